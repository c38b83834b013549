//! `markers --dictionary NAME --ids LIST` and `detect --dictionary NAME` (repeatable): standard
//! markers printed by the CLI are read back with their dictionary, id, OpenCV corner order
//! and Hamming distance; own-dictionary markers keep `code`, `robot` and `face`; unknown
//! names and ids are one clear error line.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::PathBuf;
use std::process::Command;

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("dictionary-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
}

/// Checks that the first marker object of a `detect --json` line has exactly `fields`, in
/// this order (serde_json's `Value` sorts keys, so the raw text is read).
fn fields_in_order(line: &str, value: &serde_json::Value, fields: &[&str]) {
    let mut got: Vec<&str> = value
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    got.sort_unstable();
    let mut want = fields.to_vec();
    want.sort_unstable();
    assert_eq!(got, want, "marker fields in {line}");
    let object = &line[line.find("\"markers\":[{").unwrap()..];
    let mut at = 0;
    for name in fields {
        let key = format!("\"{name}\":");
        at += object[at..]
            .find(&key)
            .unwrap_or_else(|| panic!("field {name} out of order in {object}"))
            + key.len();
    }
}

#[test]
fn printed_standard_markers_are_read_back_with_dictionary_and_id() {
    let d = dir("print");
    let st = bin()
        .args([
            "markers",
            "--dictionary",
            "tag36h11",
            "--ids",
            "0-2,586",
            "--size-mm",
            "65",
        ])
        .arg("--out")
        .arg(&d)
        .status()
        .unwrap();
    assert!(st.success());
    let list: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("markers.json")).unwrap()).unwrap();
    let list = list.as_array().unwrap();
    assert_eq!(list.len(), 4);
    assert_eq!(list[3]["dictionary"], "DICT_APRILTAG_36h11");
    assert_eq!(list[3]["id"], 586);
    assert!((list[3]["size_m"][0].as_f64().unwrap() - 0.065).abs() < 1e-12);
    // Also an own-dictionary marker, to check both schemas in one pass.
    let own = dir("own");
    assert!(
        bin()
            .args(["markers", "--robots", "1"])
            .arg("--out")
            .arg(&own)
            .status()
            .unwrap()
            .success()
    );
    let mut cmd = bin();
    cmd.args([
        "detect",
        "--json",
        "--dictionary",
        "TAG36H11",
        "--dictionary",
        "own",
    ]);
    for e in list {
        cmd.arg(d.join(e["png"].as_str().unwrap()));
    }
    cmd.arg(own.join("robot1-face3.png"));
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let raw: Vec<&str> = text.lines().collect();
    let lines: Vec<serde_json::Value> = raw
        .iter()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 5);
    for ((line, e), text) in lines.iter().zip(list).zip(&raw) {
        let m = &line["markers"].as_array().unwrap();
        assert_eq!(m.len(), 1, "{line}");
        let m = &m[0];
        fields_in_order(
            text,
            m,
            &[
                "index",
                "hamming",
                "corners",
                "contrast",
                "pose",
                "dictionary",
                "id",
            ],
        );
        assert_eq!(m["dictionary"], "DICT_APRILTAG_36h11");
        assert_eq!(m["id"], e["id"]);
        assert_eq!(m["hamming"], 0);
        // Corners in the PNG's convention, top-left as printed first, clockwise.
        for k in 0..4 {
            for j in 0..2 {
                let a = m["corners"][k][j].as_f64().unwrap();
                let b = e["corners_px"][k][j].as_f64().unwrap();
                assert!((a - b).abs() < 0.1, "corner {k}: {a} vs {b}");
            }
        }
    }
    let m = &lines[4]["markers"][0];
    fields_in_order(
        raw[4],
        m,
        &[
            "code",
            "index",
            "robot",
            "face",
            "hamming",
            "corners",
            "contrast",
            "pose",
            "dictionary",
            "id",
        ],
    );
    assert_eq!(m["dictionary"], "FORMATION_4X5");
    assert_eq!(
        (m["robot"].as_u64(), m["face"].as_u64()),
        (Some(1), Some(3))
    );
}

#[test]
fn unknown_dictionaries_and_ids_are_one_line_errors() {
    let out = bin()
        .args(["detect", "x.png", "--dictionary", "tag99h1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("tag99h1") && err.contains("tag36h11"), "{err}");
    let d = dir("bad-ids");
    let out = bin()
        .args(["markers", "--dictionary", "DICT_4X4_50", "--ids", "0-50"])
        .arg("--out")
        .arg(&d)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("50 ids"), "{err}");
}
