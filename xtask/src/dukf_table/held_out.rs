//! `docs/dukf-held-out.md` (issue #30): the formation filter on a follower that steers on its
//! own estimate, with imperfect actuation and noisy odometry, against baselines tuned on
//! other seeds. Written by `cargo xtask dukf-table --held-out`.
//!
//! For each scenario file with `control: estimate`: the default filter (what `reproduce
//! dukf` runs: the IMM, told the follower's controller) drives the follower on seeds 1..20
//! and on the held-out seeds 101..120. The baselines filter the measurements of those same
//! runs: a scalar random walk and a constant-velocity Kalman filter per variable, and a
//! filterpy UKF on the paper's polar model (the follower's odometry as its inputs, the
//! leader's velocities a random walk). Each baseline's noise is chosen from a grid on seeds
//! 1..20, per figure (the most demanding reading: a baseline may take a different setting
//! for each figure), and reported on 101..120. The raw measurements, the dual UKF and the IMM
//! not told the controller (each driving its own follower), and the paper's setting (the
//! same scenario with the follower on the truth) stand beside them.

use std::fmt::Write as _;
use std::path::Path;

use formation_filter::{FilterConfig, FilterDesign};
use formation_sim::reproduce::{
    Baseline, ClosedLoop, Reproduction, START_WORLD_POSE_STD, Summary, baseline,
};
use formation_sim::scenario::{Control, Scenario};
use formation_sim::scenario_file::ScenarioSpec;
use serde_json::{Value, json};
use unicycle::{PolarModel, wrap_angle};

use super::common::{HELD_OUT_SEEDS, SEEDS, median, verdict};
use super::{chi2_bounds, consistency};
use crate::Result;

/// The scenario files of issue #30 and what each is.
const SCENARIOS: [(&str, &str); 5] = [
    (
        "reference-actuation.yaml",
        "the reference scenario, the follower's wheels at 0.95 of v2 with noise",
    ),
    (
        "hard-turn-actuation.yaml",
        "the leader turns hard, w1 = 0.6 sin(0.6 t) rad/s",
    ),
    (
        "l12-step-actuation.yaml",
        "the l12 set-point steps from 1.0 m to 1.5 m at t = 4 s",
    ),
    (
        "far-actuation.yaml",
        "the follower 3.3 m behind, then 3.8 m from t = 5 s",
    ),
    (
        "abrupt-leader.yaml",
        "v1 steps at 2 s and 5 s, w1 flips sign at 3 s and 6 s",
    ),
];

/// The targets of issue #30: the default filter's median MSE at most this fraction of the
/// best tuned baseline's, and of the raw measurements'.
const BASELINE_FRACTION: f64 = 0.8;
const RAW_FRACTION: f64 = 0.5;
/// The offline smoother's median MSE at most this fraction of the causal filter's (issue #30).
const SMOOTHED_FRACTION: f64 = 0.7;
/// Where the oracle itself is above [`BASELINE_FRACTION`] of the best baseline, the default
/// filter's MSE at most this multiple of the oracle's instead (issue #30).
const ORACLE_FRACTION: f64 = 1.2;

/// The grid of the scalar baselines' process noise (per step for the random walk, the
/// spectral density of the white acceleration for the constant-velocity model): 1e-10 to 1
/// in steps of about half a decade.
fn scalar_grid() -> Vec<f64> {
    (-10..=0)
        .flat_map(|e| [1.0, 3.0].map(|m| m * 10f64.powi(e)))
        .filter(|q| *q <= 1.0)
        .collect()
}

/// The filterpy UKF's grid: the leader velocities' random-walk variance per step `rr` for
/// `v1` and `w1` (1e-6 to 1e-2 each), and the formation variables' process noise per step
/// (1e-8 or 1e-6 on `l12`, `alpha12`, `beta12`; the leader's unobserved world pose 1e-6).
fn ukf_grid() -> Vec<Value> {
    let mut grid = Vec::new();
    for qf in [1e-8, 1e-6] {
        for rv in [1e-6, 1e-5, 1e-4, 1e-3, 1e-2] {
            for rw in [1e-6, 1e-5, 1e-4, 1e-3, 1e-2] {
                grid.push(json!({"q": [1e-6, 1e-6, 1e-6, qf, qf, qf], "rr": [rv, rw]}));
            }
        }
    }
    grid
}

