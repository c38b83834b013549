//! `formation-tracker demo`: the project's showcase.
//!
//! Until the end-to-end vision demo exists, this runs the dual-UKF reproduction (seed 1, no
//! bias) into the output directory and prints its summary.

use std::path::PathBuf;

use clap::Args as ClapArgs;

use super::CliError;
use super::reproduce::{run_dukf, summary_table};

/// Run the project's demonstration.
///
/// For now this is the dual-UKF reproduction of the paper's Figs. 12-13 (`reproduce dukf`
/// with seed 1 and no bias): it writes series.csv, fig12.svg/png, fig13.svg/png and
/// summary.json into DIR and prints the summary. The end-to-end vision demo (synthetic
/// camera, markers, pose, filter) will replace it.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Directory to write the demo's outputs into (created if missing).
    #[arg(long, value_name = "DIR", default_value = "out/demo")]
    out: PathBuf,
}

/// Runs `demo`.
pub fn run(args: Args) -> Result<(), CliError> {
    let summary = run_dukf(&args.out, 1, false)?;
    print!("{}", summary_table(&summary));
    Ok(())
}
