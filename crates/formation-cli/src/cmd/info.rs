//! `formation-tracker info`: what this binary was built from.

use super::CliError;

/// Prints the package version; the library crates share the workspace version.
pub fn run() -> Result<(), CliError> {
    super::outln!(
        "formation-tracker {} (crates: fiducial, pose, unicycle, dukf, synthcam)",
        env!("CARGO_PKG_VERSION")
    )?;
    Ok(())
}
