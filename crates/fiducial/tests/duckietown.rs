//! Real camera frames (`fixtures/realdata/duckietown/`, tag36h11, 640 x 480): on every
//! frame we read exactly the ids AprilTag 3 reads there (every one of them, no other id, none
//! twice); and our single-marker pose on these frames agrees with OpenCV's on our corners.
//!
//! History (issue #13): 46 of the 56 tags before the re-cut of merged components
//! (`fiducial::split`), 51 with it, 52 once the light cut of the motion-blur path also read
//! id 198 in `test_image_multiple_01.png`, 55 once the first pass took corners as sharp as
//! 15 degrees (ids 22, 24 and 85 in `test_image_multiple_09.png` lie almost flat on the
//! table; the limit was 30). The last one (id 58 in that frame) touches something as dark as
//! its ink, so no closed dark component has its outline; boundary clustering
//! (`fiducial::cluster`, AprilTag 3's way of finding quads, on in `formation-tracker
//! detect`) reads it.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::PathBuf;

use fiducial::{Decoded, Detector, DetectorConfig, GrayView, dictionary_by_name};

mod common;

/// The ids AprilTag 3 reads per frame (fixtures/realdata/duckietown/README.md).
const APRILTAG3: &[(&str, &[usize])] = &[
    ("test_image.png", &[60, 82, 318, 328, 387]),
    ("test_image_multiple_01.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_02.png", &[22, 24, 85, 144, 198]),
    ("test_image_multiple_03.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_04.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_05.png", &[22, 24, 85, 198]),
    ("test_image_multiple_06.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_07.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_08.png", &[85, 144, 198]),
    ("test_image_multiple_09.png", &[22, 24, 58, 85, 144]),
    ("test_image_multiple_10.png", &[24, 58, 85, 198]),
];

/// A tag36h11 detector with the default settings, boundary clustering as given.
fn tag36h11_detector(boundary_clusters: bool) -> Detector {
    Detector::with_dictionary(
        DetectorConfig {
            boundary_clusters,
            ..DetectorConfig::default()
        },
        dictionary_by_name("tag36h11").unwrap().clone(),
    )
}

/// Reads the Duckietown frame `file` (as grey) and detects its markers into `out`.
fn detect_frame(det: &mut Detector, file: &str, out: &mut Vec<Decoded>) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/realdata/duckietown");
    let img = image::open(dir.join(file)).unwrap().to_luma8();
    let (w, h) = img.dimensions();
    det.detect(
        &GrayView::new(img.as_raw(), w as usize, h as usize).unwrap(),
        out,
    );
}

#[test]
fn duckietown_frames_read_every_apriltag3_id_and_no_other() {
    // Tag 58 of frame 09 touches something as dark as its ink: boundary clustering reads it.
    let mut det = tag36h11_detector(true);
    let mut expected = 0;
    let mut out = Vec::new();
    for (file, ids) in APRILTAG3 {
        detect_frame(&mut det, file, &mut out);
        let mut got: Vec<usize> = out.iter().map(|d| d.index).collect();
        got.sort_unstable();
        let mut want = ids.to_vec();
        want.sort_unstable();
        assert_eq!(
            got, want,
            "{file}: ids read (left) against AprilTag 3's (right)"
        );
        expected += ids.len();
    }
    assert_eq!(expected, 56);
}

/// No false read with any other dictionary (issue #31): every name `--dictionary` accepts,
/// boundary clustering on (the widest search, `formation-tracker detect`'s), reads nothing
/// on frames whose only markers are tag36h11 tags (tag36h11 itself, and its OpenCV name,
/// are the test above).
#[test]
fn no_other_dictionary_reads_anything_on_the_duckietown_frames() {
    let detectors = common::other_dictionary_detectors("tag36h11");
    // The paper's own dictionary and every OpenCV one but DICT_APRILTAG_36h11.
    assert!(detectors.len() >= 20, "{} dictionaries", detectors.len());
    let mut out = Vec::new();
    for (name, mut det) in detectors {
        for (file, _) in APRILTAG3 {
            detect_frame(&mut det, file, &mut out);
            assert!(out.is_empty(), "{name} on {file}: {out:?}");
        }
    }
}

/// Without boundary clustering (the library's default) every id read is one AprilTag 3
/// reads, and only tag 58 of `test_image_multiple_09.png`, which touches something as dark
/// as its ink, is missed (55 of 56). Regression: with the first pass's corners limited to
/// 30 degrees (the default until 2026-12-07) ids 22, 24 and 85 of that frame, thin
/// parallelograms seen at a grazing angle (24 degrees for id 24), were missed too (52).
#[test]
fn the_default_detector_reads_55_of_the_56_tags_and_no_wrong_id() {
    let mut det = tag36h11_detector(false);
    let (mut read, mut out) = (0, Vec::new());
    for (file, ids) in APRILTAG3 {
        detect_frame(&mut det, file, &mut out);
        for d in &out {
            assert!(ids.contains(&d.index), "{file}: id {} read", d.index);
        }
        let missed: Vec<usize> = ids
            .iter()
            .copied()
            .filter(|id| !out.iter().any(|d| d.index == *id))
            .collect();
        if *file == "test_image_multiple_09.png" {
            assert_eq!(missed, vec![58], "{file}");
        } else {
            assert!(missed.is_empty(), "{file}: missed {missed:?}");
        }
        read += out.len();
    }
    assert_eq!(read, 55);
}

