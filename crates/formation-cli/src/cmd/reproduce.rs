//! `formation-tracker reproduce ...`: regenerate the paper's results.
//!
//! `reproduce dukf` runs the dual-UKF experiment of the paper's Figs. 12-13 on the reference
//! scenario (`docs/reference-scenario.md`) and writes its series, figures and summary.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use clap::{Args as ClapArgs, Subcommand};
use formation_filter::{FilterConfig, FilterDesign};
use formation_sim::plot::{fig12_panels, fig13_panels, write_png, write_svg};
use formation_sim::reproduce::{
    ClosedLoop, ReproduceError, StepRecord, Summary, SummaryTally, paper_filter_config_with,
    summarize,
};
use formation_sim::scenario::{Control, ScenarioConfig, Simulation, reference_leader_inputs};
use formation_sim::scenario_file::ScenarioSpec;
use unicycle::Inputs;

use super::CliError;
use super::output::Staged;
use super::progress::errln;

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
    /// w1 = 0.2 sin(0.4 t) rad/s; follower holding formation on its filter's estimate, or
    /// on the truth as in the paper with --paper; camera offset d = 0.5 m; 8 s at 30 Hz), measures (l12, alpha12, beta12) with Gaussian noise of standard
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
    /// What the follower's controller acts on, overriding the scenario's `control`:
    /// `estimate` (the filter's estimate after each measurement, as on a robot: the
    /// default of the built-in scenario and of scenario files), `truth` (the true formation
    /// and leader inputs: the paper's setting) or `open` (no feedback: the planned run's
    /// commands replayed).
    #[arg(long, value_name = "MODE", value_parser = Control::from_name)]
    control: Option<Control>,
    /// The paper's own setting (Figs. 12-13): the built-in reference scenario with the
    /// follower's controller on the truth and exact actuation (the same as `--control
    /// truth`). Its figures hold only because the simulation hands the follower the truth;
    /// docs/dukf-reproduction.md labels them as such.
    #[arg(long, conflicts_with_all = ["scenario", "control"])]
    paper: bool,
}

/// Runs `reproduce`.
pub fn run(args: Args) -> Result<(), CliError> {
    match args.what {
        What::Dukf(a) => run_dukf(&a),
        What::PaperScenes(a) => super::reproduce_scenes::run(&a),
    }
}

/// The files `reproduce dukf` may write into its folder.
const OUTPUTS: [&str; 8] = [
    "series.csv",
    "fig12.svg",
    "fig12.png",
    "fig13.svg",
    "fig13.png",
    "summary.json",
    "series-smoothed.csv",
    "summary-smoothed.json",
];

/// Memory `--smooth` takes per step, bytes: the filter's history, the smoother's forward
/// pass and noises, and the records (measured: 943 MB for 324,000 steps).
const SMOOTH_BYTES_PER_STEP: u64 = 3_000;

/// At most this many steps go into a figure: a longer run's figures show every k-th step
/// (k a power of two), so that memory stays flat however long the scenario; series.csv
/// always has every step.
const FIGURE_STEPS: usize = 16_384;

