//! A closed or full stderr never panics (issue #32: any run whose stderr was closed or full
//! ended with a panic and exit code 101, even when it succeeded). Every line the commands
//! print on stderr goes through `errln!`, which ignores a failed write.

#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

mod common;

use std::process::{Command, Stdio};

/// Runs the binary with `args` in `dir`, stderr closed (`2>&-`) or on `/dev/full`.
fn run(dir: &std::path::Path, args: &[&str], closed: bool) -> Option<i32> {
    let exe = env!("CARGO_BIN_EXE_formation-tracker");
    let mut cmd = if closed {
        let mut c = Command::new("sh");
        c.arg("-c")
            .arg("exec \"$0\" \"$@\" 2>&-")
            .arg(exe)
            .args(args);
        c
    } else {
        let mut c = Command::new(exe);
        c.args(args).stderr(
            std::fs::OpenOptions::new()
                .write(true)
                .open("/dev/full")
                .unwrap(),
        );
        c
    };
    cmd.current_dir(dir)
        .stdout(Stdio::null())
        .status()
        .unwrap()
        .code()
}

#[test]
fn closed_or_full_stderr_never_panics() {
    let d = common::blank_frames("stderr");
    std::fs::write(d.join("broken.png"), b"not a png").unwrap();
    let cases: &[(&[&str], i32)] = &[
        (&["info"], 0),
        // Notes, progress and the summary line on stderr, results on stdout.
        (&["track", "frames", "--camera", "camera.yaml"], 0),
        (&["detect", "broken.png"], 1),
        (&["detect", "frames/f0.png", "broken.png"], 3),
        (&["track", "frames"], 2),
        (&["reproduce", "dukf", "--out", "dukf"], 0),
        (&["render", "--paper-fig", "7", "--out", "fig7.png"], 0),
        (&["render", "--paper-fig", "12", "--out", "fig7.png"], 2),
    ];
    for closed in [true, false] {
        for (args, code) in cases {
            assert_eq!(
                run(&d, args, closed),
                Some(*code),
                "{args:?} with stderr {}",
                if closed { "closed" } else { "full" }
            );
        }
    }
}
