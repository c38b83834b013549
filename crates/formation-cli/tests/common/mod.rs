//! Helpers shared by the command tests.
#![allow(dead_code)] // each test binary uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A 640 x 480 pinhole calibration (60 deg horizontal field of view, no distortion), as
/// OpenCV writes it.
pub const CAMERA: &str = "%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 554.2562584220408, 0., 319.5, 0., 554.2562584220408, 239.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
";

/// A folder with a calibration and three blank 640x480 frames (nothing to find, but every
/// frame still prints a line).
pub fn blank_frames(name: &str) -> PathBuf {
    let d =
        PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(d.join("frames")).unwrap();
    std::fs::write(d.join("camera.yaml"), CAMERA).unwrap();
    for k in 0..3 {
        image::GrayImage::from_pixel(640, 480, image::Luma([128]))
            .save(d.join("frames").join(format!("f{k}.png")))
            .unwrap();
    }
    d
}

/// Runs the binary with `args` in `dir`, and returns what it did.
pub fn run(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}
