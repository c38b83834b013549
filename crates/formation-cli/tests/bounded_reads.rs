//! Every read is bounded, and bag folders stay inside themselves (issue #32,
//! `docs/reliability.md`, "Limits"). Each case was a report: `/dev/zero` given to `--camera`,
//! `--scenario`, `--rig` or `--inputs` reached 3.9-7.7 GB, `detect /dev/zero` 15 GB, a 2 MB
//! PNG declaring 16384x16384 RGBA16 decoded 2.63 GB, a metadata.yaml could name
//! `/etc/passwd`, a missing split file was never named.

#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("bounded-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join("camera.yaml"), common::CAMERA).unwrap();
    d
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A PNG whose header says `w` x `h` at `depth` bits and colour type `colour`, with a little
/// compressed data: what a decompression bomb looks like from outside.
fn png_header(w: u32, h: u32, depth: u8, colour: u8) -> Vec<u8> {
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let start = out.len();
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        let crc = crc32fast::hash(&out[start..]);
        out.extend_from_slice(&crc.to_be_bytes());
    }
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[depth, colour, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    // A stored (uncompressed) zlib stream of 1000 zero bytes.
    let mut idat = vec![0x78, 0x01, 0x01, 0xe8, 0x03, 0x17, 0xfc];
    idat.extend_from_slice(&[0; 1000]);
    chunk(&mut png, b"IDAT", &idat);
    chunk(&mut png, b"IEND", &[]);
    png
}

#[test]
fn endless_text_inputs_are_refused_before_they_are_read_whole() {
    let d = dir("text");
    let frames = common::blank_frames("bounded-text");
    let frames = frames.join("frames");
    let frames = frames.to_str().unwrap();
    for (args, what) in [
        (
            vec!["track", frames, "--camera", "/dev/zero"],
            "calibration file /dev/zero",
        ),
        (
            vec![
                "track",
                frames,
                "--camera",
                "camera.yaml",
                "--rig",
                "/dev/zero",
            ],
            "rig file /dev/zero",
        ),
        (
            vec![
                "track",
                frames,
                "--camera",
                "camera.yaml",
                "--inputs",
                "/dev/zero",
            ],
            "follower inputs /dev/zero",
        ),
        (
            vec!["demo", "--scenario", "/dev/zero", "--out", "o"],
            "scenario file /dev/zero",
        ),
        (
            vec!["render", "--scene", "/dev/zero", "--out", "x.png"],
            "scene file /dev/zero",
        ),
        (
            vec!["reproduce", "dukf", "--scenario", "/dev/zero", "--out", "o"],
            "scenario file /dev/zero",
        ),
    ] {
        let out = common::run(&d, &args);
        let e = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {e}");
        assert!(e.contains(what) && e.contains("limit"), "{args:?}: {e}");
    }
}