/// The three tags of `test_image_multiple_09.png` that the first pass reads since its
/// corners may be as sharp as 15 degrees are lost at the old limit of 30: the limit, not
/// a merge with the table, was what hid them.
#[test]
fn at_30_degrees_the_grazing_tags_of_frame_09_are_lost() {
    let mut det = Detector::with_dictionary(
        DetectorConfig {
            min_angle_deg: 30.0,
            ..DetectorConfig::default()
        },
        dictionary_by_name("tag36h11").unwrap().clone(),
    );
    let mut out = Vec::new();
    detect_frame(&mut det, "test_image_multiple_09.png", &mut out);
    let ids: Vec<usize> = out.iter().map(|d| d.index).collect();
    assert_eq!(ids, vec![144]);
}

fn fixture_json(name: &str) -> serde_json::Value {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/opencv")
        .join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (cargo xtask solvepnp --duckietown)",
            path.display()
        )
    });
    serde_json::from_str(&text).unwrap()
}

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// Our single-marker pose on the Duckietown frames against OpenCV's `solvePnP` (IPPE_SQUARE,
/// refined by `solvePnPRefineLM`) run on our own corners: to 1 mm and 0.1 degree. The corner
/// sets and OpenCV's answers come from `cargo xtask solvepnp --duckietown`
/// (`fixtures/opencv/duckietown_*.json`); the frames are rectified, so neither side applies
/// a distortion. The corner sets must still be what the detector reads today (every tag,
/// corners within 0.05 px), or the fixture is stale.
#[test]
fn duckietown_poses_match_opencv_on_our_corners() {
    use nalgebra::{Matrix3, Point2, Vector3};
    use pose::{Intrinsics, Pose, PoseSolver};

    let cases = fixture_json("duckietown_cases.json");
    let opencv = fixture_json("duckietown_opencv.json");
    let cases = cases["cases"].as_array().unwrap().clone();
    let cams = fixture_json("duckietown_cases.json")["cameras"].clone();
    let cv_cases = opencv["cases"].as_array().unwrap();
    assert_eq!(cases.len(), cv_cases.len());

    // The recorded corners are today's detections.
    // Tag 58 of frame 09 touches something as dark as its ink: boundary clustering reads it.
    let mut det = tag36h11_detector(true);
    let mut out = Vec::new();
    let mut read = 0;
    for (file, _) in APRILTAG3 {
        detect_frame(&mut det, file, &mut out);
        for d in &out {
            let name = format!("{file}:{}", d.index);
            let case = cases
                .iter()
                .find(|c| c["name"] == name.as_str())
                .unwrap_or_else(|| {
                    panic!("{name} not in the fixture: cargo xtask solvepnp --duckietown")
                });
            for (p, c) in d.corners.iter().zip(case["corners"].as_array().unwrap()) {
                let c = floats(c);
                assert!(
                    (p.x - c[0]).hypot(p.y - c[1]) < 0.05,
                    "{name}: corners moved since the fixture (cargo xtask solvepnp --duckietown)"
                );
            }
            read += 1;
        }
    }
    assert_eq!(read, cases.len(), "the fixture has tags we no longer read");

    let (mut worst_t, mut worst_r) = (0.0f64, 0.0f64);
    for (case, cv) in cases.iter().zip(cv_cases) {
        assert_eq!(case["name"], cv["name"]);
        let cam = cams
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["name"] == case["camera"])
            .unwrap();
        assert_eq!(floats(&cam["distortion"]), vec![0.0; 5]);
        let k = Intrinsics::from_matrix(&Matrix3::from_row_slice(&floats(&cam["k"]))).unwrap();
        let corners: Vec<Point2<f64>> = case["corners"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| {
                let c = floats(c);
                Point2::new(c[0], c[1])
            })
            .collect();
        let corners: [Point2<f64>; 4] = corners.try_into().unwrap();
        let ours = PoseSolver::new(k)
            .solve_square_marker(&corners, case["size"].as_f64().unwrap())
            .unwrap();
        let s = &cv["solutions"][0];
        let theirs = Pose::new(
            Vector3::from_column_slice(&floats(&s["rotation"])),
            Vector3::from_column_slice(&floats(&s["translation"])),
        );
        let dt = (ours.best.pose.translation - theirs.translation).norm();
        let dr = ours.best.pose.rotation_angle_to(&theirs).to_degrees();
        assert!(dt < 1e-3 && dr < 0.1, "{}: {dt} m, {dr} deg", case["name"]);
        (worst_t, worst_r) = (worst_t.max(dt), worst_r.max(dr));
    }
    eprintln!(
        "{} tags: worst {:.2e} m, {:.2e} deg against OpenCV",
        cases.len(),
        worst_t,
        worst_r
    );
}
