//! `formation-tracker track`: camera frames in, formation variables and leader velocities
//! out, one line per frame.

mod args;
mod bag;
mod folder;
pub(crate) mod session;

pub use args::{Args, RunArgs};

use super::CliError;

/// Runs `track`: a bag, or a folder or y4m stream of frames.
pub fn run(args: &Args) -> Result<(), CliError> {
    refuse_overwriting_inputs(args)?;
    super::interrupt::install()?;
    if formation_io::bag::is_bag(&args.input) {
        bag::run(args)
    } else {
        folder::run(args)
    }
}

/// Refuses, before any work, an `--mcap` output that is one of the inputs (exit code 2).
fn refuse_overwriting_inputs(args: &Args) -> Result<(), CliError> {
    let Some(mcap) = &args.run.mcap else {
        return Ok(());
    };
    let mut inputs: Vec<(&str, &std::path::Path)> = vec![("INPUT", &args.input)];
    for (name, path) in [
        ("--camera", &args.camera),
        ("--rig", &args.run.rig),
        ("--inputs", &args.inputs),
        ("--controller", &args.run.controller),
    ] {
        if let Some(path) = path {
            inputs.push((name, path));
        }
    }
    super::output::refuse_inputs_as_outputs(&[("--mcap", mcap)], &inputs)
}
