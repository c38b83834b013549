//! ROS image messages to our grey frame, and `CameraInfo` to a calibration.
//!
//! Colour becomes grey with the BT.601 weights of every other frame source
//! ([`crate::frames::read_grey`]), so a bag of `rgb8` frames and a folder of the same RGB
//! PNGs give the same grey bytes. `mono16` keeps its high byte (as y4m keeps the high bits of
//! deeper samples). Bayer mosaics (`bayer_rggb8`, `bayer_bggr8`, `bayer_gbrg8`,
//! `bayer_grbg8`) are demosaiced by averaging, for each colour, its samples in the pixel's
//! 3x3 neighbourhood (clamped at the border), then converted with the same weights: this
//! keeps every pixel centred where it was, so marker corners are not shifted.

use super::cdr::{CameraInfo, CompressedImage, Image};
use crate::frames::{GreyImage, bt601_luma, decode_image};

/// The raw encodings read from `sensor_msgs/msg/Image`.
pub const ENCODINGS: [&str; 10] = [
    "mono8",
    "mono16",
    "rgb8",
    "bgr8",
    "rgba8",
    "bgra8",
    "bayer_rggb8",
    "bayer_bggr8",
    "bayer_gbrg8",
    "bayer_grbg8",
];

/// Whether `encoding` is one we read.
pub fn supported(encoding: &str) -> bool {
    ENCODINGS.contains(&encoding)
}

/// Converts a raw image into `grey`.
///
/// # Errors
/// An unsupported encoding, a size over `max_side`, or a step or data length that does not
/// match the size.
pub fn raw_to_grey(img: &Image<'_>, grey: &mut GreyImage, max_side: usize) -> Result<(), String> {
    let (w, h) = (img.width as usize, img.height as usize);
    if w == 0 || h == 0 || w > max_side || h > max_side {
        return Err(format!(
            "image size {w}x{h} is outside 1..={max_side} pixels a side (--max-side sets the limit)"
        ));
    }
    let bpp = match img.encoding.as_str() {
        "mono8" | "bayer_rggb8" | "bayer_bggr8" | "bayer_gbrg8" | "bayer_grbg8" => 1,
        "mono16" => 2,
        "rgb8" | "bgr8" => 3,
        "rgba8" | "bgra8" => 4,
        other => {
            return Err(format!(
                "image encoding `{other}` is not supported (supported: {})",
                ENCODINGS.join(", ")
            ));
        }
    };
    let step = img.step as usize;
    if step < w * bpp {
        return Err(format!(
            "step {step} bytes is shorter than a row of {w} {} pixels",
            img.encoding
        ));
    }
    if img.data.len() < step * (h - 1) + w * bpp {
        return Err(format!(
            "{} bytes of pixels, a {w}x{h} {} image with step {step} needs {}",
            img.data.len(),
            img.encoding,
            step * h
        ));
    }
    let out = grey.reshape(w, h);
    let rows = img.data.chunks(step).take(h);
    match img.encoding.as_str() {
        "mono8" => {
            for (o, row) in out.chunks_exact_mut(w).zip(rows) {
                o.copy_from_slice(&row[..w]);
            }
        }
        "mono16" => {
            let hi = usize::from(!img.is_bigendian);
            for (o, row) in out.chunks_exact_mut(w).zip(rows) {
                for (p, s) in o.iter_mut().zip(row.chunks_exact(2)) {
                    *p = s[hi];
                }
            }
        }
        "rgb8" | "bgr8" | "rgba8" | "bgra8" => {
            let bgr = img.encoding.starts_with('b');
            for (o, row) in out.chunks_exact_mut(w).zip(rows) {
                for (p, s) in o.iter_mut().zip(row.chunks_exact(bpp)) {
                    let (r, b) = if bgr { (s[2], s[0]) } else { (s[0], s[2]) };
                    *p = bt601_luma(r, s[1], b);
                }
            }
        }
        bayer => demosaic(bayer, img.data, step, w, h, out),
    }
    Ok(())
}

/// Grey from an 8-bit Bayer mosaic (see the module documentation).
fn demosaic(pattern: &str, data: &[u8], step: usize, w: usize, h: usize, out: &mut [u8]) {
    // Colour of the top-left 2x2 cell, row-major: 0 red, 1 green, 2 blue.
    let cell: [u8; 4] = match pattern {
        "bayer_rggb8" => [0, 1, 1, 2],
        "bayer_bggr8" => [2, 1, 1, 0],
        "bayer_gbrg8" => [1, 2, 0, 1],
        _ => [1, 0, 2, 1],
    };
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0u32; 3];
            let mut n = [0u32; 3];
            for dy in [-1i64, 0, 1] {
                let yy = (y as i64 + dy).clamp(0, h as i64 - 1) as usize;
                for dx in [-1i64, 0, 1] {
                    let xx = (x as i64 + dx).clamp(0, w as i64 - 1) as usize;
                    let c = usize::from(cell[(yy % 2) * 2 + xx % 2]);
                    sum[c] += u32::from(data[yy * step + xx]);
                    n[c] += 1;
                }
            }
            // Every 3x3 neighbourhood of a mosaic holds each colour at least once.
            let mean = |c: usize| (sum[c] + n[c] / 2).checked_div(n[c]).map_or(0, |m| m as u8);
            out[y * w + x] = bt601_luma(mean(0), mean(1), mean(2));
        }
    }
}

