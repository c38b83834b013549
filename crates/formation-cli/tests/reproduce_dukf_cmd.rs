//! `formation-tracker reproduce dukf`: every output is written, and a bad output folder is
//! one error line with a non-zero exit.

#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

#[test]
fn cli_reproduce_dukf_writes_every_output_and_fails_in_one_line() {
    let exe = env!("CARGO_BIN_EXE_formation-tracker");
    let dir = std::env::temp_dir().join(format!("ft-reproduce-{}", std::process::id()));
    let out = std::process::Command::new(exe)
        .args(["reproduce", "dukf", "--seed", "3", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains("alpha12") && table.contains("seed 3"),
        "{table}"
    );
    for f in [
        "series.csv",
        "fig12.svg",
        "fig12.png",
        "fig13.svg",
        "fig13.png",
        "summary.json",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    for key in [
        "mse_l12",
        "mse_alpha12",
        "mse_beta12",
        "mse_v1",
        "mse_w1",
        "mse_meas_l12",
        "mse_meas_alpha12",
        "rms_v1_after_2s",
        "rms_w1_after_2s",
        "steps",
        "seed",
        "bias",
    ] {
        assert!(json.get(key).is_some(), "summary.json lacks {key}");
    }
    assert_eq!(json["seed"], 3);
    assert_eq!(json["steps"], 240);
    let csv = std::fs::read_to_string(dir.join("series.csv")).unwrap();
    assert_eq!(csv.lines().count(), 241);
    assert!(csv.starts_with("t,l12_true,l12_measured,l12_estimated"));

    // An output "directory" below a regular file cannot be created: one line, non-zero exit.
    let bad = std::process::Command::new(exe)
        .args(["reproduce", "dukf", "--out"])
        .arg(dir.join("summary.json").join("sub"))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8(bad.stderr).unwrap();
    let errors: Vec<&str> = err.lines().filter(|l| l.contains("error")).collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert!(errors[0].starts_with("formation-tracker: error:"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn cli_reproduce_dukf_reads_a_scenario_file_and_names_a_bad_field() {
    let exe = env!("CARGO_BIN_EXE_formation-tracker");
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = std::env::temp_dir().join(format!("ft-reproduce-file-{}", std::process::id()));
    let out = std::process::Command::new(exe)
        .args(["reproduce", "dukf", "--seed", "2", "--scenario"])
        .arg(root.join("fixtures/scenarios/l12-step.yaml"))
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // 10 s at 30 Hz.
    let csv = std::fs::read_to_string(dir.join("series.csv")).unwrap();
    assert_eq!(csv.lines().count(), 301);

    let bad = dir.join("bad.yaml");
    std::fs::write(
        &bad,
        std::fs::read_to_string(root.join("fixtures/scenarios/reference.yaml"))
            .unwrap()
            .replace("frame_rate", "framerate"),
    )
    .unwrap();
    let out = std::process::Command::new(exe)
        .args(["reproduce", "dukf", "--scenario"])
        .arg(&bad)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("framerate"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// #30: the follower steers on the filter's estimate unless `--paper` (or `--control`) says
/// otherwise; `summary.json` says which, and a bad or conflicting choice is a usage error.
#[test]
fn cli_reproduce_dukf_control_modes() {
    let exe = env!("CARGO_BIN_EXE_formation-tracker");
    let dir = std::env::temp_dir().join(format!("ft-reproduce-control-{}", std::process::id()));
    let run = |args: &[&str], out: &str| {
        std::process::Command::new(exe)
            .args(["--quiet", "reproduce", "dukf"])
            .args(args)
            .arg("--out")
            .arg(dir.join(out))
            .output()
            .unwrap()
    };
    let control = |out: &str| {
        let text = std::fs::read_to_string(dir.join(out).join("summary.json")).unwrap();
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        json["control"].as_str().unwrap().to_string()
    };
    for (args, out, want) in [
        (&[][..], "default", "estimate"),
        (&["--paper"][..], "paper", "truth"),
        (&["--control", "open"][..], "open", "open"),
    ] {
        let o = run(args, out);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(control(out), want);
    }
    // The paper's setting gives other figures than the follower on its estimate.
    let series = |out: &str| std::fs::read_to_string(dir.join(out).join("series.csv")).unwrap();
    assert_ne!(series("default"), series("paper"));
    for bad in [
        &["--control", "oracle"][..],
        &["--paper", "--control", "truth"][..],
    ] {
        let o = run(bad, "bad");
        assert_eq!(o.status.code(), Some(2), "{bad:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("control"), "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
