//! An image whose size is not the calibration's is an error (its pose would be off by the
//! scale, hundreds of pixels), unless `--scale-calibration` says it was resized from the
//! calibrated camera's images; then the intrinsics are scaled and the pose is the same.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::process::Output;

mod common;
use common::run;

/// `l12` of every robot in a `detect --json` line.
fn l12s(out: &Output) -> Vec<f64> {
    let line: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&out.stdout).trim()).unwrap();
    line["robots"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["l12"].as_f64().unwrap())
        .collect()
}

#[test]
fn detect_refuses_a_resized_image_unless_told_to_scale() {
    let d = common::blank_frames("calibration-size");
    let out = run(&d, &["render", "--paper-fig", "7", "--out", "fig7.png"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let small = image::open(d.join("fig7.png")).unwrap();
    small
        .resize_exact(1280, 960, image::imageops::FilterType::Triangle)
        .save(d.join("big.png"))
        .unwrap();
    small
        .crop_imm(0, 60, 640, 360)
        .save(d.join("crop.png"))
        .unwrap();

    let reference = run(
        &d,
        &["detect", "--json", "--camera", "camera.yaml", "fig7.png"],
    );
    assert!(reference.status.success());
    let want = l12s(&reference);
    assert!(!want.is_empty(), "no robot in fig. 7");

    let refused = run(
        &d,
        &["detect", "--json", "--camera", "camera.yaml", "big.png"],
    );
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("1280x960")
            && stderr.contains("640x480")
            && stderr.contains("--scale-calibration"),
        "{stderr}"
    );
    assert!(refused.stdout.is_empty());

    let scaled = run(
        &d,
        &[
            "detect",
            "--json",
            "--scale-calibration",
            "--camera",
            "camera.yaml",
            "big.png",
        ],
    );
    assert!(
        scaled.status.success(),
        "{}",
        String::from_utf8_lossy(&scaled.stderr)
    );
    let got = l12s(&scaled);
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert!(
            (g - w).abs() < 0.005 * w,
            "l12 {g} m from the resized image, {w} m from the original"
        );
    }

    let crop = run(
        &d,
        &[
            "detect",
            "--scale-calibration",
            "--camera",
            "camera.yaml",
            "crop.png",
        ],
    );
    let stderr = String::from_utf8_lossy(&crop.stderr);
    assert_eq!(crop.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("not a resize"), "{stderr}");
}

#[test]
fn track_refuses_resized_frames_unless_told_to_scale() {
    let d = common::blank_frames("calibration-size-track");
    std::fs::create_dir_all(d.join("big")).unwrap();
    for k in 0..2 {
        image::GrayImage::from_pixel(1280, 960, image::Luma([128]))
            .save(d.join("big").join(format!("f{k}.png")))
            .unwrap();
    }
    let refused = run(&d, &["track", "--camera", "camera.yaml", "big"]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("--scale-calibration"), "{stderr}");
    let scaled = run(
        &d,
        &[
            "track",
            "--scale-calibration",
            "--camera",
            "camera.yaml",
            "big",
        ],
    );
    assert!(
        scaled.status.success(),
        "{}",
        String::from_utf8_lossy(&scaled.stderr)
    );
    assert_eq!(String::from_utf8_lossy(&scaled.stdout).lines().count(), 2);
}
