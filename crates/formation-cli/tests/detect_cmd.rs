//! `formation-tracker detect`: reads the markers of rendered scenes with the right robot,
//! face and corners, one JSON line per image; an unreadable file is one error line and a
//! non-zero exit while the other images are still reported.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::PathBuf;
use std::process::Command;

use fiducial::Dictionary;
use formation_tracker::rig::RigModel;
use marker_testkit::{CellPattern, SceneConfig, marker_scene};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Every entry of `dict` as a test pattern (index = dictionary index).
fn entries(dict: &Dictionary) -> Vec<CellPattern> {
    let f = dict.family();
    CellPattern::from_codes(
        f.rows() as usize,
        f.cols() as usize,
        (0..dict.len()).map(|i| dict.code(i).unwrap_or(0)),
    )
}

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("detect-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
}

#[test]
fn reads_scenes_and_reports_bad_files() {
    let d = dir("scenes");
    let cfg = SceneConfig {
        markers: 5,
        min_side: 40.0,
        ..SceneConfig::default()
    };
    let scene = marker_scene(
        &cfg,
        &entries(Dictionary::paper()),
        &mut ChaCha8Rng::seed_from_u64(5),
    )
    .unwrap();
    let grey = image::GrayImage::from_raw(640, 480, scene.pixels.clone()).unwrap();
    let png = d.join("scene.png");
    grey.save(&png).unwrap();
    // The same scene as RGB, to exercise colour conversion.
    let rgb = image::DynamicImage::ImageLuma8(grey).into_rgb8();
    let rgb_png = d.join("scene-rgb.png");
    rgb.save(&rgb_png).unwrap();
    let bad = d.join("not-an-image.png");
    std::fs::write(&bad, b"definitely not a PNG").unwrap();

    let out = bin()
        .arg("detect")
        .arg(&png)
        .arg(&bad)
        .arg(&rgb_png)
        .arg("--json")
        .output()
        .unwrap();
    // Exit code 3: partial, one of three images could not be read (docs/reliability.md).
    assert_eq!(out.status.code(), Some(3), "a bad file must fail the run");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(
        stderr
            .lines()
            .filter(|l| l.contains("not-an-image.png"))
            .count(),
        1,
        "{stderr}"
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2, "{stdout}");
    for line in &lines {
        assert_eq!(line["width"], 640);
        assert_eq!(line["height"], 480);
        assert!(line["robots"].as_array().unwrap().is_empty());
        assert!(line["timing"]["detect_ms"].as_f64().unwrap() >= 0.0);
        let markers = line["markers"].as_array().unwrap();
        assert_eq!(markers.len(), scene.markers.len(), "{line}");
        for truth in &scene.markers {
            let index = truth.index.unwrap();
            let (robot, face) = RigModel::reference().robot_face(index).unwrap();
            let m = markers
                .iter()
                .find(|m| m["index"] == index)
                .unwrap_or_else(|| panic!("marker {index} not reported"));
            assert_eq!(m["robot"], robot);
            assert_eq!(m["face"], face);
            assert_eq!(m["code"], Dictionary::paper().codes()[index]);
            assert_eq!(m["hamming"], 0);
            for (i, c) in m["corners"].as_array().unwrap().iter().enumerate() {
                let (x, y) = (c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
                let e = (x - truth.corners[i].x).hypot(y - truth.corners[i].y);
                assert!(e < 0.2, "corner {i} of marker {index} off by {e} px");
            }
        }
    }
    assert_eq!(
        lines[0]["markers"], lines[1]["markers"],
        "grey and RGB differ"
    );
}

#[test]
fn human_listing_names_robots_and_faces() {
    let d = dir("listing");
    let cfg = SceneConfig {
        markers: 2,
        min_side: 60.0,
        ..SceneConfig::default()
    };
    let scene = marker_scene(
        &cfg,
        &entries(Dictionary::paper()),
        &mut ChaCha8Rng::seed_from_u64(8),
    )
    .unwrap();
    let png = d.join("two.png");
    image::GrayImage::from_raw(640, 480, scene.pixels.clone())
        .unwrap()
        .save(&png)
        .unwrap();
    let out = bin().arg("detect").arg(&png).output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("2 marker(s)"), "{text}");
    for m in &scene.markers {
        let (robot, face) = RigModel::reference().robot_face(m.index.unwrap()).unwrap();
        assert!(
            text.contains(&format!("robot {robot} face {face} ")),
            "{text}"
        );
    }
}