/// Decodes a compressed image (JPEG or PNG) into `grey`.
///
/// # Errors
/// A format other than JPEG or PNG, or an image that does not decode.
pub fn compressed_to_grey(
    img: &CompressedImage<'_>,
    grey: &mut GreyImage,
    max_side: usize,
) -> Result<(), String> {
    let format = img.format.to_ascii_lowercase();
    if format.contains("compresseddepth") {
        return Err(format!(
            "compressed image format `{}` (a depth image) is not supported (jpeg, png)",
            img.format
        ));
    }
    let is_jpeg = img.data.starts_with(&[0xFF, 0xD8]);
    let is_png = img.data.starts_with(b"\x89PNG");
    if !is_jpeg && !is_png {
        return Err(format!(
            "compressed image format `{}`: the data is neither JPEG nor PNG (supported: jpeg, png)",
            img.format
        ));
    }
    decode_image(img.data, grey, max_side)
}

/// The distortion model of a `CameraInfo` (`plumb_bob`, `rational_polynomial` or
/// `equidistant`, as `pose` reads them; empty means `plumb_bob`), or why it is refused.
fn check_distortion_model(model: &str) -> Result<(), String> {
    if model.is_empty() {
        return Ok(());
    }
    pose::DistortionModel::from_name(model)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// A calibration from `CameraInfo`, through the ROS calibration-file reader of `pose`, so
/// that it gets the same checks as a `camera_info` YAML file (focal lengths, principal
/// point, distortion that can be inverted over the image).
///
/// # Errors
/// An unknown distortion model or a calibration `pose` refuses (e.g. a zero focal
/// length), as one line.
pub fn calibration(info: &CameraInfo) -> Result<pose::Camera, String> {
    check_distortion_model(&info.distortion_model)?;
    // A NaN or infinity would be written as text YAML cannot read as a number, and reported
    // as "not valid YAML": name the field and the element instead.
    for (field, values) in [("k", &info.k[..]), ("d", &info.d[..])] {
        if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(format!(
                "CameraInfo field `{field}[{i}]` is {v:?}, not a finite number"
            ));
        }
    }
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:?}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let model = if info.distortion_model.is_empty() {
        "plumb_bob"
    } else {
        &info.distortion_model
    };
    let d = if info.d.is_empty() {
        vec![0.0; 5]
    } else {
        info.d.clone()
    };
    let yaml = format!(
        "image_width: {}\nimage_height: {}\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [{}]\n\
         distortion_model: {model}\ndistortion_coefficients:\n  rows: 1\n  cols: {}\n  data: [{}]\n",
        info.width,
        info.height,
        list(&info.k),
        d.len(),
        list(&d),
    );
    pose::Camera::from_yaml_str(&yaml).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(model: &str, fx: f64) -> CameraInfo {
        CameraInfo {
            stamp_ns: 0,
            height: 480,
            width: 640,
            distortion_model: model.into(),
            d: vec![0.01, -0.02, 0.0, 0.0, 0.0],
            k: [fx, 0.0, 320.0, 0.0, fx, 240.0, 0.0, 0.0, 1.0],
        }
    }

    #[test]
    fn plumb_bob_camera_info_is_a_calibration() {
        let c = calibration(&info("plumb_bob", 500.0)).unwrap();
        assert_eq!((c.width, c.height), (640, 480));
        assert_eq!(c.intrinsics.alpha(), 500.0);
        assert_eq!(c.distortion.model(), pose::DistortionModel::PlumbBob);
        assert_eq!(&c.distortion.coefficients()[..2], &[0.01, -0.02]);
    }

    #[test]
    fn rational_and_fisheye_camera_infos_are_calibrations_and_unknown_models_are_refused() {
        let mut rational = info("rational_polynomial", 500.0);
        rational.d = vec![0.01, -0.02, 0.0, 0.0, 0.001, 0.0, 0.0, 0.0];
        let c = calibration(&rational).unwrap();
        assert_eq!(
            c.distortion.model(),
            pose::DistortionModel::RationalPolynomial
        );
        let mut fisheye = info("equidistant", 500.0);
        fisheye.d = vec![0.01, -0.002, 0.0, 0.0];
        let c = calibration(&fisheye).unwrap();
        assert_eq!(c.distortion.model(), pose::DistortionModel::Equidistant);
        let e = calibration(&info("fisheye_2000", 500.0)).unwrap_err();
        assert!(e.contains("unknown distortion model `fisheye_2000`"), "{e}");
    }

    #[test]
    fn zero_focal_length_is_an_error() {
        let e = calibration(&info("plumb_bob", 0.0)).unwrap_err();
        assert!(e.contains("focal"), "{e}");
    }

    /// #32: a NaN in CameraInfo was reported as "not valid YAML".
    #[test]
    fn a_non_finite_camera_info_value_names_its_field() {
        let e = calibration(&info("plumb_bob", f64::NAN)).unwrap_err();
        assert_eq!(e, "CameraInfo field `k[0]` is NaN, not a finite number");
        let mut bad = info("plumb_bob", 500.0);
        bad.d[1] = f64::INFINITY;
        let e = calibration(&bad).unwrap_err();
        assert_eq!(e, "CameraInfo field `d[1]` is inf, not a finite number");
    }

    fn raw<'a>(encoding: &str, w: u32, h: u32, bpp: u32, data: &'a [u8]) -> Image<'a> {
        Image {
            stamp_ns: 0,
            frame_id: String::new(),
            height: h,
            width: w,
            encoding: encoding.into(),
            is_bigendian: false,
            step: w * bpp,
            data,
        }
    }

    #[test]
    fn colour_orders_agree() {
        let rgb = [10u8, 200, 30, 90, 40, 250];
        let bgr = [30u8, 200, 10, 250, 40, 90];
        let rgba = [10u8, 200, 30, 7, 90, 40, 250, 7];
        let bgra = [30u8, 200, 10, 7, 250, 40, 90, 7];
        let mut out = Vec::new();
        for (enc, data, bpp) in [
            ("rgb8", &rgb[..], 3),
            ("bgr8", &bgr[..], 3),
            ("rgba8", &rgba[..], 4),
            ("bgra8", &bgra[..], 4),
        ] {
            let mut g = GreyImage::default();
            raw_to_grey(&raw(enc, 2, 1, bpp, data), &mut g, 100).unwrap();
            out.push(g.data);
        }
        assert_eq!(
            out[0],
            vec![bt601_luma(10, 200, 30), bt601_luma(90, 40, 250)]
        );
        assert!(out.iter().all(|o| *o == out[0]));
    }

    #[test]
    fn mono16_keeps_the_high_byte_in_either_order() {
        let mut g = GreyImage::default();
        raw_to_grey(
            &raw("mono16", 2, 1, 2, &[0x34, 0x12, 0xff, 0xab]),
            &mut g,
            9,
        )
        .unwrap();
        assert_eq!(g.data, vec![0x12, 0xab]);
        let mut img = raw("mono16", 2, 1, 2, &[0x12, 0x34, 0xab, 0xff]);
        img.is_bigendian = true;
        raw_to_grey(&img, &mut g, 9).unwrap();
        assert_eq!(g.data, vec![0x12, 0xab]);
    }

    #[test]
    fn a_uniform_bayer_mosaic_of_one_grey_is_that_grey() {
        let data = [77u8; 16];
        for enc in ["bayer_rggb8", "bayer_bggr8", "bayer_gbrg8", "bayer_grbg8"] {
            let mut g = GreyImage::default();
            raw_to_grey(&raw(enc, 4, 4, 1, &data), &mut g, 9).unwrap();
            assert!(g.data.iter().all(|v| *v == 77), "{enc}: {:?}", g.data);
        }
    }

    #[test]
    fn a_red_scene_through_each_bayer_pattern_gives_the_luma_of_red() {
        // Red 200 everywhere, green and blue 0: each pattern places the red samples where
        // its own letters say.
        for (enc, red_at) in [
            ("bayer_rggb8", (0, 0)),
            ("bayer_bggr8", (1, 1)),
            ("bayer_gbrg8", (1, 0)),
            ("bayer_grbg8", (0, 1)),
        ] {
            let mut data = [0u8; 36];
            for y in 0..6 {
                for x in 0..6 {
                    if (y % 2, x % 2) == red_at {
                        data[y * 6 + x] = 200;
                    }
                }
            }
            let mut g = GreyImage::default();
            raw_to_grey(&raw(enc, 6, 6, 1, &data), &mut g, 9).unwrap();
            let want = bt601_luma(200, 0, 0);
            assert!(g.data.iter().all(|v| *v == want), "{enc}: {:?}", g.data);
        }
    }

    #[test]
    fn short_data_and_bad_encodings_are_errors() {
        let mut g = GreyImage::default();
        let e = raw_to_grey(&raw("mono8", 4, 4, 1, &[0; 15]), &mut g, 9).unwrap_err();
        assert!(e.contains("needs 16"), "{e}");
        let e = raw_to_grey(&raw("yuv422", 2, 2, 2, &[0; 8]), &mut g, 9).unwrap_err();
        assert!(e.contains("`yuv422` is not supported"), "{e}");
        let e = raw_to_grey(&raw("mono8", 40, 4, 1, &[0; 160]), &mut g, 9).unwrap_err();
        assert!(e.contains("--max-side"), "{e}");
    }
}
