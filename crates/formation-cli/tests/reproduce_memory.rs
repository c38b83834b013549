//! `reproduce dukf` keeps its memory flat in the scenario's duration unless `--smooth` is
//! asked for (issue #32): the samples are simulated, filtered and written one at a time, the
//! figures keep at most a bounded number of steps, and the smoother's history is kept only
//! with `--smooth`. Scenarios of 400 s and more used to fail in a smoother nobody asked for.
//!
//! The peak resident memory of the child is read from `/proc/PID/status` (`VmHWM`, a high-water
//! mark) while it runs, so the figure is a lower bound of the true peak by at most the growth
//! of its last few milliseconds.

#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The reference scenario file with another duration.
fn scenario(dir: &Path, seconds: u32) -> PathBuf {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenarios/reference.yaml"
    ))
    .unwrap()
    .replace("duration: 8.0", &format!("duration: {seconds}.0"));
    assert!(text.contains(&format!("duration: {seconds}.0")));
    let path = dir.join(format!("reference-{seconds}s.yaml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs `reproduce dukf` on `scenario` (plus `extra` options) and returns its peak resident
/// memory in kB and its stdout; panics if it fails or takes more than two minutes.
fn peak_kb(scenario: &Path, out: &Path, extra: &[&str]) -> (u64, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(["--quiet", "reproduce", "dukf", "--scenario"])
        .arg(scenario)
        .arg("--out")
        .arg(out)
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let status_file = format!("/proc/{}/status", child.id());
    let start = Instant::now();
    let mut peak = 0;
    let status = loop {
        if let Ok(text) = std::fs::read_to_string(&status_file)
            && let Some(kb) = text
                .lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        {
            peak = peak.max(kb);
        }
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "still running");
        std::thread::sleep(Duration::from_millis(5));
    };
    let output = child.wait_with_output().unwrap();
    assert!(
        status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    (peak, String::from_utf8(output.stdout).unwrap())
}

#[test]
fn reproduce_dukf_memory_does_not_grow_with_the_duration() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("repro-mem-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (short, _) = peak_kb(&scenario(&dir, 200), &dir.join("short"), &[]);
    let (long, table) = peak_kb(&scenario(&dir, 2000), &dir.join("long"), &[]);
    // 60,000 steps: the smoother's history alone would be about 85 MB, the records 10 MB.
    assert!(table.contains("(60000 steps"), "{table}");
    let rows = std::fs::read_to_string(dir.join("long/series.csv"))
        .unwrap()
        .lines()
        .count();
    assert_eq!(rows, 60_001, "series.csv keeps every step");
    assert!(short > 0 && long > 0, "no VmHWM read");
    assert!(
        long < short + 8 * 1024,
        "peak memory grew from {short} kB (200 s) to {long} kB (2000 s)"
    );
    assert!(!dir.join("long/series-smoothed.csv").exists());
    // --smooth keeps every step: what would not fit in --max-memory is refused up front.
    let out = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args([
            "--max-memory",
            "64MiB",
            "reproduce",
            "dukf",
            "--smooth",
            "--scenario",
        ])
        .arg(scenario(&dir, 2000))
        .arg("--out")
        .arg(dir.join("smooth"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("--smooth keeps every step: 60000 steps need about 171.7 MiB, more than --max-memory 64 MiB"),
        "{stderr}"
    );
    assert!(!dir.join("smooth/series.csv").exists());
}