/// The IMM with the manoeuvre hypothesis J in C's place (`unicycle::LeaderJump`): velocity
/// jumps of 0.05 m/s and 0.1 rad/s per step, J held 0.2 s on average, a manoeuvre every 10 s
/// on average. Chosen on seeds 1..20 of these scenarios (by hand, from a few settings).
fn with_jump(config: &FilterConfig) -> FilterConfig {
    let mut c = config.clone();
    c.tuning.imm.jump = Some(unicycle::LeaderJump {
        velocity_std: nalgebra::Vector2::new(0.05, 0.1),
        sojourn: 0.2,
        onset: 10.0,
    });
    c
}

/// One run's figures: MSE of `l12`, `alpha12`, `beta12`, RMS error of `v1`, `w1` after 2 s.
type Figures = [f64; 5];

/// The figures of estimates `[l12, alpha12, beta12, v1, w1]` per step `k = 1..` of `s`.
fn figures(s: &Scenario, est: &[[f64; 5]]) -> Figures {
    let mut acc = [0.0; 5];
    let mut late = 0usize;
    for (pair, e) in s.samples.windows(2).zip(est) {
        let (prev, now) = (&pair[0], &pair[1]);
        let h = PolarModel::h(&now.truth);
        acc[0] += (e[0] - h[0]).powi(2);
        acc[1] += wrap_angle(e[1] - h[1]).powi(2);
        acc[2] += wrap_angle(e[2] - h[2]).powi(2);
        if now.t > 2.0 {
            acc[3] += (e[3] - prev.leader_inputs.v).powi(2);
            acc[4] += (e[4] - prev.leader_inputs.w).powi(2);
            late += 1;
        }
    }
    let n = est.len().max(1) as f64;
    let nl = late.max(1) as f64;
    [
        acc[0] / n,
        acc[1] / n,
        acc[2] / n,
        (acc[3] / nl).sqrt(),
        (acc[4] / nl).sqrt(),
    ]
}

fn summary_figures(s: &Summary) -> Figures {
    [
        s.mse.l12,
        s.mse.alpha12,
        s.mse.beta12,
        s.rms_v1_after_2s,
        s.rms_w1_after_2s,
    ]
}

/// The median over runs of figure `i`.
fn med(runs: &[Figures], i: usize) -> f64 {
    median(runs.iter().map(|f| f[i]).collect())
}

/// A run exported for `ukf_baseline.py`: started at the first measurement as ours is.
fn export(s: &Scenario, config: &FilterConfig) -> Result<Value> {
    let r = s.config.noise_covariance();
    let first = s.samples.first().ok_or("a scenario without samples")?;
    let started = config.started_at(&first.measurement, &r, START_WORLD_POSE_STD)?;
    let tu = &started.tuning;
    Ok(json!({
        "dt": s.config.dt,
        "d": s.config.d,
        "ut": [1.0, 2.0, 0.0],
        "x0": started.x0.as_slice(),
        "p0": tu.p0.diagonal().as_slice(),
        "w0": tu.w0.as_slice(),
        "pw0": tu.pw0.diagonal().as_slice(),
        "r": r.diagonal().as_slice(),
        "measurements": s.samples[1..].iter().map(|x| x.measurement.as_slice().to_vec()).collect::<Vec<_>>(),
        "inputs": s.samples[..s.samples.len() - 1].iter().map(|x| [x.odometry.v, x.odometry.w]).collect::<Vec<_>>(),
    }))
}

/// Runs `ukf_baseline.py` over `runs` at every grid point; `[grid point][run]` figures
/// (NaN where filterpy failed).
fn filterpy(
    python: &Path,
    root: &Path,
    name: &str,
    scenarios: &[&Scenario],
    config: &FilterConfig,
) -> Result<Vec<Vec<Figures>>> {
    let work = root.join("target").join("dukf-held-out");
    std::fs::create_dir_all(&work)?;
    let runs = scenarios
        .iter()
        .map(|s| export(s, config))
        .collect::<Result<Vec<_>>>()?;
    let input = work.join(format!("{name}.json"));
    let output = work.join(format!("{name}-estimates.json"));
    std::fs::write(
        &input,
        serde_json::to_string(&json!({"runs": runs, "grid": ukf_grid()}))?,
    )?;
    eprintln!(
        "dukf-table: filterpy UKF on {name} ({} grid points)",
        ukf_grid().len()
    );
    crate::pyenv::run_script(
        python,
        &root.join("xtask/py/ukf_baseline.py"),
        &[&input, &output],
    )?;
    let results: Value = serde_json::from_str(&std::fs::read_to_string(&output)?)?;
    let grid = results["estimates"]
        .as_array()
        .ok_or("ukf_baseline.py: no estimates")?;
    Ok(grid
        .iter()
        .map(|point| {
            let per_run = point.as_array().cloned().unwrap_or_default();
            scenarios
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    let est: Option<Vec<[f64; 5]>> = per_run.get(i).and_then(|v| {
                        v.as_array().map(|rows| {
                            rows.iter()
                                .map(|row| {
                                    let mut e = [f64::NAN; 5];
                                    for (j, x) in e.iter_mut().enumerate() {
                                        *x = row[j].as_f64().unwrap_or(f64::NAN);
                                    }
                                    e
                                })
                                .collect()
                        })
                    });
                    est.map_or([f64::NAN; 5], |e| figures(s, &e))
                })
                .collect()
        })
        .collect())
}

