//! Commands that render or time thousands of frames are worth a release build: from the dev
//! profile they run themselves again through `cargo run --release`.

/// Runs `cargo xtask COMMAND ARGS` again in the release profile, with `marker` set in its
/// environment (so that the rerun does not rerun itself).
pub fn rerun_in_release(command: &str, args: &[String], marker: &str) -> crate::Result {
    let status = std::process::Command::new(env!("CARGO"))
        .args([
            "run",
            "--release",
            "-q",
            "-p",
            "xtask",
            "--bin",
            "xtask",
            "--",
        ])
        .arg(command)
        .args(args)
        .env(marker, "1")
        .status()?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{command} (release) failed").into())
    }
}
