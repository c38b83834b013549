//! `formation-tracker reproduce ...`: regenerate the paper's results.
//!
//! `reproduce dukf` runs the dual-UKF experiment of the paper's Figs. 12-13 on the reference
//! scenario (`docs/reference-scenario.md`) and writes its series, figures and summary.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use clap::{Args as ClapArgs, Subcommand};
use formation_sim::plot::{fig12_panels, fig13_panels, write_png, write_svg};
use formation_sim::reproduce::{Reproduction, StepRecord, Summary, reproduce_with, run_filter};
use formation_sim::scenario_file::ScenarioSpec;
use formation_tracker::filter::FilterDesign;

use super::CliError;

/// Size of every figure, pixels.
const FIGURE_SIZE: (u32, u32) = (800, 600);

/// Regenerate one of the paper's results from the project's reference scenarios.
#[derive(Debug, ClapArgs)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Debug, Subcommand)]
enum What {
    /// The dual unscented Kalman filter experiment of the paper's Figs. 12-13.
    ///
    /// Simulates the reference scenario (leader weaving at v1 = 0.8 + 0.2 sin(0.5 t) m/s,
    /// w1 = 0.2 sin(0.4 t) rad/s; follower holding formation, camera offset d = 0.5 m;
    /// 8 s at 30 Hz), measures (l12, alpha12, beta12) with Gaussian noise of standard
    /// deviations (0.07 m, 0.03 rad, 0.03 rad), and filters from the paper's x0 = [1.5,
    /// 0.25, 0, 1.047, 0.233, 0.232], w0 = [0, 0], Pw0 = I with the formation filter: the
    /// IMM of a constant-acceleration leader and a formation moving as the follower's own
    /// controller commands (default; the filter is told the controller's gains and
    /// set-points) or, with --dual, the paper's dual UKF.
    ///
    /// Writes into DIR: series.csv (one row per step: true / measured / estimated
    /// l12, alpha12, beta12 and true / estimated v1, w1), fig12.svg + fig12.png (l12 and
    /// alpha12 with their errors), fig13.svg + fig13.png (v1 and w1 with their errors) and
    /// summary.json (mean square errors, RMS velocity errors after 2 s, seed, bias), and
    /// prints the summary as a table.
    Dukf(DukfArgs),
    /// The paper's scenes, Figs. 7-11: render (640 x 480, 60 deg HFOV, camera level at
    /// marker height, noise sigma 3, blur sigma 1), detect, measure each robot's pose and
    /// score it against the ground truth.
    ///
    /// Writes into DIR: figN.png (annotated: markers read with robot/face, each robot's
    /// estimated rig reprojected), figN-raw.png, scenes.md and scenes.json.
    PaperScenes(super::reproduce_scenes::Args),
}

