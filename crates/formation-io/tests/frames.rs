//! Frame sources on small y4m streams written byte by byte here, and on a folder of images
//! with a broken file.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

use std::io::Cursor;
use std::path::PathBuf;

use formation_io::frames::{FrameError, FrameSource};

/// A y4m stream of `frames` frames of `w x h` in colour space `cs` (`"420"`, `"mono"`,
/// `"420p10"`) at 30000/1001 frames/s; luma of frame `k` at pixel `i` is `(10 k + i) % 256`.
fn y4m(w: usize, h: usize, cs: &str, frames: usize) -> Vec<u8> {
    let chroma = 2 * w.div_ceil(2) * h.div_ceil(2);
    let (depth, other) = match cs {
        "mono" => (8, 0),
        "420p10" => (10, chroma),
        _ => (8, chroma),
    };
    y4m_any(w, h, cs, "F30000:1001", depth, other, frames)
}

fn source(bytes: Vec<u8>) -> Result<FrameSource, FrameError> {
    FrameSource::from_y4m_reader(Box::new(Cursor::new(bytes)))
}

fn expected_luma(k: usize, n: usize) -> Vec<u8> {
    (0..n).map(|i| ((10 * k + i) % 256) as u8).collect()
}

/// A y4m stream in any colour space: `depth`-bit samples (two bytes above 8), `other`
/// samples of chroma and alpha per frame after the luma plane.
fn y4m_any(
    w: usize,
    h: usize,
    cs: &str,
    rate: &str,
    depth: u32,
    other: usize,
    frames: usize,
) -> Vec<u8> {
    let mut out =
        format!("YUV4MPEG2 W{w} H{h} {rate} It A0:0 C{cs} XCOLORRANGE=FULL\n").into_bytes();
    for k in 0..frames {
        out.extend_from_slice(b"FRAME\n");
        for i in 0..w * h {
            let v = ((10 * k + i) % 256) as u16;
            if depth == 8 {
                out.push(v as u8);
            } else {
                out.extend_from_slice(&(v << (depth - 8)).to_le_bytes());
            }
        }
        let bytes = if depth == 8 { 1 } else { 2 };
        out.extend(std::iter::repeat_n(77u8, other * bytes));
    }
    out
}

/// Regression (#11): gray16le, gray10le, yuva444p, yuv411p and yuv444p16le failed with
/// "Bad input parameters provided". Every colour space ffmpeg's y4m muxer writes is read.
#[test]
fn every_colour_space_ffmpeg_writes_is_read() {
    let (w, h) = (7usize, 5usize);
    let (cw2, ch2) = (w.div_ceil(2), h.div_ceil(2));
    for (cs, depth, other) in [
        ("mono", 8, 0),
        ("mono16", 16, 0),
        ("mono10", 10, 0),
        ("mono12", 12, 0),
        ("444alpha", 8, 3 * w * h),
        ("411", 8, 2 * w.div_ceil(4) * h),
        ("444p16", 16, 2 * w * h),
        ("444", 8, 2 * w * h),
        ("422", 8, 2 * cw2 * h),
        ("422p12", 12, 2 * cw2 * h),
        ("420jpeg", 8, 2 * cw2 * ch2),
        ("420paldv", 8, 2 * cw2 * ch2),
        ("420mpeg2", 8, 2 * cw2 * ch2),
        ("420p9", 9, 2 * cw2 * ch2),
        ("420p16", 16, 2 * cw2 * ch2),
    ] {
        let mut src = source(y4m_any(w, h, cs, "F25:1", depth, other, 2)).unwrap();
        assert_eq!(src.frame_rate(), Some(25.0), "{cs}");
        for k in 0..2 {
            let f = src.next_frame().unwrap().expect("a frame");
            assert_eq!(f.image.data, expected_luma(k, w * h), "{cs} frame {k}");
        }
        assert!(src.next_frame().unwrap().is_none(), "{cs}");
        assert!(
            !src.truncated(),
            "{cs}: the planes were not skipped exactly"
        );
    }
}

#[test]
fn header_errors_name_the_field_and_the_value() {
    for (header, says) in [
        (
            "YUV4MPEG2 W4 H4 Cnv12\n",
            "header field C: colour space `nv12` is not one y4m defines",
        ),
        ("YUV4MPEG2 W4 H4 C420p7\n", "7-bit samples"),
        (
            "YUV4MPEG2 W4x H4\n",
            "header field W: `4x` is not a whole number",
        ),
        (
            "YUV4MPEG2 W4 H4 F30\n",
            "header field F: `30` is not a frame rate",
        ),
        ("YUV4MPEG2 W4 H4", "the stream ended inside its header"),
    ] {
        let e = source(header.as_bytes().to_vec()).unwrap_err();
        assert!(e.to_string().contains(says), "{header:?}: {e}");
    }
    let long = format!("YUV4MPEG2 W4 H4 X{}\n", "a".repeat(2000));
    let e = source(long.into_bytes()).unwrap_err();
    assert!(e.to_string().contains("within 1024 bytes"), "{e}");
}

