//! Image files as cameras and users produce them: the format comes from the content, not
//! the extension; a truncated JPEG is an error (decoders return a partly grey image); the
//! size comes from the header, so an oversized image is refused before it is decoded.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::process::Output;

mod common;
use common::run;

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 == 1 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A PNG whose header claims `w x h` pixels, with almost no image data.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 0, 0, 0, 0]); // 8-bit grey, deflate, no filter, no interlace
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(13u32.to_be_bytes());
    png.extend(&ihdr);
    png.extend(crc32(&ihdr).to_be_bytes());
    // The start of the image data (a zlib header), then nothing: a decoder that tried would fail.
    let idat = b"IDAT\x78\x9c".to_vec();
    png.extend(2u32.to_be_bytes());
    png.extend(&idat);
    png.extend(crc32(&idat).to_be_bytes());
    png
}

#[test]
fn images_are_read_by_content_and_checked_before_decoding() {
    let d = common::blank_frames("image-inputs");
    let out = run(&d, &["render", "--paper-fig", "7", "--out", "fig7.png"]);
    assert!(out.status.success());
    let img = image::open(d.join("fig7.png")).unwrap().into_rgb8();
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
        .encode_image(&img)
        .unwrap();
    std::fs::write(d.join("fig7.jpg"), &jpeg).unwrap();
    std::fs::write(d.join("half.jpg"), &jpeg[..jpeg.len() / 2]).unwrap();
    std::fs::copy(d.join("fig7.png"), d.join("png-named.jpg")).unwrap();
    std::fs::write(d.join("huge.png"), png_header_only(20_000, 20_000)).unwrap();

    // A whole JPEG, and a PNG with a .jpg name, are read with the same markers.
    let png = run(&d, &["detect", "--json", "fig7.png"]);
    let markers = |o: &Output| {
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        v["markers"].as_array().unwrap().len()
    };
    for name in ["fig7.jpg", "png-named.jpg"] {
        let out = run(&d, &["detect", "--json", name]);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(markers(&out), markers(&png), "{name}");
    }
    // Truncated and oversized files are one error line each, for detect and track alike.
    for (name, says) in [
        ("half.jpg", "truncated JPEG"),
        (
            "huge.png",
            "image size 20000x20000 is outside 1..=16384 pixels a side",
        ),
    ] {
        let out = run(&d, &["detect", name]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        assert!(stderr.contains(says), "{name}: {stderr}");
        let folder = d.join(format!("only-{name}"));
        std::fs::create_dir_all(&folder).unwrap();
        std::fs::copy(d.join(name), folder.join(name)).unwrap();
        let out = run(
            &d,
            &["track", "--camera", "camera.yaml", folder.to_str().unwrap()],
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "track {name}: {stderr}");
        assert!(stderr.contains(says), "track {name}: {stderr}");
    }
}

/// The pixel limit is an option: `--max-side` lowers or raises it, and the message says so.
#[test]
fn the_pixel_limit_is_configurable() {
    let d = common::blank_frames("image-max-side");
    let out = run(&d, &["detect", "--max-side", "100", "frames/f0.png"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("image size 640x480 is outside 1..=100 pixels a side (--max-side"),
        "{stderr}"
    );
    let out = run(
        &d,
        &[
            "track",
            "--max-side",
            "479",
            "--camera",
            "camera.yaml",
            "frames",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("outside 1..=479 pixels"), "{stderr}");
    let out = run(
        &d,
        &[
            "track",
            "--max-side",
            "640",
            "--camera",
            "camera.yaml",
            "frames",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run(&d, &["detect", "--max-side", "0", "frames/f0.png"]);
    assert_eq!(out.status.code(), Some(2));
}
