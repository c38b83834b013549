//! The image loader on images as cameras produce them: PNG and JPEG, 8 and 16 bits, grey,
//! grey with alpha, RGB and RGBA, and JPEGs whose EXIF Orientation tag (1-8) says how to turn
//! the stored rows. Every image is made here; the EXIF bytes are written by hand.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

use formation_io::frames::{GreyImage, read_grey};
use image::{ImageBuffer, Luma, LumaA, Rgb, Rgba};
use std::path::PathBuf;

const W: u32 = 48;
const H: u32 = 32;

fn dir() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("image-formats-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The test picture's grey level: the top-left quadrant dark (40), the rest bright (220).
fn level(x: u32, y: u32) -> u8 {
    if x < W / 2 && y < H / 2 { 40 } else { 220 }
}

/// Mean grey level of each quadrant: top-left, top-right, bottom-left, bottom-right.
fn quadrants(g: &GreyImage) -> [f64; 4] {
    let mut sum = [0.0; 4];
    let mut n = [0.0; 4];
    for y in 0..g.height {
        for x in 0..g.width {
            let q = usize::from(x >= g.width / 2) + 2 * usize::from(y >= g.height / 2);
            sum[q] += f64::from(g.data[y * g.width + x]);
            n[q] += 1.0;
        }
    }
    std::array::from_fn(|i| sum[i] / n[i])
}

/// Which quadrant is dark (the others bright); panics if the picture is not one dark
/// quadrant.
fn dark_quadrant(g: &GreyImage) -> usize {
    let q = quadrants(g);
    let dark: Vec<usize> = (0..4).filter(|&i| q[i] < 80.0).collect();
    assert_eq!(dark.len(), 1, "{q:?}");
    assert!(q.iter().filter(|v| **v > 180.0).count() == 3, "{q:?}");
    dark[0]
}

/// Writes the test picture to a path in some pixel type.
type Writer = dyn Fn(&std::path::Path);

#[test]
fn png_in_every_depth_and_colour_type() {
    let d = dir();
    let l = |x, y| level(x, y);
    let cases: Vec<(&str, Box<Writer>)> = vec![
        (
            "grey8",
            Box::new(move |p| {
                ImageBuffer::from_fn(W, H, |x, y| Luma([l(x, y)]))
                    .save(p)
                    .unwrap()
            }),
        ),
        (
            "grey16",
            Box::new(move |p| {
                ImageBuffer::from_fn(W, H, |x, y| Luma([u16::from(l(x, y)) * 257]))
                    .save(p)
                    .unwrap()
            }),
        ),
        (
            "greyalpha8",
            Box::new(move |p| {
                ImageBuffer::from_fn(W, H, |x, y| LumaA([l(x, y), 128]))
                    .save(p)
                    .unwrap()
            }),
        ),
        (
            "rgb8",
            Box::new(move |p| {
                ImageBuffer::from_fn(W, H, |x, y| Rgb([l(x, y), l(x, y), l(x, y)]))
                    .save(p)
                    .unwrap()
            }),
        ),
        (
            "rgba8",
            Box::new(move |p| {
                ImageBuffer::from_fn(W, H, |x, y| Rgba([l(x, y), l(x, y), l(x, y), 200]))
                    .save(p)
                    .unwrap()
            }),
        ),
        (
            "rgb16",
            Box::new(move |p| {
                let v = |x, y| u16::from(l(x, y)) * 257;
                ImageBuffer::from_fn(W, H, |x, y| Rgb([v(x, y), v(x, y), v(x, y)]))
                    .save(p)
                    .unwrap()
            }),
        ),
        (
            "rgba16",
            Box::new(move |p| {
                let v = |x, y| u16::from(l(x, y)) * 257;
                ImageBuffer::from_fn(W, H, |x, y| Rgba([v(x, y), v(x, y), v(x, y), 65535]))
                    .save(p)
                    .unwrap()
            }),
        ),
    ];
    for (name, write) in cases {
        let path = d.join(format!("{name}.png"));
        write(&path);
        let g = read_grey(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((g.width, g.height), (W as usize, H as usize), "{name}");
        // Lossless: exactly the levels written (16-bit 257 v scales back to v).
        for y in 0..H {
            for x in 0..W {
                assert_eq!(
                    g.data[(y * W + x) as usize],
                    level(x, y),
                    "{name} at ({x}, {y})"
                );
            }
        }
    }
}

#[test]
fn colour_is_converted_with_bt601_weights() {
    let d = dir();
    let path = d.join("colour.png");
    ImageBuffer::from_fn(W, H, |x, _| match x % 3 {
        0 => Rgb([255u8, 0, 0]),
        1 => Rgb([0, 255, 0]),
        _ => Rgb([0, 0, 255]),
    })
    .save(&path)
    .unwrap();
    let g = read_grey(&path).unwrap();
    assert_eq!(&g.data[..3], &[76, 150, 29]);
}

/// A JPEG of the test picture (grey or RGB), optionally with an EXIF APP1 segment carrying
/// `orientation`.
fn jpeg(rgb: bool, orientation: Option<u16>) -> Vec<u8> {
    let mut bytes = Vec::new();
    let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 95);
    if rgb {
        let img = ImageBuffer::from_fn(W, H, |x, y| Rgb([level(x, y), level(x, y), level(x, y)]));
        img.write_with_encoder(enc).unwrap();
    } else {
        let img = ImageBuffer::from_fn(W, H, |x, y| Luma([level(x, y)]));
        img.write_with_encoder(enc).unwrap();
    }
    let Some(o) = orientation else { return bytes };
    // APP1 "Exif\0\0", then a big-endian TIFF header and IFD0 with one entry:
    // tag 0x0112 (Orientation), type 3 (SHORT), count 1, the value left-aligned in 4 bytes.
    let mut tiff = vec![b'M', b'M', 0x00, 0x2A, 0, 0, 0, 8];
    tiff.extend([0x00, 0x01]); // one entry
    tiff.extend([0x01, 0x12, 0x00, 0x03, 0, 0, 0, 1]);
    tiff.extend(o.to_be_bytes());
    tiff.extend([0, 0]);
    tiff.extend([0, 0, 0, 0]); // no next IFD
    let mut app1 = b"Exif\0\0".to_vec();
    app1.extend(tiff);
    let len = u16::try_from(app1.len() + 2).unwrap();
    let mut out = vec![0xFF, 0xD8, 0xFF, 0xE1];
    out.extend(len.to_be_bytes());
    out.extend(app1);
    assert_eq!(&bytes[..2], &[0xFF, 0xD8]);
    out.extend(&bytes[2..]);
    out
}

#[test]
fn jpeg_grey_and_rgb() {
    let d = dir();
    for rgb in [false, true] {
        let path = d.join(format!("plain-{rgb}.jpg"));
        std::fs::write(&path, jpeg(rgb, None)).unwrap();
        let g = read_grey(&path).unwrap();
        assert_eq!((g.width, g.height), (W as usize, H as usize));
        assert_eq!(dark_quadrant(&g), 0);
    }
}

#[test]
fn exif_orientation_is_applied() {
    // Where the stored top-left quadrant is shown (0 TL, 1 TR, 2 BL, 3 BR) and whether the
    // sides swap, for each EXIF orientation (TIFF 6.0 / Exif 2.3 definitions).
    let expected = [
        (1, 0, false), // as stored
        (2, 1, false), // mirrored left-right
        (3, 3, false), // turned 180 degrees
        (4, 2, false), // mirrored top-bottom
        (5, 0, true),  // transposed
        (6, 1, true),  // turned 90 degrees clockwise
        (7, 3, true),  // transversed
        (8, 2, true),  // turned 90 degrees counter-clockwise
    ];
    let d = dir();
    for (orientation, quadrant, swapped) in expected {
        for rgb in [false, true] {
            let path = d.join(format!("exif-{orientation}-{rgb}.jpg"));
            std::fs::write(&path, jpeg(rgb, Some(orientation))).unwrap();
            let g = read_grey(&path).unwrap();
            let size = if swapped { (H, W) } else { (W, H) };
            assert_eq!(
                (g.width, g.height),
                (size.0 as usize, size.1 as usize),
                "orientation {orientation}"
            );
            assert_eq!(
                dark_quadrant(&g),
                quadrant,
                "orientation {orientation}, rgb {rgb}"
            );
        }
    }
}

#[test]
fn a_20_megapixel_frame_loads() {
    // 5472x3648 (20 MP, a common sensor) with an EXIF-free JPEG of it: sizes from the header.
    let (w, h) = (5472u32, 3648u32);
    let img = ImageBuffer::from_fn(w, h, |x, y| {
        Luma([if x < w / 2 && y < h / 2 { 40u8 } else { 220 }])
    });
    let path = dir().join("20mp.jpg");
    let mut bytes = Vec::new();
    img.write_with_encoder(image::codecs::jpeg::JpegEncoder::new_with_quality(
        &mut bytes, 80,
    ))
    .unwrap();
    std::fs::write(&path, bytes).unwrap();
    let g = read_grey(&path).unwrap();
    assert_eq!((g.width, g.height), (w as usize, h as usize));
    assert_eq!(g.data.len(), (w * h) as usize);
    assert_eq!(dark_quadrant(&g), 0);
}
