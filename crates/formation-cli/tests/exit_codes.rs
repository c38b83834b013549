//! The exit-code policy of `docs/reliability.md`: 0 everything done, 1 nothing usable,
//! 2 bad usage, 3 partial (some inputs could not be used).
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::Path;
use std::process::Command;

mod common;

fn code(d: &Path, args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(args)
        .current_dir(d)
        .output()
        .unwrap();
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