/// The ids `detect --json` reads in one image, sorted.
fn ids_read(args: &[&str], image: &std::path::Path) -> Vec<u64> {
    corners_read(args, image).into_iter().map(|m| m.0).collect()
}

/// `detect` reads the Duckietown tag that touches something as dark as its ink (id 58 in
/// this frame; AprilTag 3 reads all five) by default, with boundary clustering;
/// `--no-boundary-clusters` misses it (and reads the four others, ids 22, 24 and 85 seen at
/// a grazing angle among them); the old `--boundary-clusters` flag still runs and changes
/// nothing; `--no-motion-blur` changes nothing on this sharp frame.
#[test]
fn boundary_clusters_are_on_by_default_and_read_tags_touching_dark_regions() {
    let frame = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/realdata/duckietown/test_image_multiple_09.png");
    let default = ids_read(&["--dictionary", "tag36h11"], &frame);
    let plain = ids_read(
        &["--dictionary", "tag36h11", "--no-boundary-clusters"],
        &frame,
    );
    assert_eq!(default, vec![22, 24, 58, 85, 144]);
    assert_eq!(plain, vec![22, 24, 85, 144], "without clustering");
    assert_eq!(
        ids_read(&["--dictionary", "tag36h11", "--boundary-clusters"], &frame),
        default
    );
    assert_eq!(
        ids_read(&["--dictionary", "tag36h11", "--no-motion-blur"], &frame),
        default
    );
}

/// The markers `detect --json` reads in one image, as (id, corners x0 y0 .. x3 y3), by id.
fn corners_read(args: &[&str], image: &std::path::Path) -> Vec<(u64, Vec<f64>)> {
    let out = bin()
        .arg("detect")
        .arg("--json")
        .args(args)
        .arg(image)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let mut found: Vec<(u64, Vec<f64>)> = line["markers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            let corners = m["corners"].as_array().unwrap();
            let xy = corners
                .iter()
                .flat_map(|c| c.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()))
                .collect();
            (m["id"].as_u64().unwrap(), xy)
        })
        .collect();
    found.sort_by_key(|m| m.0);
    found
}

/// `--photometric` (the tracker's `DetectorConfig::for_pose`) reads the same tags and moves
/// the corners of those with cells under 3 px by a fraction of a pixel; without it (the
/// library's default) they are the pattern step's. Duckietown `test_image_multiple_01.png`:
/// tag 144's cells are wider and it keeps its corners exactly.
#[test]
fn photometric_fits_the_small_tags_only_when_asked() {
    let frame = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/realdata/duckietown/test_image_multiple_01.png");
    let plain = corners_read(&["--dictionary", "tag36h11"], &frame);
    let fitted = corners_read(&["--dictionary", "tag36h11", "--photometric"], &frame);
    let ids = |v: &[(u64, Vec<f64>)]| v.iter().map(|m| m.0).collect::<Vec<_>>();
    assert_eq!(ids(&plain), ids(&fitted));
    let moved: Vec<(u64, f64)> = plain
        .iter()
        .zip(&fitted)
        .map(|(a, b)| {
            let most = a.1.iter().zip(&b.1).map(|(p, q)| (p - q).abs());
            (a.0, most.fold(0.0, f64::max))
        })
        .collect();
    assert!(
        moved.iter().filter(|m| m.1 > 0.01).count() >= 3,
        "{moved:?}"
    );
    assert!(moved.iter().all(|m| m.1 < 1.0), "{moved:?}");
    assert!(moved.iter().any(|m| m.0 == 144 && m.1 == 0.0), "{moved:?}");
}