#[test]
fn reads_every_frame_luma_into_one_buffer() {
    for cs in ["420", "mono", "420p10"] {
        let mut src = source(y4m(5, 3, cs, 3)).unwrap();
        assert!((src.frame_rate().unwrap() - 29.97).abs() < 1e-2);
        let mut ptr = None;
        for k in 0..3 {
            let f = src.next_frame().unwrap().expect("a frame");
            assert_eq!(f.index, k as u64);
            assert_eq!((f.image.width, f.image.height), (5, 3));
            assert_eq!(f.image.data, expected_luma(k, 15), "{cs} frame {k}");
            // One grey buffer per stream.
            let p = f.image.data.as_ptr();
            assert_eq!(*ptr.get_or_insert(p), p);
        }
        assert!(src.next_frame().unwrap().is_none());
        assert!(src.next_frame().unwrap().is_none());
        assert_eq!(src.frames_read(), 3);
        assert!(!src.truncated());
    }
}

#[test]
fn truncated_stream_ends_cleanly() {
    let full = y4m(4, 4, "420", 3);
    let frame = 6 + 16 + 2 * 4;
    let header = full.len() - 3 * frame;
    // Cut inside the third frame's pixels, inside its FRAME line, and right before it.
    for (cut, truncated) in [
        (header + 2 * frame + 10, true),
        (header + 2 * frame + 3, true),
        (header + 2 * frame, false),
    ] {
        let mut src = source(full[..cut].to_vec()).unwrap();
        let mut n = 0;
        while src.next_frame().unwrap().is_some() {
            n += 1;
        }
        assert_eq!(n, 2);
        assert_eq!(src.frames_read(), 2);
        assert_eq!(src.truncated(), truncated, "cut at {cut}");
    }
}

#[test]
fn broken_frame_header_is_an_error_then_the_stream_ends() {
    let mut bytes = y4m(4, 2, "mono", 3);
    let frame = 6 + 8;
    let second = bytes.len() - 2 * frame;
    bytes[second + 4] = b'X'; // "FRAMX"
    let mut src = source(bytes).unwrap();
    assert!(src.next_frame().unwrap().is_some());
    let err = src.next_frame().unwrap_err();
    assert!(matches!(err, FrameError::Y4m { index: 1, .. }), "{err}");
    assert!(src.next_frame().unwrap().is_none());
    assert_eq!(src.frames_read(), 1);
}

#[test]
fn bad_headers_are_typed_errors() {
    assert!(matches!(
        source(b"P5 4 4 255\n".to_vec()),
        Err(FrameError::Y4mHeader { .. })
    ));
    assert!(matches!(
        source(b"YUV4MPEG2 W99999999 H99999999 C420\nFRAME\n".to_vec()),
        Err(FrameError::Size { .. })
    ));
    assert!(matches!(
        source(b"YUV4MPEG2 W0 H4\n".to_vec()),
        Err(FrameError::Size { .. })
    ));
    assert!(matches!(
        source(b"YUV4MPEG2 H4 C420\n".to_vec()),
        Err(FrameError::Y4mHeader { .. })
    ));
    assert!(matches!(
        source(Vec::new()),
        Err(FrameError::Y4mHeader { .. })
    ));
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ft-frames-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn folder_sorted_by_name_skips_broken_file_and_goes_on() {
    let dir = scratch("folder");
    let grey = image::GrayImage::from_fn(6, 4, |x, y| image::Luma([(x * 10 + y) as u8]));
    grey.save(dir.join("frame-002.png")).unwrap();
    let colour = image::RgbImage::from_fn(6, 4, |_, _| image::Rgb([200, 100, 50]));
    colour.save(dir.join("frame-001.png")).unwrap();
    std::fs::write(dir.join("frame-003.png"), b"not a png").unwrap();
    grey.save(dir.join("frame-004.jpg")).unwrap();
    std::fs::write(dir.join("notes.txt"), b"ignored").unwrap();

    let mut src = FrameSource::open(&dir).unwrap();
    assert_eq!(src.len_hint(), Some(4));
    let f = src.next_frame().unwrap().unwrap();
    assert_eq!(f.index, 0);
    // Rec. 601: (299*200 + 587*100 + 114*50) / 1000 = 124.2
    assert!(f.image.data.iter().all(|&v| v == 124), "{:?}", f.image.data);
    let f = src.next_frame().unwrap().unwrap();
    assert_eq!(f.index, 1);
    assert_eq!(f.image.data, grey.as_raw().clone());
    match src.next_frame() {
        Err(FrameError::Image { index, path, .. }) => {
            assert_eq!(index, 2);
            assert!(path.ends_with("frame-003.png"));
        }
        other => panic!("expected a broken-frame error, got {other:?}"),
    }
    let f = src.next_frame().unwrap().unwrap();
    assert_eq!(f.index, 3);
    assert_eq!((f.image.width, f.image.height), (6, 4));
    assert!(src.next_frame().unwrap().is_none());
    assert_eq!(src.frames_read(), 3);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn missing_input_and_empty_folder_are_errors() {
    let dir = scratch("empty");
    assert!(matches!(
        FrameSource::open(&dir),
        Err(FrameError::EmptyFolder { .. })
    ));
    assert!(matches!(
        FrameSource::open(&dir.join("nope.y4m")),
        Err(FrameError::Open { .. })
    ));
    let file = dir.join("clip.y4m");
    std::fs::write(&file, y4m(3, 3, "420", 2)).unwrap();
    let mut src = FrameSource::open(&file).unwrap();
    assert!(src.next_frame().unwrap().is_some());
    std::fs::remove_dir_all(&dir).unwrap();
}