/// The best tuned setting per figure: the index whose median over the tuning runs is least.
fn best_per_figure(tune: &[Vec<Figures>]) -> [usize; 5] {
    let mut best = [0; 5];
    for (i, b) in best.iter_mut().enumerate() {
        let mut least = f64::INFINITY;
        for (g, runs) in tune.iter().enumerate() {
            let m = med(runs, i);
            if m < least {
                least = m;
                *b = g;
            }
        }
    }
    best
}

/// The scalar baseline of `kind` at every grid point over `runs`, `[grid point][run]`
/// (velocities NaN: it has none).
fn scalar(runs: &[&Scenario], x0: &[f64; 3], kind: fn(f64) -> Baseline) -> Vec<Vec<Figures>> {
    scalar_grid()
        .into_iter()
        .map(|q| {
            runs.iter()
                .map(|s| {
                    let [a, b, c] = baseline(s, x0, kind(q));
                    [a, b, c, f64::NAN, f64::NAN]
                })
                .collect()
        })
        .collect()
}

/// The default filter and every column on one scenario file, as markdown, with its verdicts
/// and its row of the smoothing section of `docs/smoothing.md`.
fn scenario_section(
    python: &Path,
    root: &Path,
    file: &str,
    what: &str,
) -> Result<(String, Vec<bool>, String)> {
    let spec = ScenarioSpec::load(&root.join("fixtures").join("scenarios").join(file))?;
    if spec.control != Control::Estimate {
        return Err(format!("{file}: control is not estimate").into());
    }
    let config = spec.filter_config();
    let mut dual = spec.filter_config();
    dual.tuning.design = FilterDesign::Dual;
    let mut paper_spec = spec.clone();
    paper_spec.control = Control::Truth;
    let mut tune: Vec<(Scenario, Reproduction)> = Vec::new();
    let mut test: Vec<(Scenario, Reproduction)> = Vec::new();
    let (mut duals, mut not_told, mut paper) = (Vec::new(), Vec::new(), Vec::new());
    let (mut jumps, mut oracle) = (Vec::new(), Vec::new());
    let jump = with_jump(&config);
    for seed in SEEDS {
        tune.push(spec.run(seed, false, &config, true)?);
    }
    for seed in HELD_OUT_SEEDS {
        eprintln!("dukf-table: {file}, held-out seed {seed}");
        test.push(spec.run(seed, false, &config, true)?);
        duals.push(summary_figures(
            &spec.run(seed, false, &dual, false)?.1.summary,
        ));
        not_told.push(summary_figures(
            &spec.run(seed, false, &config, false)?.1.summary,
        ));
        jumps.push(summary_figures(
            &spec.run(seed, false, &jump, false)?.1.summary,
        ));
        paper.push(summary_figures(
            &paper_spec.run(seed, false, &config, true)?.1.summary,
        ));
        // The same filter handed the leader's true inputs before every step, driving its own
        // follower.
        let simulation = spec.simulation(seed, false)?;
        let run = ClosedLoop::new(simulation, &config, true, true)?.oracle();
        oracle.push(summary_figures(&run.collect_run()?.1.summary));
    }
    let tune_s: Vec<&Scenario> = tune.iter().map(|r| &r.0).collect();
    let test_s: Vec<&Scenario> = test.iter().map(|r| &r.0).collect();
    let ours: Vec<Figures> = test.iter().map(|r| summary_figures(&r.1.summary)).collect();
    let smoothed: Vec<Figures> = test
        .iter()
        .map(|r| summary_figures(&r.1.smoothed_summary))
        .collect();
    let raw: Vec<Figures> = test
        .iter()
        .map(|r| {
            let m = &r.1.summary.mse;
            [
                m.meas_l12,
                m.meas_alpha12,
                m.meas_beta12,
                f64::NAN,
                f64::NAN,
            ]
        })
        .collect();
    let x0 = {
        let x = spec.filter_x0();
        [x[3], x[4], x[5]]
    };
    let grid = scalar_grid();
    let mut columns: Vec<(&str, Vec<Figures>, Vec<String>)> = Vec::new();
    for (name, kind) in [
        (
            "random walk",
            (|q| Baseline::RandomWalk { q }) as fn(f64) -> Baseline,
        ),
        ("constant velocity", |q| Baseline::ConstantVelocity { q }),
    ] {
        let best = best_per_figure(&scalar(&tune_s, &x0, kind));
        let held = scalar(&test_s, &x0, kind);
        let figs: Vec<Figures> = (0..test_s.len())
            .map(|r| std::array::from_fn(|i| held[best[i]][r][i]))
            .collect();
        let qs = best.iter().map(|&g| format!("q {:.0e}", grid[g])).collect();
        columns.push((name, figs, qs));
    }
    let mut all: Vec<&Scenario> = tune_s.clone();
    all.extend(&test_s);
    let ukf = filterpy(python, root, file.trim_end_matches(".yaml"), &all, &config)?;
    let (ukf_tune, ukf_test): (Vec<Vec<Figures>>, Vec<Vec<Figures>>) = ukf
        .into_iter()
        .map(|runs| {
            let (a, b) = runs.split_at(tune_s.len());
            (a.to_vec(), b.to_vec())
        })
        .unzip();
    let best = best_per_figure(&ukf_tune);
    let figs: Vec<Figures> = (0..test_s.len())
        .map(|r| std::array::from_fn(|i| ukf_test[best[i]][r][i]))
        .collect();
    let points = ukf_grid();
    let qs = best
        .iter()
        .map(|&g| {
            let p = &points[g];
            format!(
                "rr {:.0e}/{:.0e}, q {:.0e}",
                p["rr"][0].as_f64().unwrap_or(f64::NAN),
                p["rr"][1].as_f64().unwrap_or(f64::NAN),
                p["q"][3].as_f64().unwrap_or(f64::NAN)
            )
        })
        .collect();
    columns.push(("filterpy UKF", figs, qs));

    let mut md = String::new();
    let mut verdicts = Vec::new();
    let _ = writeln!(md, "### `{file}`: {what}\n");
    let _ = writeln!(
        md,
        "| figure | default filter | raw | random walk | constant velocity | filterpy UKF | oracle (true v1, w1) | x best baseline (<= {BASELINE_FRACTION}, or {ORACLE_FRACTION}x the oracle) | x raw (<= {RAW_FRACTION}) | dual UKF | IMM not told | IMM with J, not told | paper setting (truth control) | default filter smoothed offline (x causal, <= {SMOOTHED_FRACTION}) |"
    );
    let _ = writeln!(
        md,
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    let names = [
        "MSE l12 [m^2]",
        "MSE alpha12 [rad^2]",
        "MSE beta12 [rad^2]",
        "RMS v1 after 2 s [m/s]",
        "RMS w1 after 2 s [rad/s]",
    ];
    let mut smooth_row = format!("| `{file}` |");
    for (i, name) in names.iter().enumerate() {
        let o = med(&ours, i);
        let cells: Vec<String> = columns
            .iter()
            .map(|(_, f, qs)| {
                let m = med(f, i);
                if m.is_nan() {
                    "-".into()
                } else {
                    format!("{m:.3e} ({})", qs[i])
                }
            })
            .collect();
        let (vs_best, vs_raw) = if i < 3 {
            let best = columns
                .iter()
                .map(|(_, f, _)| med(f, i))
                .fold(f64::INFINITY, f64::min);
            let raw_m = med(&raw, i);
            let (a, b) = (o / best, o / raw_m);
            // Issue #30: where the oracle itself does not reach the fraction of the best
            // baseline, the row's target is a multiple of the oracle's figure instead.
            let or = med(&oracle, i);
            let cell = if or / best <= BASELINE_FRACTION {
                verdicts.push(a <= BASELINE_FRACTION);
                format!("{a:.2} {}", verdict(a <= BASELINE_FRACTION))
            } else {
                let vs_oracle = o / or;
                verdicts.push(vs_oracle <= ORACLE_FRACTION);
                format!(
                    "{a:.2}; oracle {:.2}, so {vs_oracle:.2}x the oracle {}",
                    or / best,
                    verdict(vs_oracle <= ORACLE_FRACTION)
                )
            };
            verdicts.push(b <= RAW_FRACTION);
            (cell, format!("{b:.2} {}", verdict(b <= RAW_FRACTION)))
        } else {
            // The velocities: at most the tuned filterpy UKF's.
            let theirs = med(&columns[2].1, i);
            verdicts.push(o <= theirs);
            (
                format!("{:.2} {} (vs filterpy)", o / theirs, verdict(o <= theirs)),
                "-".into(),
            )
        };
        let raw_cell = if i < 3 {
            format!("{:.3e}", med(&raw, i))
        } else {
            "-".into()
        };
        let sm = med(&smoothed, i);
        // MSEs at most the fraction of the causal filter's, velocity errors below it.
        let smoothed_ok = if i < 3 {
            sm / o <= SMOOTHED_FRACTION
        } else {
            sm < o
        };
        let _ = write!(
            smooth_row,
            " {o:.3e} / {sm:.3e} ({:.2} {}) |",
            sm / o,
            verdict(smoothed_ok)
        );
        let smoothed_cell = if i < 3 {
            let ratio = sm / o;
            verdicts.push(ratio <= SMOOTHED_FRACTION);
            format!(
                "{sm:.3e} ({ratio:.2} {})",
                verdict(ratio <= SMOOTHED_FRACTION)
            )
        } else {
            format!("{sm:.3e}")
        };
        let _ = writeln!(
            md,
            "| {name} | {o:.3e} | {raw_cell} | {} | {} | {} | {:.3e} | {vs_best} | {vs_raw} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {smoothed_cell} |",
            cells[0],
            cells[1],
            cells[2],
            med(&oracle, i),
            med(&duals, i),
            med(&not_told, i),
            med(&jumps, i),
            med(&paper, i),
        );
    }
    let reps: Vec<Reproduction> = test.into_iter().map(|r| r.1).collect();
    let b3 = chi2_bounds(3.0, reps.len());
    let b2 = chi2_bounds(2.0, reps.len());
    let nis = consistency(&reps, |c| c.nis, b3, 2.0);
    let nx = consistency(&reps, |c| c.nees_formation, b3, 2.0);
    let nw = consistency(&reps, |c| c.nees_velocity, b2, 2.0);
    let inside = |m: f64, b: (f64, f64)| m >= b.0 && m <= b.1;
    verdicts.push(inside(nis.0, b3));
    verdicts.push(inside(nx.0, b3));
    verdicts.push(inside(nw.0, b2));
    let _ = writeln!(
        md,
        "\nConsistency of the default filter after 2 s, per-step averages over the 20 held-out \
         runs: NIS mean {:.2} ({}; band {:.2}..{:.2}, {:.0} % of steps inside), formation NEES \
         {:.2} ({}; same band, {:.0} %), velocity NEES {:.2} ({}; band {:.2}..{:.2}, {:.0} %).\n",
        nis.0,
        verdict(inside(nis.0, b3)),
        b3.0,
        b3.1,
        100.0 * nis.1,
        nx.0,
        verdict(inside(nx.0, b3)),
        100.0 * nx.1,
        nw.0,
        verdict(inside(nw.0, b2)),
        b2.0,
        b2.1,
        100.0 * nw.1
    );
    Ok((md, verdicts, smooth_row))
}

/// The whole document, and the held-out section of `docs/smoothing.md`.
pub fn document() -> Result<(String, String)> {
    let root = crate::workspace_root()?;
    let python = crate::pyenv::python(
        &root,
        "dukf-table",
        &[crate::pyenv::NUMPY, crate::pyenv::FILTERPY],
        "import filterpy",
    )?;
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# The formation filter on a follower that steers on its estimate (issue #30)\n\n\
         Generated by `cargo xtask dukf-table --held-out` (`xtask/src/dukf_table/held_out.rs`, \
         `xtask/py/ukf_baseline.py`); do not edit by hand.\n\n\
         Every scenario below has `control: estimate`: the filter runs inside the simulation \
         and the follower's separation-bearing controller acts on its estimate, as on a robot; \
         the follower's wheels execute 0.95 of the commanded `v2` with white noise of 0.03 m/s \
         and 0.03 rad/s, and the filter is given its odometry (the executed inputs plus white \
         noise of 0.01 m/s and 0.01 rad/s), never the executed inputs. The filter starts at its \
         first measurement.\n\n\
         **Columns.** *Default filter*: what `formation-tracker reproduce dukf` runs (the IMM, \
         told the follower's controller). *Raw*: the measurements. *Random walk*, *constant \
         velocity*: one scalar Kalman filter per variable (`formation_sim::reproduce::Baseline`). \
         *filterpy UKF*: one `UnscentedKalmanFilter` over `[x1, y1, theta1, l12, alpha12, beta12, \
         v1, w1]` with the paper's polar model (`xtask/py/polar_ukf.py`), the follower's odometry \
         as its inputs and the leader's velocities a random walk. The three baselines filter the \
         default filter's runs' measurements; their noise is chosen **per figure** from a grid \
         on seeds 1..20 (shown in brackets: `q` for the scalar filters, 1e-10..1, half decades; \
         for the UKF `rr` of `v1`/`w1` 1e-6..1e-2 in decades and `q` of the formation variables \
         1e-8 or 1e-6), and every figure is the median over the **held-out seeds 101..120**. \
         *x best baseline*: the default filter's median over the best baseline's. *Dual UKF*, \
         *IMM not told*: the other designs, each driving its own follower, reference tuning. \
         *IMM with J, not told*: the IMM not told the controller, with the manoeuvre \
         hypothesis J (`unicycle::LeaderJump`: velocity jumps of 0.05 m/s and 0.1 rad/s per \
         step, held 0.2 s, one every 10 s on average, chosen on seeds 1..20) in place of C. \
         *Smoothed offline*: the default filter's runs after the offline unscented RTS \
         smoother (`docs/smoothing.md`), against the causal figure. \
         *Paper setting*: the default filter on the same scenario with the follower's \
         controller on the truth (`control: truth`), shown for comparison only: no robot has \
         the truth. *Oracle*: the default filter handed the leader's true `v1`, `w1` before \
         every step (`FormationFilter::pin_leader_velocity`), driving its own follower; no \
         robot has them either. Where the oracle's MSE is itself above {BASELINE_FRACTION}x \
         the best baseline's, that row's target is {ORACLE_FRACTION}x the oracle's figure \
         instead (issue #30), and the cell says so.\n\n\
         Targets (issue #30): MSE at most {BASELINE_FRACTION}x the best tuned baseline and at \
         most {RAW_FRACTION}x the raw measurements, and smoothed at most {SMOOTHED_FRACTION}x \
         the causal filter; RMS `v1`, `w1` after 2 s at most the tuned \
         filterpy UKF's; NIS and NEES inside their 95 % bands. The filters are told the \
         follower's odometry noise (`FilterTuning::input_noise_std`, from the scenario file).\n"
    );
    let mut smoothing = format!(
        "## The control: estimate scenarios, held-out seeds 101..120 (issue #30)\n\n\
         Written by `cargo xtask dukf-table --held-out` from the runs of \
         `docs/dukf-held-out.md` (its *default filter* and *smoothed offline* columns): the \
         follower steers on its filter's estimate, its wheels execute 0.95 of `v2` with noise, \
         and the filter has only its odometry. Each cell is the causal IMM's median over the \
         20 held-out seeds, then the smoothed median, then their ratio. Targets (issue #30): \
         smoothed MSE at most {SMOOTHED_FRACTION}x the causal filter's; the velocity errors \
         lower than the causal filter's.\n\n\
         | scenario | MSE l12 [m^2] | MSE alpha12 [rad^2] | MSE beta12 [rad^2] | RMS v1 after 2 s [m/s] | RMS w1 after 2 s [rad/s] |\n\
         |---|---|---|---|---|---|\n"
    );
    let mut pass = 0;
    let mut total = 0;
    for (file, what) in SCENARIOS {
        let (section, verdicts, smooth_row) = scenario_section(&python, &root, file, what)?;
        md.push_str(&section);
        let _ = writeln!(smoothing, "{smooth_row}");
        pass += verdicts.iter().filter(|v| **v).count();
        total += verdicts.len();
    }
    let _ = writeln!(md, "Targets met: {pass} of {total}.");
    Ok((md, smoothing))
}