#[test]
fn images_are_refused_from_their_header_and_their_size() {
    let d = dir("images");
    std::fs::write(d.join("bomb.png"), png_header(16384, 16384, 16, 6)).unwrap();
    std::fs::write(d.join("wide.png"), png_header(u32::MAX, 1, 8, 0)).unwrap();
    // A sparse 2 GiB file: refused by its size, nothing read.
    std::fs::File::create(d.join("sparse.png"))
        .unwrap()
        .set_len(2 << 30)
        .unwrap();
    for (file, want) in [
        (
            "bomb.png",
            "image size 16384x16384 needs 2.2 GiB decoded, more than the 256 MiB",
        ),
        (
            "wide.png",
            "image size 4294967295x1 is outside 1..=16384 pixels a side",
        ),
        (
            "sparse.png",
            "too large for an image file: it holds 2 GiB, over the 256 MiB limit",
        ),
        (
            "/dev/zero",
            "too large for an image file: it holds more than 256 MiB",
        ),
    ] {
        let out = common::run(&d, &["detect", file]);
        let e = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{file}: {e}");
        assert!(e.contains(want), "{file}: {e}");
    }
    // The bound follows --max-memory: a 640x480 frame is too large for 16 MiB of budget
    // only if its decoded size is; a 2048x2048 RGBA frame (16 MiB + grey) is.
    std::fs::write(d.join("big.png"), png_header(2048, 2048, 8, 6)).unwrap();
    let out = common::run(&d, &["--max-memory", "16MiB", "detect", "big.png"]);
    assert!(
        stderr(&out).contains("more than the 4 MiB an input may take"),
        "{}",
        stderr(&out)
    );
    let out = common::run(&d, &["detect", "--max-memory", "1e3", "big.png"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

#[test]
fn a_y4m_header_beyond_the_budget_is_refused_before_a_frame_is_read() {
    let d = dir("y4m");
    let y4m = b"YUV4MPEG2 W16384 H16384 F30:1 C444p16\nFRAME\n".to_vec();
    std::fs::write(d.join("huge.y4m"), y4m).unwrap();
    let out = common::run(&d, &["track", "huge.y4m", "--camera", "camera.yaml"]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{e}");
    assert!(
        e.contains("a 16384x16384 frame needs 768 MiB to read"),
        "{e}"
    );
}

/// A copy of the Duckietown bag folder whose metadata.yaml lists `files`.
fn bag_folder(name: &str, files: &[&str]) -> PathBuf {
    let d = dir(name);
    let bag = d.join("bag");
    std::fs::create_dir_all(&bag).unwrap();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/bags/duckietown");
    std::fs::copy(
        fixtures.join("duckietown.mcap"),
        bag.join("duckietown.mcap"),
    )
    .unwrap();
    let metadata = std::fs::read_to_string(fixtures.join("metadata.yaml")).unwrap();
    let listed: String = files.iter().map(|f| format!("  - {f}\n")).collect();
    let metadata = metadata.replace(
        "  relative_file_paths:\n  - duckietown.mcap\n",
        &format!("  relative_file_paths:\n{listed}"),
    );
    assert!(metadata.contains(&listed));
    std::fs::write(bag.join("metadata.yaml"), metadata).unwrap();
    bag
}

#[test]
fn a_missing_split_file_is_named_and_the_rest_tracked() {
    let bag = bag_folder("missing", &["duckietown.mcap", "duckietown_1.mcap"]);
    let out = common::run(bag.parent().unwrap(), &["track", "bag", "--json"]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(3), "{e}");
    assert!(
        e.contains("missing: ") && e.contains("duckietown_1.mcap"),
        "{e}"
    );
    assert!(!out.stdout.is_empty());
    // Nothing there at all: exit 1, naming them.
    let bag = bag_folder("all-missing", &["a.mcap", "b.mcap"]);
    let out = common::run(bag.parent().unwrap(), &["track", "bag"]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{e}");
    assert!(
        e.contains("none of the 2 files it lists is there") && e.contains("b.mcap"),
        "{e}"
    );
}

#[test]
fn bag_paths_that_leave_the_folder_are_refused() {
    for (name, listed) in [
        ("dotdot", "../../other.mcap"),
        ("absolute", "/etc/passwd"),
        ("link", "link.mcap"),
    ] {
        let bag = bag_folder(name, &["duckietown.mcap", listed]);
        if name == "link" {
            let outside = bag.parent().unwrap().join("outside.mcap");
            std::fs::copy(bag.join("duckietown.mcap"), &outside).unwrap();
            std::os::unix::fs::symlink(&outside, bag.join("link.mcap")).unwrap();
        }
        let out = common::run(bag.parent().unwrap(), &["track", "bag"]);
        let e = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{name}: {e}");
        assert!(
            e.contains("metadata.yaml: relative_file_paths:") && e.contains("(refused)"),
            "{name}: {e}"
        );
        assert!(out.stdout.is_empty(), "{name}");
    }
}

#[test]
fn a_chunk_declaring_more_than_the_budget_is_refused_before_it_is_decompressed() {
    let d = dir("chunk");
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/bags/demo_zstd.mcap");
    let mut bytes = std::fs::read(fixture).unwrap();
    // Walk the records (opcode, u64 length, body) to the first chunk, and make it declare
    // 900 MiB of records: a 3 MB file that would ask for 900 MiB.
    let mut at = 8;
    loop {
        let opcode = bytes[at];
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        if opcode == 0x06 {
            let size = at + 9 + 16;
            bytes[size..size + 8].copy_from_slice(&(900u64 << 20).to_le_bytes());
            break;
        }
        at += 9 + len;
    }
    std::fs::write(d.join("bomb.mcap"), &bytes).unwrap();
    let out = common::run(&d, &["track", "bomb.mcap"]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{e}");
    assert!(
        e.contains(&format!(
            "uncompressed size {} bytes is more than the {}-byte limit",
            900u64 << 20,
            256u64 << 20
        )),
        "{e}"
    );
    // The limit follows --max-memory: the fixture's own chunks pass at 64 MiB.
    let ok = common::run(
        Path::new(env!("CARGO_MANIFEST_DIR")),
        &[
            "--max-memory",
            "64MiB",
            "track",
            "../../fixtures/bags/demo_zstd.mcap",
        ],
    );
    assert_eq!(ok.status.code(), Some(0), "{}", stderr(&ok));
}

/// A bag cut before its first channel says so (#32: it said "no image topic; topics: none").
#[test]
fn a_bag_cut_before_its_first_channel_says_where() {
    let d = dir("cut");
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/bags/demo_lz4.mcap");
    let bytes = std::fs::read(fixture).unwrap();
    std::fs::write(d.join("cut.mcap"), &bytes[..300]).unwrap();
    let out = common::run(&d, &["track", "cut.mcap"]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{e}");
    assert!(
        e.contains("cut.mcap is truncated: it ends inside a record at byte"),
        "{e}"
    );
    assert!(!e.contains("topics: none"), "{e}");
}