/// Runs `reproduce dukf`: simulates the scenario one sample at a time, filters it, and
/// streams series.csv; keeps only the figure's (bounded) steps, the summary's sums, and with
/// `--smooth` the history the smoother needs. Progress goes to stderr.
fn run_dukf(a: &DukfArgs) -> Result<(), CliError> {
    let design = if a.dual {
        FilterDesign::Dual
    } else {
        FilterDesign::Imm
    };
    let with_bias = if a.bias {
        ", with the paper's bias"
    } else {
        ""
    };
    let (summary, smoothed) = match &a.scenario {
        None => {
            errln!(
                "reproduce dukf: seed {}{with_bias}, writing to {}",
                a.seed,
                a.out.display()
            );
            super::prepare_out_dir(&a.out)?;
            let control = if a.paper {
                Control::Truth
            } else {
                a.control.unwrap_or_default()
            };
            let mut config = ScenarioConfig::reference(a.seed).with_control(control);
            if a.bias {
                config = config.with_paper_bias();
            }
            let filter = paper_filter_config_with(config.d, config.dt, design);
            let simulation = Simulation::new(&config, reference_leader_inputs, &[])
                .map_err(ReproduceError::from)?;
            filter_and_write(&a.out, simulation, &filter, a.smooth)?
        }
        Some(file) => {
            let outputs: Vec<_> = OUTPUTS.iter().map(|n| a.out.join(n)).collect();
            let outputs: Vec<_> = outputs.iter().map(|p| ("--out", p.as_path())).collect();
            super::output::refuse_inputs_as_outputs(&outputs, &[("--scenario", file)])?;
            let mut spec = ScenarioSpec::load(file)?;
            errln!(
                "reproduce dukf: scenario {}, seed {}{with_bias}, writing to {}",
                file.display(),
                a.seed,
                a.out.display()
            );
            super::prepare_out_dir(&a.out)?;
            spec.control = a.control.unwrap_or(spec.control);
            let simulation = spec
                .simulation(a.seed, a.bias)
                .map_err(ReproduceError::from)?;
            let mut filter = spec.filter_config();
            filter.tuning.design = design;
            filter_and_write(&a.out, simulation, &filter, a.smooth)?
        }
    };
    let label = match design {
        FilterDesign::Imm => "IMM formation filter,",
        FilterDesign::Dual => "dual UKF,",
    };
    let mut text = summary_table(&summary).replacen("dual UKF,", label, 1);
    if let Some(smoothed) = smoothed {
        text.push('\n');
        text.push_str(&summary_table(&smoothed).replacen(
            "dual UKF,",
            "smoothed (offline, joint unscented RTS),",
            1,
        ));
    }
    super::write_stdout(format_args!("{text}"))?;
    Ok(())
}

/// Runs `simulation` with `filter` in the loop and writes series.csv (streamed), the figures, summary.json and, with
/// `smooth`, series-smoothed.csv and summary-smoothed.json into `out`; returns the summaries.
fn filter_and_write<F: Fn(f64) -> Inputs>(
    out: &Path,
    simulation: Simulation<F>,
    filter: &FilterConfig,
    smooth: bool,
) -> Result<(Summary, Option<Summary>), CliError> {
    let scenario = &simulation.config().clone();
    if smooth {
        // The smoother needs every step: refuse up front what would not fit.
        let need = scenario.steps() as u64 * SMOOTH_BYTES_PER_STEP;
        let budget = formation_io::limits::max_memory();
        if need > budget {
            return Err(format!(
                "--smooth keeps every step: {} steps need about {}, more than --max-memory {} (run without --smooth, whose memory does not grow with the duration, or raise --max-memory)",
                scenario.steps(),
                formation_io::textfile::bytes_text(need),
                formation_io::textfile::bytes_text(budget)
            )
            .into());
        }
    }
    let mut run = ClosedLoop::new(simulation, filter, true, smooth)?;
    let mut staged = Staged::new();
    let mut series = SeriesFile::create(&mut staged, &out.join("series.csv"))?;
    let mut tally = SummaryTally::default();
    let mut figure = Thinned::new(FIGURE_STEPS);
    // Every record, for the smoother's series (only with --smooth).
    let mut all = Vec::new();
    let mut progress =
        super::progress::Progress::new("reproduce dukf", "steps", Some(scenario.steps() as u64));
    for step in run.by_ref() {
        let Some((record, _)) = step?.1 else {
            continue;
        };
        progress.inc();
        series.row(&record)?;
        tally.push(&record);
        if smooth {
            all.push(record.clone());
        }
        figure.push(record);
    }
    progress.finish();
    series.finish()?;
    let summary = tally.finish(scenario);
    let records = figure.into_vec();
    let fig12 = fig12_panels(&records);
    write_svg(&staged.path(&out.join("fig12.svg")), &fig12, FIGURE_SIZE)?;
    write_png(&staged.path(&out.join("fig12.png")), &fig12, FIGURE_SIZE)?;
    let fig13 = fig13_panels(&records);
    write_svg(&staged.path(&out.join("fig13.svg")), &fig13, FIGURE_SIZE)?;
    write_png(&staged.path(&out.join("fig13.png")), &fig13, FIGURE_SIZE)?;
    let json = serde_json::to_string_pretty(&summary)?;
    staged.write(&out.join("summary.json"), json + "\n")?;
    let smoothed_summary = if smooth {
        let smoothed = run.smoothed_records(&all)?;
        let mut series = SeriesFile::create(&mut staged, &out.join("series-smoothed.csv"))?;
        for r in &smoothed {
            series.row(r)?;
        }
        series.finish()?;
        let smoothed_summary = summarize(&smoothed, scenario);
        let json = serde_json::to_string_pretty(&smoothed_summary)?;
        staged.write(&out.join("summary-smoothed.json"), json + "\n")?;
        Some(smoothed_summary)
    } else {
        None
    };
    staged.commit()?;
    errln!(
        "reproduce dukf: wrote series.csv, fig12.svg/png, fig13.svg/png, summary.json ({} steps){}",
        summary.steps,
        if smooth {
            ", series-smoothed.csv, summary-smoothed.json"
        } else {
            ""
        }
    );
    Ok((summary, smoothed_summary))
}

