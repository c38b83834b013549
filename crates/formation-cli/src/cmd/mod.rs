//! One module per subcommand. Each exposes an `Args` struct (clap) and a `run` function.

/// Any error a subcommand reports; printed as one line by `main`.
pub type CliError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// The rig of `--rig FILE`, or the reference rig of spec 3.3 without one: every command that
/// takes `--rig` reads it here, so they all agree.
pub fn load_rig(
    path: Option<&std::path::Path>,
    dictionary: &fiducial::Dictionary,
) -> Result<formation_tracker::rig::RigModel, CliError> {
    Ok(match path {
        Some(path) => formation_tracker::rig::RigModel::load(path, dictionary)?,
        None => formation_tracker::rig::RigModel::reference(),
    })
}

pub mod demo;
pub mod detect;
pub mod detect_robots;
pub mod info;
pub mod markers;
pub mod render;
pub mod reproduce;
pub mod reproduce_scenes;
pub mod track;
