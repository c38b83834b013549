//! Every command that writes to standard output copes with a reader that goes away: a closed
//! pipe (`formation-tracker detect *.png | head -n 1`) ends it quietly with exit code 0, and a
//! full disk (`> /dev/full`) is one error line with exit code 1. Neither is a panic
//! (`println!` used to panic with exit code 101).
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

mod common;

use std::path::Path;
use std::process::{Command, Output, Stdio};

/// Every command that prints its results on stdout, with arguments that make it print.
/// (`demo` and `reproduce paper-scenes` print through the same function as `reproduce dukf`
/// and take many seconds, so they are left to the end-to-end tests.)
fn commands(d: &Path) -> Vec<Vec<String>> {
    let out = d.join("dukf").display().to_string();
    [
        vec!["info"],
        vec!["detect", "frames/f0.png", "frames/f1.png", "frames/f2.png"],
        vec!["detect", "--json", "frames/f0.png", "frames/f1.png"],
        vec!["track", "--camera", "camera.yaml", "frames"],
        vec!["track", "--json", "--camera", "camera.yaml", "frames"],
        vec!["reproduce", "dukf", "--seed", "1", "--out", &out],
    ]
    .into_iter()
    .map(|args| args.into_iter().map(String::from).collect())
    .collect()
}

fn run(d: &Path, args: &[String], stdout: Stdio, close_stdout: bool) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(args)
        .current_dir(d)
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    if close_stdout {
        // The reader goes away before the command has written anything.
        drop(child.stdout.take());
    }
    child.wait_with_output().unwrap()
}

#[test]
fn a_closed_pipe_ends_every_command_quietly() {
    let d = common::blank_frames("stdout-pipe");
    for args in commands(&d) {
        let out = run(&d, &args, Stdio::piped(), true);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
        assert_eq!(out.status.code(), Some(0), "{args:?}: {stderr}");
        assert!(
            !stderr.contains("error"),
            "{args:?} reported an error: {stderr}"
        );
    }
}

#[test]
fn a_full_disk_is_one_error_line_and_exit_code_1() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        return; // not Linux: no /dev/full to write to
    };
    let d = common::blank_frames("stdout-full");
    for args in commands(&d) {
        let out = run(&d, &args, Stdio::from(full.try_clone().unwrap()), false);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.contains("error")).collect();
        assert_eq!(
            errors,
            [
                "formation-tracker: error: cannot write to standard output: No space left on device (os error 28)"
            ],
            "{args:?}: {stderr}"
        );
    }
}
