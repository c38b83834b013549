//! `formation-tracker detect --camera FILE --marker-size [ID=]METRES`: each marker's own pose
//! in OpenCV's marker frame, checked on a frontal marker at a known distance.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

mod common;

use fiducial::{Dictionary, RenderOptions, render_marker};
use std::path::PathBuf;

fn dir(name: &str) -> PathBuf {
    let d =
        PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A 640x480 frame with marker `index` drawn frontally, 12 px a cell, its quiet zone's top
/// left at `(x0, y0)`; returns the border's centre in pixels and its size in cells.
fn frontal_frame(
    path: &std::path::Path,
    index: usize,
    x0: u32,
    y0: u32,
) -> ((f64, f64), (u32, u32)) {
    let dict = Dictionary::paper();
    let family = dict.family();
    let opts = RenderOptions {
        px_per_cell: 12,
        quiet_cells: 2,
    };
    let m = render_marker(family, dict.code(index).unwrap(), &opts).unwrap();
    let mut img = image::GrayImage::from_pixel(640, 480, image::Luma([255]));
    for y in 0..m.height() {
        for x in 0..m.width() {
            let v = m.pixels()[y * m.width() + x];
            img.put_pixel(x0 + x as u32, y0 + y as u32, image::Luma([v]));
        }
    }
    img.save(path).unwrap();
    let c = m.corners();
    let centre = (
        x0 as f64 + (c[0].x + c[2].x) / 2.0,
        y0 as f64 + (c[0].y + c[2].y) / 2.0,
    );
    (centre, (family.width_cells(), family.height_cells()))
}

#[test]
fn a_frontal_marker_gets_its_pose() {
    let d = dir("marker-pose");
    let png = d.join("frontal.png");
    let (centre, (wc, hc)) = frontal_frame(&png, 7, 200, 120);
    std::fs::write(d.join("camera.yaml"), common::CAMERA).unwrap();
    // 25 mm cells: at 12 px a cell the marker is f * 0.025 / 12 m away.
    let (w, h) = (f64::from(wc) * 0.025, f64::from(hc) * 0.025);
    let f = 554.2562584220408;
    let z = f * 0.025 / 12.0;
    let out = common::run(
        &d,
        &[
            "detect",
            "frontal.png",
            "--camera",
            "camera.yaml",
            "--json",
            "--marker-size",
            "0.5",
            "--marker-size",
            &format!("7={w}x{h}"),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let markers = line["markers"].as_array().unwrap();
    assert_eq!(markers.len(), 1, "{line}");
    let pose = &markers[0]["pose"];
    let t: Vec<f64> = pose["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let expected = [(centre.0 - 319.5) * z / f, (centre.1 - 239.5) * z / f, z];
    for (a, b) in t.iter().zip(expected) {
        // The detector's corners are good to a few hundredths of a pixel here.
        assert!((a - b).abs() < 2e-3 * z, "{t:?} vs {expected:?}");
    }
    // Frontal and upright: the marker's axes are the camera's x, -y, -z, a half turn about x.
    let r: Vec<f64> = pose["rotation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(
        (r[0].abs() - std::f64::consts::PI).abs() < 0.02 && r[1].abs() < 0.02 && r[2].abs() < 0.02,
        "{r:?}"
    );
    assert!(pose["reprojection_rms_px"].as_f64().unwrap() < 0.5);
    assert!(
        pose["alternative"]["reprojection_rms_px"]
            .as_f64()
            .is_some()
    );
    let cov = pose["covariance"].as_array().unwrap();
    assert_eq!(cov.len(), 6);
    assert!(cov.iter().all(|row| row.as_array().unwrap().len() == 6));
    assert!(cov[5][5].as_f64().unwrap() > 0.0);
    // No marker pose was rejected (the robot stage may reject the rig pose: a frontal marker
    // at this height is not on a robot standing on the floor).
    assert!(
        line["rejected"]
            .as_array()
            .unwrap()
            .iter()
            .all(|r| r.get("marker").is_none()),
        "{line}"
    );

    // Without a size for that marker there is no pose.
    let out = common::run(
        &d,
        &[
            "detect",
            "frontal.png",
            "--camera",
            "camera.yaml",
            "--json",
            "--marker-size",
            "3=0.1",
        ],
    );
    let line: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(line["markers"][0]["pose"].is_null(), "{line}");
}

#[test]
fn bad_marker_sizes_are_usage_errors() {
    let d = dir("marker-pose-usage");
    std::fs::write(d.join("camera.yaml"), common::CAMERA).unwrap();
    image::GrayImage::from_pixel(64, 48, image::Luma([128]))
        .save(d.join("blank.png"))
        .unwrap();
    for args in [
        &["detect", "blank.png", "--marker-size", "0.065"][..],
        &[
            "detect",
            "blank.png",
            "--camera",
            "camera.yaml",
            "--marker-size",
            "-1",
        ][..],
        &[
            "detect",
            "blank.png",
            "--camera",
            "camera.yaml",
            "--marker-size",
            "x=0.1",
        ][..],
    ] {
        let out = common::run(&d, args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--marker-size") || err.contains("--camera"),
            "{err}"
        );
    }
}

#[test]
fn a_fisheye_calibration_works_end_to_end() {
    // The ROS equidistant (fisheye) fixture is for 1280x800 frames; a marker near the image
    // centre, where the lens is nearly a pinhole, gets a pose in front of the camera.
    let d = dir("marker-pose-fisheye");
    let png = d.join("frame.png");
    let dict = Dictionary::paper();
    let m = render_marker(
        dict.family(),
        dict.code(3).unwrap(),
        &RenderOptions {
            px_per_cell: 10,
            quiet_cells: 2,
        },
    )
    .unwrap();
    let mut img = image::GrayImage::from_pixel(1280, 800, image::Luma([255]));
    let (x0, y0) = (640 - m.width() as u32 / 2, 400 - m.height() as u32 / 2);
    for y in 0..m.height() {
        for x in 0..m.width() {
            img.put_pixel(
                x0 + x as u32,
                y0 + y as u32,
                image::Luma([m.pixels()[y * m.width() + x]]),
            );
        }
    }
    img.save(&png).unwrap();
    let camera = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/calibration/ros_equidistant.yaml");
    let (wc, hc) = (dict.family().width_cells(), dict.family().height_cells());
    let size = format!("{}x{}", f64::from(wc) * 0.02, f64::from(hc) * 0.02);
    let out = common::run(
        &d,
        &[
            "detect",
            "frame.png",
            "--camera",
            camera.to_str().unwrap(),
            "--json",
            "--marker-size",
            &size,
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let pose = &line["markers"][0]["pose"];
    assert!(pose["translation"][2].as_f64().unwrap() > 0.3, "{line}");
    assert!(
        pose["reprojection_rms_px"].as_f64().unwrap() < 1.0,
        "{line}"
    );
}

/// The README's real-camera example, end to end: `detect --dictionary tag36h11 --camera ...
/// --marker-size 0.065` on a Duckietown frame (real camera, 65 mm tags, the intrinsics of
/// its `test_info.yaml` written as an OpenCV calibration file) reads exactly the tags
/// AprilTag 3 reads there, and gives each the pose the `pose` crate solves from the corners
/// printed (the solver that `crates/fiducial/tests/duckietown.rs` checks against OpenCV's
/// `solvePnP(IPPE_SQUARE)` + `solvePnPRefineLM` to 1 mm and 0.1 degree on the same corners).
/// Against OpenCV's answers on the fixture's corners it agrees to 1 mm and 0.2 degree: the
/// CLI turns colour into grey with the Rec. 601 weights (as OpenCV and AprilTag do), the
/// fixture's corners come from `image`'s Rec. 709 grey, and the corners differ by up to
/// 0.02 px, which turns a 20 px tag by about a tenth of a degree.
#[test]
fn tag36h11_poses_on_a_real_frame_match_opencv() {
    use nalgebra::{Matrix3, Point2, Rotation3, Vector3};
    use pose::{Intrinsics, PoseSolver};
    let d = dir("tag36h11-pose");
    let k = Intrinsics::from_matrix(&Matrix3::new(
        338.563277422543,
        0.,
        336.45495347495824,
        0.,
        338.939280638548,
        230.486982216255,
        0.,
        0.,
        1.,
    ))
    .unwrap();
    let fixtures = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
    let frame = fixtures.join("realdata/duckietown/test_image_multiple_01.png");
    // The tests' OpenCV calibration file with this camera's matrix.
    let camera = common::CAMERA.replace(
        "554.2562584220408, 0., 319.5, 0., 554.2562584220408, 239.5",
        "338.563277422543, 0., 336.45495347495824, 0., 338.939280638548, 230.486982216255",
    );
    assert_ne!(camera, common::CAMERA);
    std::fs::write(d.join("camera.yaml"), camera).unwrap();
    let out = common::run(
        &d,
        &[
            "detect",
            frame.to_str().unwrap(),
            "--dictionary",
            "tag36h11",
            "--camera",
            "camera.yaml",
            "--marker-size",
            "0.065",
            "--json",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let opencv: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fixtures.join("opencv/duckietown_opencv.json")).unwrap(),
    )
    .unwrap();
    let vec3 = |v: &serde_json::Value| {
        let f: Vec<f64> = v
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        Vector3::new(f[0], f[1], f[2])
    };
    let markers = line["markers"].as_array().unwrap();
    let mut ids: Vec<u64> = markers.iter().map(|m| m["id"].as_u64().unwrap()).collect();
    ids.sort_unstable();
    // The frame's tags in the fixture: the ids AprilTag 3 reads there (which
    // `crates/fiducial/tests/duckietown.rs` checks).
    let expected: Vec<u64> = opencv["cases"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|c| {
            let name = c["name"].as_str().unwrap();
            let id = name.strip_prefix("test_image_multiple_01.png:")?;
            id.parse().ok()
        })
        .collect::<std::collections::BTreeSet<u64>>()
        .into_iter()
        .collect();
    assert!(!expected.is_empty());
    assert_eq!(ids, expected, "{line}");
    for m in markers {
        // Reported under OpenCV's name for the family, whichever name was asked for.
        assert_eq!(m["dictionary"], "DICT_APRILTAG_36h11", "{m}");
        let name = format!("test_image_multiple_01.png:{}", m["id"]);
        let cv = opencv["cases"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["name"] == name.as_str())
            .unwrap();
        let (t, r) = (
            vec3(&m["pose"]["translation"]),
            Rotation3::from_scaled_axis(vec3(&m["pose"]["rotation"])),
        );
        // The pose solved from the corners printed.
        let corners: Vec<Point2<f64>> = m["corners"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| Point2::new(c[0].as_f64().unwrap(), c[1].as_f64().unwrap()))
            .collect();
        let solved = PoseSolver::new(k)
            .solve_square_marker(&corners.try_into().unwrap(), 0.065)
            .unwrap()
            .best
            .pose;
        assert!((solved.translation - t).norm() < 1e-9, "{name}");
        assert!(
            (solved.rotation - vec3(&m["pose"]["rotation"])).norm() < 1e-9,
            "{name}"
        );
        // OpenCV on the fixture's corners.
        let theirs = &cv["solutions"][0];
        let dt = (t - vec3(&theirs["translation"])).norm();
        let dr = r
            .angle_to(&Rotation3::from_scaled_axis(vec3(&theirs["rotation"])))
            .to_degrees();
        assert!(dt < 1e-3 && dr < 0.2, "{name}: {dt} m, {dr} deg");
    }
}
