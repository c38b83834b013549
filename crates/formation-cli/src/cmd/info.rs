//! `formation-tracker info`: what this binary was built from.

use super::CliError;

/// The packages this binary links, with the version each was built at.
pub fn packages() -> [(&'static str, &'static str); 10] {
    [
        ("formation-tracker-cli", env!("CARGO_PKG_VERSION")),
        ("formation-tracker", formation_tracker::VERSION),
        ("formation-filter", formation_filter::VERSION),
        ("formation-io", formation_io::VERSION),
        ("formation-sim", formation_sim::VERSION),
        ("formation-fiducial", fiducial::VERSION),
        ("formation-pose", pose::VERSION),
        ("formation-unicycle", unicycle::VERSION),
        ("formation-dukf", dukf::VERSION),
        ("formation-synthcam", synthcam::VERSION),
    ]
}

/// Prints one line per package: its name and version.
pub fn run() -> Result<(), CliError> {
    for (name, version) in packages() {
        super::outln!("{name} {version}")?;
    }
    Ok(())
}
