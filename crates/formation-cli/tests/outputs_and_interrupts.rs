//! Outputs never destroy an input or an earlier result, and SIGINT/SIGTERM end `track`
//! cleanly (issue #32, `docs/reliability.md`, "Outputs and interruption").

#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

mod common;

use std::io::Write as _;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use formation_io::bag::mcap::McapReader;

fn exe() -> Command {
    Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
}

/// The reference clip as a y4m stream: the header and one `FRAME` per image.
fn y4m_frames(clip: &common::Clip) -> (Vec<u8>, Vec<Vec<u8>>) {
    let header = b"YUV4MPEG2 W640 H480 F30:1 Ip A1:1 Cmono\n".to_vec();
    let frames = clip
        .images
        .iter()
        .map(|image| {
            let mut f = b"FRAME\n".to_vec();
            f.extend_from_slice(image.as_raw());
            f
        })
        .collect();
    (header, frames)
}

/// Sends `signal` (`INT`, `TERM`) to `child`.
fn signal(child: &Child, signal: &str) {
    let ok = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill -{signal} failed");
}

/// Whether `path` is a complete MCAP file that our reader opens, with its summary.
fn assert_complete_mcap(path: &Path) -> usize {
    let bytes = std::fs::read(path).unwrap();
    let magic = b"\x89MCAP0\r\n";
    assert!(
        bytes.starts_with(magic) && bytes.ends_with(magic),
        "{}: not closed",
        path.display()
    );
    let mut r = McapReader::open(path).unwrap();
    let summary = r.summary().unwrap().expect("a summary section");
    assert!(!summary.channels.is_empty());
    let mut messages = 0;
    while r.next_message().unwrap().is_some() {
        messages += 1;
    }
    messages
}

/// `track -` reading y4m from a pipe, stopped by `sig` after its first output line: it
/// finishes the frame, closes the MCAP and stdout, and exits with `code`.
fn track_is_stopped_cleanly_by(sig: &str, code: i32) {
    let clip = common::reference_clip(&format!("interrupt-{sig}"), 4);
    let mcap = clip.dir.join("out.mcap");
    let (header, frames) = y4m_frames(&clip);
    let mut child = exe()
        .args([
            "track",
            "-",
            "--camera",
            "camera.yaml",
            "--inputs",
            "inputs.csv",
        ])
        .args(["--json", "--mcap", "out.mcap"])
        .current_dir(&clip.dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(&header).unwrap();
    stdin.write_all(&frames[0]).unwrap();
    stdin.write_all(&frames[1]).unwrap();
    stdin.flush().unwrap();
    let stdout = child.stdout.take().unwrap();
    let rx = common::lines_of(stdout);
    // The first frame's line is out: the run is in its loop.
    let mut lines = vec![
        rx.recv_timeout(Duration::from_secs(60))
            .expect("no output line"),
    ];
    signal(&child, sig);
    // The blocked read sees the flag at the next frame: hand one over, then end the input.
    let _ = stdin.write_all(&frames[2]);
    drop(stdin);
    let status = child.wait().unwrap();
    // The reader thread ends with the pipe: the rest of the lines.
    lines.extend(rx.iter());
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(status.code(), Some(code), "{stderr}");
    assert!(stderr.contains("stopped: interrupted by SIG"), "{stderr}");
    assert!(!lines.is_empty() && lines.len() <= 3, "{lines:?}");
    for line in &lines {
        serde_json::from_str::<serde_json::Value>(line).expect("a complete JSON line");
    }
    // Four channels a frame, every frame that was printed.
    assert_eq!(assert_complete_mcap(&mcap), 4 * lines.len());
    let leftovers: Vec<_> = std::fs::read_dir(&clip.dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn sigint_stops_track_with_130_and_complete_outputs() {
    track_is_stopped_cleanly_by("INT", 130);
}

#[test]
fn sigterm_stops_track_with_143_and_complete_outputs() {
    track_is_stopped_cleanly_by("TERM", 143);
}

#[test]
fn an_output_that_is_an_input_is_refused_before_any_work() {
    let clip = common::reference_clip("out-is-in", 2);
    let d = &clip.dir;
    std::fs::write(d.join("keep.mcap"), b"not touched").unwrap();
    for args in [
        vec![
            "track",
            "frames",
            "--camera",
            "camera.yaml",
            "--mcap",
            "camera.yaml",
        ],
        vec![
            "track",
            "frames",
            "--camera",
            "camera.yaml",
            "--mcap",
            "./camera.yaml",
        ],
        vec![
            "track",
            "frames",
            "--camera",
            "camera.yaml",
            "--mcap",
            "frames/x.mcap",
        ],
        vec!["track", "keep.mcap", "--mcap", "keep.mcap"],
        vec![
            "track",
            "frames",
            "--camera",
            "camera.yaml",
            "--inputs",
            "inputs.csv",
            "--mcap",
            "inputs.csv",
        ],
    ] {
        let out = common::run(d, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains("would overwrite the input"), "{stderr}");
    }
    assert_eq!(std::fs::read(d.join("keep.mcap")).unwrap(), b"not touched");
    assert_eq!(
        std::fs::read_to_string(d.join("camera.yaml")).unwrap(),
        common::CAMERA
    );
    // The same for render's two outputs.
    let out = common::run(
        d,
        &[
            "render",
            "--paper-fig",
            "7",
            "--out",
            "x.png",
            "--truth",
            "x.png",
        ],
    );
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!d.join("x.png").exists());
    // markers writes markers.json into --out: never onto the rig it reads.
    let rig = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/rigs/reference.yaml"
    ))
    .unwrap();
    std::fs::write(d.join("markers.json"), &rig).unwrap();
    let out = common::run(d, &["markers", "--rig", "markers.json", "--out", "."]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read_to_string(d.join("markers.json")).unwrap(),
        rig
    );
}

