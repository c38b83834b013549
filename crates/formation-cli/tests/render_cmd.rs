//! `formation-tracker render`: a paper figure with its truth, and a bad figure number as
//! one error line.

#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

use std::path::PathBuf;
use std::process::Command;

use formation_sim::scene::SceneTruth;

#[test]
fn render_command_writes_png_and_truth() {
    let dir =
        PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("fig10.png");
    let json = dir.join("fig10.json");
    let status = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(["render", "--paper-fig", "10", "--out"])
        .arg(&png)
        .arg("--truth")
        .arg(&json)
        .status()
        .unwrap();
    assert!(status.success());
    let img = image::open(&png).unwrap().into_luma8();
    assert_eq!(img.dimensions(), (640, 480));
    let text = std::fs::read_to_string(&json).unwrap();
    // Angles in machine-readable outputs are radians (docs/outputs.md): no field in degrees
    // (`off_axis_deg` was one).
    assert!(!text.contains("_deg\""), "{text}");
    assert!(text.contains("\"off_axis\""));
    let truth: SceneTruth = serde_json::from_str(&text).unwrap();
    assert_eq!(truth.robots.len(), 2);
    assert!((truth.robots[1].translation[2] - 3.0).abs() < 0.01);
    let out = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(["render", "--paper-fig", "12", "--out"])
        .arg(dir.join("x.png"))
        .output()
        .unwrap();
    // A usage error (#32): exit code 2, its one error line naming the value and the range.
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.lines().filter(|l| l.contains("error")).count(),
        1,
        "{err}"
    );
    assert!(err.contains("`12`") && err.contains("7 to 11"), "{err}");
}

/// A render is long work for a large scene, so it is visible in a log: without a terminal it
/// prints status lines counting the rows traced (here at every row,
/// `FORMATION_TRACKER_STATUS_SECS=0`), the last one at the full height; `--quiet` prints none.
#[test]
fn render_progress_is_logged_and_quiet_silences_it() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("render-progress-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |quiet: bool| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_formation-tracker"));
        if quiet {
            cmd.arg("--quiet");
        }
        let out = cmd
            .args(["render", "--paper-fig", "7", "--out"])
            .arg(dir.join(format!("fig7-{quiet}.png")))
            .env("FORMATION_TRACKER_STATUS_SECS", "0")
            .output()
            .unwrap();
        assert!(out.status.success());
        String::from_utf8(out.stderr).unwrap()
    };
    let logged = run(false);
    let rows: Vec<&str> = logged
        .lines()
        .filter(|l| l.starts_with("render: "))
        .collect();
    assert!(rows.len() > 100, "{logged}");
    assert!(
        logged.contains("render: 480/480 rows after "),
        "the last row is reported: {logged}"
    );
    let quiet = run(true);
    assert!(!quiet.contains("rows after"), "{quiet}");
    assert!(
        quiet.contains("render: wrote"),
        "the result still prints: {quiet}"
    );
}
