//! `demo --scenario` says up front how long its rendering will take when that is above a
//! minute (issue #32): a 4096x4096 camera with supersampling 8 and motion blur, within the
//! validated limits, projected to hours and printed nothing for 48 s.

#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

mod common;

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
fn demo_estimates_a_long_rendering_before_it_starts() {
    let dir =
        PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("demo-est-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let far = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenarios/far.yaml"
    ))
    .unwrap();
    let huge = far
        .replace(
            "camera: {width: 640, height: 480, hfov_deg: 60}",
            "camera: {width: 4096, height: 4096, hfov_deg: 60}",
        )
        .replace("supersampling: 3", "supersampling: 8")
        .replace("subframes: 3", "subframes: 5");
    assert!(huge.contains("width: 4096") && huge.contains("supersampling: 8"));
    let scenario = dir.join("huge.yaml");
    std::fs::write(&scenario, huge).unwrap();
    let out = dir.join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_formation-tracker"))
        .args(["demo", "--scenario"])
        .arg(&scenario)
        .arg("--out")
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let rx = common::lines_of(stderr);
    // The estimate comes from a probe of about 2e6 rays: well within 30 s even in a debug
    // build on a loaded machine (the first frame itself takes about a minute).
    let mut seen = Vec::new();
    let estimate = loop {
        match rx.recv_timeout(Duration::from_secs(30)) {
            Ok(line) if line.contains("estimated") => break line,
            Ok(line) => seen.push(line),
            Err(e) => {
                let _ = child.kill();
                panic!("no estimate ({e}); stderr so far: {seen:?}");
            }
        }
    };
    let _ = child.kill();
    let _ = child.wait();
    assert!(
        estimate.contains("demo: rendering will take about"),
        "{estimate}"
    );
    assert!(
        estimate.contains("min") || estimate.contains(" h"),
        "above a minute, in minutes or hours: {estimate}"
    );
    assert!(estimate.contains("4096x4096"), "{estimate}");
}
