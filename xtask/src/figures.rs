//! `cargo xtask figures`: regenerates the README's figures in `docs/img/` from the demo, so that
//! they always show what `formation-tracker demo` produces today.
//!
//! Runs the demo (release build, default settings, progress off) into `target/xtask-figures`
//! and copies `fig12.png` to `docs/img/fig12.png` and `strip.png` to `docs/img/demo-strip.png`.

use std::path::PathBuf;
use std::process::Command;

use crate::Result;

/// (demo output, file in `docs/img/`).
const FIGURES: &[(&str, &str)] = &[("fig12.png", "fig12.png"), ("strip.png", "demo-strip.png")];

pub fn run(args: &[String]) -> Result {
    if !args.is_empty() {
        return Err(format!("figures takes no arguments (got {})", args.join(" ")).into());
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = root.join("target").join("xtask-figures");
    let status = Command::new(env!("CARGO"))
        .current_dir(&root)
        .args([
            "run",
            "--release",
            "-p",
            "formation-tracker-cli",
            "--",
            "--quiet",
            "demo",
            "--out",
        ])
        .arg(&out)
        .status()?;
    if !status.success() {
        return Err(format!("the demo failed with {status}").into());
    }
    for (from, to) in FIGURES {
        let target = root.join("docs").join("img").join(to);
        std::fs::copy(out.join(from), &target)
            .map_err(|e| format!("cannot copy {from} to {}: {e}", target.display()))?;
        eprintln!("figures: wrote {}", target.display());
    }
    Ok(())
}
