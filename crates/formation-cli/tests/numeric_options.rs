//! Numeric options are checked before any work starts, the same way in every command:
//! `nan`, `inf` and out-of-range values are one usage error (exit code 2) naming the option,
//! and options that may be negative take negative numbers without `=`.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::Path;
use std::process::{Command, Output};

mod common;

fn run(d: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(args)
        .current_dir(d)
        .output()
        .unwrap()
}

#[test]
fn non_finite_and_out_of_range_values_are_usage_errors() {
    let d = common::blank_frames("numeric-bad");
    let track = ["track", "--camera", "camera.yaml", "frames"];
    for (option, value, says) in [
        ("--pan", "nan", "finite"),
        ("--pan", "inf", "finite"),
        ("--mount-height", "nan", "finite"),
        ("--mount-tilt", "nan", "finite"),
        ("--mount-offset", "-inf", "finite"),
        ("--mount-offset", "-0.05", "zero or more"),
        ("--pan", "-nan", "finite"),
        ("--lost-after", "0", "above zero"),
        ("--fps", "1e300", "valid range"),
        ("--fps", "1e-9", "valid range"),
        ("--fps", "abc", "not a number"),
    ] {
        let out = run(&d, &[&track[..], &[option, value]].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            out.status.code(),
            Some(2),
            "track {option} {value}: {stderr}"
        );
        assert!(stderr.contains(option) && stderr.contains(says), "{stderr}");
        assert!(
            out.stdout.is_empty(),
            "track {option} {value} processed frames"
        );
    }
    let out = run(&d, &["detect", "--pan", "nan", "frames/f0.png"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--pan") && stderr.contains("finite"),
        "{stderr}"
    );
}

#[test]
fn negative_values_need_no_equals_sign() {
    let d = common::blank_frames("numeric-negative");
    let out = run(
        &d,
        &[
            "track",
            "--camera",
            "camera.yaml",
            "--mount-tilt",
            "-0.1",
            "--pan",
            "-0.2",
            "--mount-height",
            "-0.05",
            "frames",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 3);
    let out = run(
        &d,
        &[
            "detect",
            "--pan",
            "-0.3",
            "--camera",
            "camera.yaml",
            "frames/f0.png",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
