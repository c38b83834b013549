//! `formation-tracker markers`: the JSON agrees with the PNGs (each PNG decodes at its
//! `corners_px` to its `code`), and too many robots is a clear error.

use std::path::PathBuf;
use std::process::Command;

use fiducial::{DecodeParams, Dictionary, GrayView, decode};
use formation_tracker::rig::RigModel;
use nalgebra::Point2;

fn out_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("markers-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
}

#[test]
fn json_matches_the_pngs() {
    let dir = out_dir("ok");
    let status = bin()
        .args(["markers", "--out"])
        .arg(&dir)
        .args(["--robots", "3", "--px-per-cell", "9"])
        .status()
        .unwrap();
    assert!(status.success());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("markers.json")).unwrap()).unwrap();
    let entries = json.as_array().unwrap();
    assert_eq!(entries.len(), 15);
    let dict = Dictionary::paper();
    for e in entries {
        let robot = e["robot"].as_u64().unwrap() as u32;
        let face = e["face"].as_u64().unwrap() as u8;
        let code = e["code"].as_u64().unwrap();
        assert_eq!(
            code,
            dict.codes()[RigModel::reference().index_of(robot, face).unwrap()]
        );
        let size: Vec<f64> = e["size_m"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert!((size[0] - 0.14).abs() < 1e-12 && (size[1] - 0.12).abs() < 1e-12);
        let corners: Vec<Point2<f64>> = e["corners_px"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| Point2::new(c[0].as_f64().unwrap(), c[1].as_f64().unwrap()))
            .collect();
        let corners: fiducial::Corners = corners.try_into().unwrap();
        let png = image::open(dir.join(e["png"].as_str().unwrap()))
            .unwrap()
            .to_luma8();
        assert_eq!((png.width(), png.height()), (9 * 9, 8 * 9));
        // The PNG carries its print scale: 9 px per 0.02 m cell = 450 px/m, so the border's
        // corners print size_m apart.
        let file = std::fs::File::open(dir.join(e["png"].as_str().unwrap())).unwrap();
        let reader = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .unwrap();
        let dims = reader.info().pixel_dims.expect("a pHYs chunk");
        assert_eq!(
            (dims.xppu, dims.yppu, dims.unit),
            (450, 450, png::Unit::Meter)
        );
        assert!(((corners[1].x - corners[0].x) / 450.0 - size[0]).abs() < 1e-9);
        let view =
            GrayView::new(png.as_raw(), png.width() as usize, png.height() as usize).unwrap();
        let d = decode(&view, &corners, dict, &DecodeParams::default()).unwrap();
        assert_eq!(
            (d.code, d.rotation, d.distance),
            (code, 0, 0),
            "robot {robot} face {face}"
        );
        let svg = std::fs::read_to_string(dir.join(e["svg"].as_str().unwrap())).unwrap();
        assert!(svg.contains("width=\"180mm\" height=\"160mm\""));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn too_many_robots_is_a_clear_error() {
    let dir = out_dir("too-many");
    let too_many = RigModel::reference().max_robots(Dictionary::paper()) + 1;
    let out = bin()
        .args(["markers", "--out"])
        .arg(&dir)
        .args(["--robots", &too_many.to_string()])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("robots the dictionary supports"), "{err}");
    assert!(!dir.join("markers.json").exists());
}

#[test]
fn rig_file_chooses_the_faces_and_the_codes() {
    let dir = out_dir("rig");
    let rig = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/rigs/three-faces-custom-codes.yaml");
    let out = bin()
        .args(["markers", "--out"])
        .arg(&dir)
        .args(["--robots", "3", "--rig"])
        .arg(&rig)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("markers.json")).unwrap()).unwrap();
    let dict = Dictionary::paper();
    let model = formation_io::rigfile::load(&rig, dict).unwrap();
    let entries = json.as_array().unwrap();
    // Only the (robot, face) pairs of the rig's table, each with its own code.
    let expected: Vec<(u32, u8)> = (1..=3)
        .flat_map(|r| model.faces.iter().map(move |f| (r, f.face)))
        .filter(|&(r, f)| model.index_of(r, f).is_some())
        .collect();
    assert_eq!(entries.len(), expected.len());
    assert!(
        expected.len() < 9,
        "the fixture leaves some faces without a marker"
    );
    for (e, (robot, face)) in entries.iter().zip(&expected) {
        assert_eq!(e["robot"].as_u64().unwrap() as u32, *robot);
        assert_eq!(e["face"].as_u64().unwrap() as u8, *face);
        let index = model.index_of(*robot, *face).unwrap();
        assert_eq!(e["index"].as_u64().unwrap() as usize, index);
        assert_eq!(e["code"].as_u64().unwrap(), dict.codes()[index]);
        assert!(dir.join(e["png"].as_str().unwrap()).is_file());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_bad_rig_file_is_one_error_line() {
    let dir = out_dir("bad-rig");
    let rig = dir.with_extension("yaml");
    std::fs::write(&rig, "cell_size_mm: 20\n").unwrap();
    let out = bin()
        .args(["markers", "--out"])
        .arg(&dir)
        .arg("--rig")
        .arg(&rig)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("cell_size_mm"), "{err}");
    let _ = std::fs::remove_file(&rig);
}
