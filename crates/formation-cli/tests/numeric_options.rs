//! Numeric options are checked before any work starts, the same way in every command:
//! `nan`, `inf` and out-of-range values are one usage error (exit code 2) naming the option,
//! and options that may be negative take negative numbers without `=`.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::process::Command;

mod common;
use common::run;

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
        (
            "--mount-offset",
            "-0.05",
            "not a camera offset (0 up to 100 m)",
        ),
        ("--mount-offset", "150", "not a camera offset"),
        // Physics (#32): angles within pi (a hint when it looks like degrees), a camera
        // above the ground and below 100 m, a tilt that looks ahead.
        ("--pan", "30", "did you mean 30 degrees = 0.5236 rad"),
        ("--pan", "1e308", "outside -pi to pi rad"),
        (
            "--mount-height",
            "-1",
            "not a camera height (above 0 and below 100 m)",
        ),
        ("--mount-height", "0", "not a camera height"),
        ("--mount-height", "1e9", "not a camera height"),
        ("--mount-tilt", "1e20", "outside -pi/2 to pi/2"),
        ("--mount-tilt", "1.5707963267948966", "straight up or down"),
        ("--pan", "-nan", "finite"),
        ("--lost-after", "0", "above zero"),
        ("--odometry-noise", "-0.01,0.01", "not an odometry noise"),
        ("--odometry-noise", "0.01,nan", "finite"),
        ("--odometry-noise", "0.01", "not two numbers"),
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
            "--mount-offset",
            "-0",
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

#[test]
fn y4m_frame_rates_outside_the_valid_range_are_errors() {
    use std::io::Write as _;
    let d = common::blank_frames("numeric-y4m");
    for rate in ["F1000000000:1", "F1:1000000000"] {
        let mut y4m = format!("YUV4MPEG2 W64 H48 {rate} Ip A1:1 Cmono\nFRAME\n").into_bytes();
        y4m.extend(std::iter::repeat_n(128u8, 64 * 48));
        let mut child = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
            .args(["track", "--camera", "camera.yaml", "-"])
            .current_dir(&d)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // The command may stop reading once it has seen the header.
        let _ = child.stdin.take().unwrap().write_all(&y4m);
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{rate}: {stderr}");
        assert!(
            stderr.contains("frame rate") && stderr.contains("valid range"),
            "{rate}: {stderr}"
        );
        assert!(out.stdout.is_empty(), "{rate}: frames were tracked");
    }
}
