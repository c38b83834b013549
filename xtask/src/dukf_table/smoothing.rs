//! `docs/smoothing.md`: the offline smoother against the causal IMM (the tracker's default,
//! which `track --smooth` follows), with the dual UKF's reported beside it, on the reference
//! scenario (seeds 1..20 and the never-tuned 21..40) and the scenario fixtures. Written by
//! `cargo xtask dukf-table` from the same runs as `docs/dukf-reproduction.md`.

use std::fmt::Write as _;

use formation_filter::FilterDesign;
use formation_sim::reproduce::{Reproduction, Summary, reproduce, run_filter};
use formation_sim::scenario_file::ScenarioSpec;

use super::common::{CHECK_SEEDS, SEEDS, median, verdict};
use crate::Result;

/// The smoothed median MSE of `l12` and `alpha12` must be at most this fraction of the
/// causal filter's (issue #10).
const MAX_RATIO: f64 = 0.5;

type Field = (&'static str, fn(&Summary) -> f64, Target);

#[derive(Clone, Copy)]
enum Target {
    /// Smoothed median at most `MAX_RATIO` x causal.
    Half,
    /// Smoothed median below causal.
    Lower,
    /// Reported only.
    None,
}

const FIELDS: [Field; 7] = [
    ("MSE l12 [m^2]", |s| s.mse.l12, Target::Half),
    ("MSE alpha12 [rad^2]", |s| s.mse.alpha12, Target::Half),
    ("MSE beta12 [rad^2]", |s| s.mse.beta12, Target::None),
    ("MSE v1 [(m/s)^2]", |s| s.mse.v1, Target::None),
    ("MSE w1 [(rad/s)^2]", |s| s.mse.w1, Target::None),
    (
        "RMS v1 error after 2 s [m/s]",
        |s| s.rms_v1_after_2s,
        Target::Lower,
    ),
    (
        "RMS w1 error after 2 s [rad/s]",
        |s| s.rms_w1_after_2s,
        Target::Lower,
    ),
];

/// One table: the IMM's causal and smoothed medians (with the targets when `targets`), and the
/// dual UKF's causal and smoothed medians reported beside them.
fn table(
    md: &mut String,
    causal: &[Summary],
    smoothed: &[Summary],
    dual: &[Summary],
    dual_smoothed: &[Summary],
    targets: bool,
) {
    if targets {
        let _ = writeln!(
            md,
            "| figure | causal filter (IMM) | smoothed | smoothed / causal | target | result | dual UKF causal (reported) | dual UKF smoothed (reported) |\n\
             |---|---:|---:|---:|---|---|---:|---:|"
        );
    } else {
        let _ = writeln!(
            md,
            "| figure | causal filter (IMM) | smoothed | smoothed / causal | dual UKF causal (reported) | dual UKF smoothed (reported) |\n|---|---:|---:|---:|---:|---:|"
        );
    }
    for (name, f, target) in FIELDS {
        let c = median(causal.iter().map(f).collect());
        let s = median(smoothed.iter().map(f).collect());
        let d = median(dual.iter().map(f).collect());
        let ds = median(dual_smoothed.iter().map(f).collect());
        let ratio = s / c;
        let _ = write!(md, "| {name} | {c:.3e} | {s:.3e} | {ratio:.3} |");
        if targets {
            let (text, ok) = match target {
                Target::Half => (format!("<= {MAX_RATIO} x causal"), Some(ratio <= MAX_RATIO)),
                Target::Lower => ("< causal".to_string(), Some(ratio < 1.0)),
                Target::None => ("-".to_string(), None),
            };
            let _ = write!(md, " {text} | {} |", ok.map_or("-", verdict));
        }
        let _ = writeln!(md, " {d:.3e} | {ds:.3e} |");
    }
}

/// The causal and the smoothed summaries of `runs`.
fn split(runs: &[Reproduction]) -> (Vec<Summary>, Vec<Summary>) {
    runs.iter()
        .map(|r| (r.summary.clone(), r.smoothed_summary.clone()))
        .unzip()
}

/// The document, from the dual UKF's reference runs over [`SEEDS`] and the check seeds (with
/// their smoothed summaries); the IMM's runs (the tracker's default, whose smoother the
/// targets are for) are rerun here with their smoothed summaries (`_imm`, `_check_imm`: the
/// same runs' causal summaries, which these reproduce).
pub(super) fn document(
    dual: &[Reproduction],
    check_dual: &[Reproduction],
    _imm: &[Summary],
    _check_imm: &[Summary],
) -> Result<String> {
    let imm_runs = |seeds: std::ops::RangeInclusive<u64>| -> Result<Vec<Reproduction>> {
        let mut out = Vec::new();
        for seed in seeds {
            eprintln!("dukf-table: smoothing, IMM seed {seed}");
            out.push(reproduce(seed, false)?);
        }
        Ok(out)
    };
    let mut md = String::new();
    md.push_str(include_str!("smoothing_intro.md"));
    let (c, s) = split(&imm_runs(SEEDS)?);
    let (d, ds) = split(dual);
    let _ = writeln!(
        md,
        "\n## Reference scenario, seeds 1..20 (medians, without bias)\n"
    );
    table(&mut md, &c, &s, &d, &ds, true);
    let (c, s) = split(&imm_runs(CHECK_SEEDS)?);
    let (d, ds) = split(check_dual);
    let _ = writeln!(
        md,
        "\n## Reference scenario, seeds 21..40 (never used for tuning)\n"
    );
    table(&mut md, &c, &s, &d, &ds, true);
    let root = crate::workspace_root()?;
    for name in ["l12-step.yaml", "hard-turn.yaml"] {
        eprintln!("dukf-table: smoothing on {name}");
        let spec = ScenarioSpec::load(&root.join("fixtures").join("scenarios").join(name))?;
        let imm_config = spec.filter_config();
        let mut dual_config = spec.filter_config();
        dual_config.tuning.design = FilterDesign::Dual;
        let (mut imm, mut dual) = (Vec::new(), Vec::new());
        for seed in SEEDS {
            let scenario = spec.simulate(seed, false)?;
            imm.push(run_filter(&scenario, &imm_config)?);
            dual.push(run_filter(&scenario, &dual_config)?);
        }
        let (c, s) = split(&imm);
        let (d, ds) = split(&dual);
        let _ = writeln!(
            md,
            "\n## `fixtures/scenarios/{name}`, seeds 1..20 (medians, same tuning)\n"
        );
        table(&mut md, &c, &s, &d, &ds, false);
    }
    Ok(md)
}
