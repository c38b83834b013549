//! The exit-code policy of `docs/reliability.md`: 0 everything done, 1 nothing usable,
//! 2 bad usage, 3 partial (some inputs could not be used).
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::Path;
use std::process::Command;

mod common;

fn code(d: &Path, args: &[&str]) -> (Option<i32>, String) {
    let out = common::run(d, args);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn every_outcome_has_its_exit_code() {
    let d = common::blank_frames("exit-codes");
    std::fs::write(d.join("broken.png"), b"not a PNG").unwrap();
    std::fs::create_dir_all(d.join("all-broken")).unwrap();
    std::fs::write(d.join("all-broken").join("f0.png"), b"not a PNG").unwrap();
    std::fs::write(d.join("all-broken").join("f1.png"), b"nor this").unwrap();
    let cases: [(&[&str], i32, &str); 8] = [
        (&["detect", "frames/f0.png", "frames/f1.png"], 0, ""),
        (
            &["detect", "frames/f0.png", "broken.png"],
            3,
            "warning: 1 of 2 image(s)",
        ),
        (
            &["detect", "broken.png"],
            1,
            "error: none of the 1 image(s)",
        ),
        (&["track", "--camera", "camera.yaml", "frames"], 0, ""),
        (
            &["track", "--camera", "camera.yaml", "all-broken"],
            1,
            "error: nothing tracked: 0 frames tracked, 2 broken",
        ),
        (
            &["track", "--camera", "camera.yaml", "--pan", "x", "frames"],
            2,
            "--pan",
        ),
        (
            &["detect", "--no-such-option", "frames/f0.png"],
            2,
            "--no-such-option",
        ),
        (&["info"], 0, ""),
    ];
    for (args, want, says) in cases {
        let (got, stderr) = code(&d, args);
        assert_eq!(got, Some(want), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    }
}

/// Commands that write files check their output directory before the long work: `demo
/// --out /proc/x` used to render for 11 s and then fail.
#[test]
fn an_unwritable_output_directory_fails_before_any_work() {
    let d = common::blank_frames("exit-codes-out");
    let blocker = d.join("a-file");
    std::fs::write(&blocker, b"").unwrap();
    let inside = blocker.join("out");
    let inside = inside.to_str().unwrap();
    let png = blocker.join("x.png");
    let png = png.to_str().unwrap();
    for args in [
        vec!["demo", "--out", inside],
        vec!["reproduce", "dukf", "--out", inside],
        vec!["reproduce", "paper-scenes", "--out", inside],
        vec!["markers", "--out", inside],
        vec!["render", "--paper-fig", "7", "--out", png],
    ] {
        let (got, stderr) = code(&d, &args);
        assert_eq!(got, Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains("cannot write to output directory"),
            "{args:?}: {stderr}"
        );
        assert!(
            !stderr.contains("rendering and tracking"),
            "{args:?} started: {stderr}"
        );
    }
    let (got, stderr) = code(&d, &["demo", "--robots", "9"]);
    assert_eq!(got, Some(2), "{stderr}");
    assert!(stderr.contains("from 2 to 6"), "{stderr}");
}

/// `info` prints what its help says: every package the binary was built from, with its
/// version, one per line.
#[test]
fn info_lists_every_package_with_its_version() {
    let out = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .arg("info")
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let names: Vec<&str> = text.lines().map(|l| l.split(' ').next().unwrap()).collect();
    assert_eq!(
        names,
        [
            "formation-tracker-cli",
            "formation-tracker",
            "formation-filter",
            "formation-io",
            "formation-sim",
            "formation-fiducial",
            "formation-pose",
            "formation-unicycle",
            "formation-dukf",
            "formation-synthcam"
        ]
    );
    for line in text.lines() {
        let version = line.split(' ').nth(1).unwrap();
        assert_eq!(version.split('.').count(), 3, "{line}");
        assert!(
            version.split('.').all(|p| p.parse::<u32>().is_ok()),
            "{line}"
        );
    }
    let help = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .arg("--help")
        .output()
        .unwrap();
    assert!(
        String::from_utf8(help.stdout)
            .unwrap()
            .contains("name and version of every package")
    );
}

/// Long work is visible in a log: without a terminal, `track` prints status lines (here
/// every frame, `FORMATION_TRACKER_STATUS_SECS=0`); `--quiet` prints none.
#[test]
fn progress_is_logged_without_a_terminal_and_quiet_silences_it() {
    let d = common::blank_frames("progress");
    let run = |quiet: bool| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_formation-tracker"));
        if quiet {
            cmd.arg("--quiet");
        }
        let out = cmd
            .args(["track", "--camera", "camera.yaml", "frames"])
            .env("FORMATION_TRACKER_STATUS_SECS", "0")
            .current_dir(&d)
            .output()
            .unwrap();
        assert!(out.status.success());
        String::from_utf8(out.stderr).unwrap()
    };
    let logged = run(false);
    for k in 1..=3 {
        assert!(
            logged.contains(&format!("track: {k}/3 frames after ")),
            "{logged}"
        );
    }
    let quiet = run(true);
    assert!(!quiet.contains("frames after"), "{quiet}");
    assert!(
        quiet.contains("3 frames tracked"),
        "results still print: {quiet}"
    );
}

/// `demo --scenario` with a bad `vision` field: one line naming the field, a non-zero exit,
/// before any rendering; `--robots` other than 2 with a scenario file is refused too.
#[test]
fn demo_scenario_errors_name_the_field() {
    let d = common::blank_frames("demo-scenario");
    let file = d.join("bad.yaml");
    let text = include_str!("../../../fixtures/scenarios/far.yaml").replace("pan: 0.0", "pan: 30");
    std::fs::write(&file, text).unwrap();
    let out = d.join("out");
    let args = [
        "demo",
        "--scenario",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    let (got, stderr) = code(&d, &args);
    assert!(got.is_some_and(|c| c != 0), "{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.contains("error")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    assert!(errors[0].contains("vision.mount.pan"), "{stderr}");
    assert!(!stderr.contains("rendering and tracking"), "{stderr}");
    let far = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenarios/far.yaml"
    );
    let (got, stderr) = code(&d, &["demo", "--scenario", far, "--robots", "3"]);
    assert!(got.is_some_and(|c| c != 0), "{stderr}");
    assert!(stderr.contains("two robots"), "{stderr}");
}
