//! `formation-tracker detect --camera`: the `robots` of each image agree with the ground truth
//! of a rendered paper scene, and bad robot-stage options are one-line errors.

use std::path::PathBuf;
use std::process::Command;

use formation_sim::scene::SceneTruth;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
}

fn fixture(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(path)
}

fn dir() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("detect-robots-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temporary directory");
    d
}

#[test]
fn robots_match_the_truth_of_a_rendered_scene() {
    let d = dir();
    let (png, truth) = (d.join("fig10.png"), d.join("fig10.json"));
    let ok = bin()
        .args(["render", "--paper-fig", "10", "--out"])
        .arg(&png)
        .arg("--truth")
        .arg(&truth)
        .status()
        .unwrap();
    assert!(ok.success());
    let truth: SceneTruth =
        serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    let out = bin()
        .arg("detect")
        .arg(&png)
        .arg("--camera")
        .arg(fixture("scenes/camera-640x480-hfov60.yaml"))
        .args(["--mount", "0,0.30", "--pan", "0", "--json"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let robots = line["robots"].as_array().unwrap();
    assert_eq!(robots.len(), 2, "{line}");
    for r in robots {
        let n = r["robot"].as_u64().unwrap() as u32;
        let t = truth.robot(n).unwrap();
        let l12 = r["l12"].as_f64().unwrap();
        assert!(
            (l12 - t.formation.l12).abs() / t.formation.l12 < 0.01,
            "robot {n}: l12 {l12} vs {}",
            t.formation.l12
        );
        for i in 0..3 {
            let tr = r["translation"][i].as_f64().unwrap();
            assert!(
                (tr - t.translation[i]).abs() < 0.05,
                "robot {n} translation"
            );
            let rv = r["rotation"][i].as_f64().unwrap();
            assert!((rv - t.rotation[i]).abs() < 0.05, "robot {n} rotation");
        }
        let faces: Vec<u64> = r["faces"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_u64().unwrap())
            .collect();
        assert!(faces.len() >= 2, "robot {n}: {faces:?}");
        assert!(r["reprojection_rms_px"].as_f64().unwrap() < 1.0);
        assert_eq!(r["ambiguous"].as_bool(), Some(false));
        for key in ["alpha12", "beta12"] {
            assert!(r[key].as_f64().is_some(), "{key}");
        }
    }
    // The output format: every robot's field names, in this order.
    let text = String::from_utf8(out.stdout.clone()).unwrap();
    let fields = [
        "robot",
        "faces",
        "rejected_faces",
        "rejections",
        "rotation",
        "translation",
        "reprojection_rms_px",
        "l12",
        "alpha12",
        "beta12",
        "covariance",
        "ambiguous",
        "ambiguity_ratio",
        "ground_plane",
    ];
    for r in robots {
        let keys: Vec<&str> = r.as_object().unwrap().keys().map(String::as_str).collect();
        let mut sorted = fields.to_vec();
        sorted.sort_unstable();
        let mut got = keys.clone();
        got.sort_unstable();
        assert_eq!(got, sorted, "robot fields");
    }
    let robots_text = &text[text.find("\"robots\":[").expect("a robots array")..];
    for object in robots_text.split("{\"robot\":").skip(1).take(robots.len()) {
        let mut at = 0;
        for name in &fields[1..] {
            let key = format!(",\"{name}\":");
            let pos = object[at..]
                .find(&key)
                .unwrap_or_else(|| panic!("field {name} missing or out of order in {object}"));
            at += pos + key.len();
        }
    }
    // Without --camera, `robots` stays empty.
    let out = bin()
        .arg("detect")
        .arg(&png)
        .arg("--json")
        .output()
        .unwrap();
    let line: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(line["robots"].as_array().map(Vec::len), Some(0));
}

#[test]
fn bad_robot_options_are_one_line_errors() {
    let d = dir();
    let png = d.join("blank.png");
    image::GrayImage::from_pixel(64, 48, image::Luma([128]))
        .save(&png)
        .unwrap();
    for (args, needle) in [
        (vec!["--pan", "0.1"], "need --camera"),
        (vec!["--camera", "no-such-file.yaml"], "no-such-file"),
        (vec!["--camera", "CAM", "--mount", "0.5"], "--mount"),
        (
            vec!["--camera", "CAM", "--mount", "0.5,x"],
            "--mount 0.5,x: HEIGHT `x`: `x` is not a number",
        ),
        (
            vec!["--camera", "CAM", "--rig", "no-such-rig.yaml"],
            "no-such-rig",
        ),
    ] {
        let cam = fixture("scenes/camera-640x480-hfov60.yaml");
        let args: Vec<String> = args
            .iter()
            .map(|a| {
                if *a == "CAM" {
                    cam.display().to_string()
                } else {
                    a.to_string()
                }
            })
            .collect();
        let out = bin().arg("detect").arg(&png).args(&args).output().unwrap();
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}
