//! `cargo xtask fingerprint [--check]`: the detector's output fingerprints,
//! `fixtures/fingerprints/fiducial.txt`. The frames, the entry points and the hash are those
//! of `crates/fiducial/tests/fingerprint.rs`, which this command runs with
//! `FIDUCIAL_FINGERPRINT_WRITE` set so that the test writes the file instead of checking it
//! (one piece of code computes them). `--check` runs the test as `cargo test` does.

/// Regenerates (or with `--check` checks) the fingerprint file.
pub fn run(args: &[String]) -> crate::Result {
    let check = match args {
        [] => false,
        [a] if a == "--check" => true,
        _ => return Err("usage: cargo xtask fingerprint [--check]".into()),
    };
    let mut cmd = std::process::Command::new(env!("CARGO"));
    cmd.args([
        "test",
        "-q",
        "-p",
        "formation-fiducial",
        "--test",
        "fingerprint",
    ]);
    if !check {
        cmd.env("FIDUCIAL_FINGERPRINT_WRITE", "1");
    }
    let status = cmd.status()?;
    if !status.success() {
        return Err(if check {
            "fingerprint: the detector's output differs from fixtures/fingerprints/fiducial.txt"
                .into()
        } else {
            "fingerprint: the fingerprint test failed".into()
        });
    }
    if !check {
        eprintln!("fingerprint: wrote fixtures/fingerprints/fiducial.txt");
    }
    Ok(())
}