/// Options of `reproduce dukf`.
#[derive(Debug, ClapArgs)]
pub struct DukfArgs {
    /// Directory to write the series, figures and summary into (created if missing).
    #[arg(long, value_name = "DIR", default_value = "out/reproduce/dukf")]
    out: PathBuf,
    /// Seed of the measurement noise (ChaCha8); the same seed gives the same files.
    #[arg(long, value_name = "N", default_value_t = 1)]
    seed: u64,
    /// Add the paper's constant measurement bias [-0.0702, 0.0248, 0.0236] to every
    /// measurement (the filter is not told about it); a scenario file's own bias wins.
    #[arg(long)]
    bias: bool,
    /// Simulate this scenario file (YAML, or JSON if named .json) instead of the built-in
    /// reference scenario: leader inputs as sums of constants, sines and steps, the
    /// follower's set-point changes, noise, duration, initial state (see
    /// fixtures/scenarios/reference.yaml, which is the built-in scenario).
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Also run the offline fixed-interval smoother (a joint unscented pass over the
    /// state and the leader velocities, then the unscented RTS smoother; docs/smoothing.md)
    /// and write series-smoothed.csv and summary-smoothed.json beside the causal ones.
    #[arg(long)]
    smooth: bool,
    /// Filter with the paper's dual UKF instead of the default IMM formation filter (for
    /// comparison; docs/dukf-reproduction.md).
    #[arg(long)]
    dual: bool,
}

/// Runs `reproduce`.
pub fn run(args: Args) -> Result<(), CliError> {
    match args.what {
        What::Dukf(a) => {
            let design = if a.dual {
                FilterDesign::Dual
            } else {
                FilterDesign::Imm
            };
            let run = match &a.scenario {
                None => run_dukf(&a.out, a.seed, a.bias, design)?,
                Some(file) => run_dukf_scenario(&a.out, a.seed, a.bias, file, design)?,
            };
            let label = match design {
                FilterDesign::Imm => "IMM formation filter,",
                FilterDesign::Dual => "dual UKF,",
            };
            let mut text = summary_table(&run.summary).replacen("dual UKF,", label, 1);
            if a.smooth {
                write_smoothed(&a.out, &run)?;
                text.push('\n');
                text.push_str(&summary_table(&run.smoothed_summary).replacen(
                    "dual UKF,",
                    "smoothed (offline, joint unscented RTS),",
                    1,
                ));
            }
            super::write_stdout(format_args!("{text}"))?;
            Ok(())
        }
        What::PaperScenes(a) => super::reproduce_scenes::run(&a),
    }
}

/// Runs the reproduction with `design` and writes every output into `out`; progress goes
/// to stderr.
fn run_dukf(
    out: &Path,
    seed: u64,
    bias: bool,
    design: FilterDesign,
) -> Result<Reproduction, CliError> {
    eprintln!(
        "reproduce dukf: seed {seed}{}, writing to {}",
        if bias { ", with the paper's bias" } else { "" },
        out.display()
    );
    super::prepare_out_dir(out)?;
    let run = reproduce_with(seed, bias, design)?;
    write_outputs(out, &run)?;
    Ok(run)
}

/// As [`run_dukf`] on a scenario file.
fn run_dukf_scenario(
    out: &Path,
    seed: u64,
    bias: bool,
    file: &Path,
    design: FilterDesign,
) -> Result<Reproduction, CliError> {
    let spec = ScenarioSpec::load(file).map_err(|e| e.to_string())?;
    eprintln!(
        "reproduce dukf: scenario {}, seed {seed}{}, writing to {}",
        file.display(),
        if bias { ", with the paper's bias" } else { "" },
        out.display()
    );
    super::prepare_out_dir(out)?;
    let scenario = spec
        .simulate(seed, bias)
        .map_err(formation_sim::reproduce::ReproduceError::from)?;
    let mut config = spec.filter_config();
    config.tuning.design = design;
    let run = run_filter(&scenario, &config)?;
    write_outputs(out, &run)?;
    Ok(run)
}

/// Writes the smoothed series and summary of a run into `out`.
fn write_smoothed(out: &Path, run: &Reproduction) -> Result<(), CliError> {
    write_file(
        &out.join("series-smoothed.csv"),
        &series_csv(&run.smoothed_records),
    )?;
    let json = serde_json::to_string_pretty(&run.smoothed_summary)?;
    write_file(&out.join("summary-smoothed.json"), &(json + "\n"))?;
    eprintln!("reproduce dukf: wrote series-smoothed.csv, summary-smoothed.json");
    Ok(())
}

/// Writes the series, figures and summary of a run into `out`.
fn write_outputs(out: &Path, run: &Reproduction) -> Result<Summary, CliError> {
    write_file(&out.join("series.csv"), &series_csv(&run.records))?;
    let fig12 = fig12_panels(&run.records);
    write_svg(&out.join("fig12.svg"), &fig12, FIGURE_SIZE)?;
    write_png(&out.join("fig12.png"), &fig12, FIGURE_SIZE)?;
    let fig13 = fig13_panels(&run.records);
    write_svg(&out.join("fig13.svg"), &fig13, FIGURE_SIZE)?;
    write_png(&out.join("fig13.png"), &fig13, FIGURE_SIZE)?;
    let json = serde_json::to_string_pretty(&run.summary)?;
    write_file(&out.join("summary.json"), &(json + "\n"))?;
    eprintln!(
        "reproduce dukf: wrote series.csv, fig12.svg/png, fig13.svg/png, summary.json ({} steps)",
        run.summary.steps
    );
    Ok(run.summary.clone())
}

fn write_file(path: &Path, text: &str) -> Result<(), CliError> {
    std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()).into())
}

/// The per-step series as CSV with a header.
fn series_csv(records: &[StepRecord]) -> String {
    let mut s = String::from(
        "t,l12_true,l12_measured,l12_estimated,alpha12_true,alpha12_measured,alpha12_estimated,\
         beta12_true,beta12_measured,beta12_estimated,v1_true,v1_estimated,w1_true,w1_estimated\n",
    );
    for r in records {
        let _ = writeln!(
            s,
            "{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}",
            r.t,
            r.truth[0],
            r.measured[0],
            r.estimated[0],
            r.truth[1],
            r.measured[1],
            r.estimated[1],
            r.truth[2],
            r.measured[2],
            r.estimated[2],
            r.v1_true,
            r.v1_estimated,
            r.w1_true,
            r.w1_estimated
        );
    }
    s
}

/// A short readable table of the summary.
pub fn summary_table(s: &Summary) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "dual UKF, seed {}, {} ({} steps from t = {:.3} s)",
        s.seed,
        if s.bias {
            "with the paper's bias"
        } else {
            "no bias"
        },
        s.steps,
        s.mse_from_t
    );
    let _ = writeln!(
        t,
        "{:<10} {:>14} {:>14} {:>8}",
        "variable", "MSE estimate", "MSE measured", "ratio"
    );
    for (name, est, meas) in [
        ("l12", s.mse_l12, s.mse_meas_l12),
        ("alpha12", s.mse_alpha12, s.mse_meas_alpha12),
        ("beta12", s.mse_beta12, s.mse_meas_beta12),
    ] {
        let _ = writeln!(
            t,
            "{name:<10} {est:>14.3e} {meas:>14.3e} {:>8.1}",
            meas / est
        );
    }
    let _ = writeln!(t, "{:<10} {:>14.3e}", "v1", s.mse_v1);
    let _ = writeln!(t, "{:<10} {:>14.3e}", "w1", s.mse_w1);
    let _ = writeln!(
        t,
        "RMS error after t = 2 s: v1 {:.4} m/s, w1 {:.4} rad/s",
        s.rms_v1_after_2s, s.rms_w1_after_2s
    );
    t
}