/// Every step while there are at most `cap`; past that every second one of those kept, and
/// so on: at most `cap` steps, evenly spaced, in constant memory.
struct Thinned {
    kept: Vec<StepRecord>,
    cap: usize,
    stride: usize,
    seen: usize,
}

impl Thinned {
    fn new(cap: usize) -> Self {
        Self {
            kept: Vec::new(),
            cap: cap.max(2),
            stride: 1,
            seen: 0,
        }
    }

    fn push(&mut self, r: StepRecord) {
        if self.seen.is_multiple_of(self.stride) {
            if self.kept.len() == self.cap {
                let mut i = 0;
                self.kept.retain(|_| {
                    i += 1;
                    i % 2 == 1
                });
                self.stride *= 2;
            }
            if self.seen.is_multiple_of(self.stride) {
                self.kept.push(r);
            }
        }
        self.seen += 1;
    }

    fn into_vec(self) -> Vec<StepRecord> {
        self.kept
    }
}

/// The per-step series as CSV, written one row at a time.
struct SeriesFile {
    path: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
}

impl SeriesFile {
    fn create(staged: &mut Staged, path: &Path) -> Result<Self, CliError> {
        let mut series = Self {
            path: path.to_owned(),
            out: staged.create(path)?,
        };
        series.write(SERIES_HEADER)?;
        Ok(series)
    }

    fn row(&mut self, r: &StepRecord) -> Result<(), CliError> {
        let mut line = String::new();
        series_row(&mut line, r);
        self.write(&line)
    }

    fn write(&mut self, text: &str) -> Result<(), CliError> {
        use std::io::Write as _;
        self.out
            .write_all(text.as_bytes())
            .map_err(|e| format!("cannot write {}: {e}", self.path.display()).into())
    }

    fn finish(mut self) -> Result<(), CliError> {
        use std::io::Write as _;
        self.out
            .flush()
            .map_err(|e| format!("cannot write {}: {e}", self.path.display()).into())
    }
}

/// The header line of series.csv.
const SERIES_HEADER: &str = "t,l12_true,l12_measured,l12_estimated,alpha12_true,alpha12_measured,\
     alpha12_estimated,beta12_true,beta12_measured,beta12_estimated,v1_true,v1_estimated,w1_true,\
     w1_estimated\n";

/// One row of series.csv.
fn series_row(s: &mut String, r: &StepRecord) {
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

/// A short readable table of the summary.
pub fn summary_table(s: &Summary) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "dual UKF, seed {}, {}, control on the {} ({} steps from t = {:.3} s)",
        s.seed,
        if s.bias {
            "with the paper's bias"
        } else {
            "no bias"
        },
        match s.control {
            Control::Truth => "truth (the paper's setting)",
            Control::Open => "plan (open loop)",
            Control::Estimate => "estimate",
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
        ("l12", s.mse.l12, s.mse.meas_l12),
        ("alpha12", s.mse.alpha12, s.mse.meas_alpha12),
        ("beta12", s.mse.beta12, s.mse.meas_beta12),
    ] {
        let _ = writeln!(
            t,
            "{name:<10} {est:>14.3e} {meas:>14.3e} {:>8.1}",
            meas / est
        );
    }
    let _ = writeln!(t, "{:<10} {:>14.3e}", "v1", s.mse.v1);
    let _ = writeln!(t, "{:<10} {:>14.3e}", "w1", s.mse.w1);
    let _ = writeln!(
        t,
        "RMS error after t = 2 s: v1 {:.4} m/s, w1 {:.4} rad/s",
        s.rms_v1_after_2s, s.rms_w1_after_2s
    );
    t
}