#[test]
fn a_run_that_tracks_nothing_keeps_the_earlier_mcap() {
    let clip = common::reference_clip("nothing-tracked", 2);
    let d = &clip.dir;
    let good = common::run(
        d,
        &[
            "track",
            "frames",
            "--camera",
            "camera.yaml",
            "--mcap",
            "out.mcap",
        ],
    );
    assert_eq!(
        good.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&good.stderr)
    );
    let before = std::fs::read(d.join("out.mcap")).unwrap();
    // Frames of another size: every frame is an error, nothing is tracked (exit 1).
    std::fs::create_dir_all(d.join("small")).unwrap();
    image::GrayImage::new(64, 48)
        .save(d.join("small/a.png"))
        .unwrap();
    let bad = common::run(
        d,
        &[
            "track",
            "small",
            "--camera",
            "camera.yaml",
            "--mcap",
            "out.mcap",
        ],
    );
    assert_eq!(
        bad.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
    assert_eq!(std::fs::read(d.join("out.mcap")).unwrap(), before);
    assert!(
        std::fs::read_dir(d).unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .contains(".tmp-"))
    );
}

/// The reference scenario file with another duration, in `dir`.
fn short_scenario(dir: &Path, seconds: f64) -> std::path::PathBuf {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenarios/reference.yaml"
    ))
    .unwrap()
    .replace("duration: 8.0", &format!("duration: {seconds:?}"));
    let path = dir.join(format!("reference-{seconds}.yaml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Every file below `dir` with its bytes, sorted by path.
fn snapshot(dir: &Path) -> Vec<(std::path::PathBuf, Vec<u8>)> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let path = e.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                files.push((path.clone(), std::fs::read(&path).unwrap()));
            }
        }
    }
    files.sort();
    files
}

#[test]
fn an_interrupted_demo_leaves_the_earlier_folder_as_it_was() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("demo-interrupt-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("out");
    let short = short_scenario(&dir, 1.0);
    let first = exe()
        .args(["-q", "demo", "--seed", "1", "--scenario"])
        .arg(&short)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(
        first.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let before = snapshot(&out);
    assert!(before.iter().any(|(p, _)| p.ends_with("demo.mcap")));
    // A second, longer run into the same folder, stopped after its first frames.
    let mut child = exe()
        .args(["demo", "--seed", "2", "--scenario"])
        .arg(short_scenario(&dir, 8.0))
        .arg("--out")
        .arg(&out)
        .env("FORMATION_TRACKER_STATUS_SECS", "0")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let rx = common::lines_of(stderr);
    let mut lines = Vec::new();
    loop {
        let line = rx
            .recv_timeout(Duration::from_secs(60))
            .expect("no progress line");
        let started = line.starts_with("demo: 2/");
        lines.push(line);
        if started {
            break;
        }
    }
    signal(&child, "INT");
    let status = child.wait().unwrap();
    while let Ok(line) = rx.recv_timeout(Duration::from_secs(5)) {
        lines.push(line);
    }
    assert_eq!(status.code(), Some(130), "{lines:?}");
    assert!(
        lines
            .iter()
            .any(|l| l.contains("stopped: interrupted by SIGINT") && l.contains("left as it was")),
        "{lines:?}"
    );
    assert_eq!(snapshot(&out), before, "the folder changed");
    // Into a folder that did not exist: nothing is left, not even the empty folders.
    let fresh = dir.join("new/nested");
    let mut child = exe()
        .args(["demo", "--seed", "2", "--scenario"])
        .arg(short_scenario(&dir, 8.0))
        .arg("--out")
        .arg(&fresh)
        .env("FORMATION_TRACKER_STATUS_SECS", "0")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let rx = common::lines_of(child.stderr.take().unwrap());
    while !rx
        .recv_timeout(Duration::from_secs(60))
        .expect("no progress line")
        .starts_with("demo: 2/")
    {}
    signal(&child, "INT");
    assert_eq!(child.wait().unwrap().code(), Some(130));
    assert!(!dir.join("new").exists(), "an empty output folder was left");
}
