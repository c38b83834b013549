//! `docs/smoothing.md`: the offline smoother against the causal dual UKF (the tracker's
//! default, which `track --smooth` follows), with the IMM reported beside it, on the reference
//! scenario (seeds 1..20 and the never-tuned 21..40) and the scenario fixtures. Written by
//! `cargo xtask dukf-table` from the same runs as `docs/dukf-reproduction.md`.

use std::fmt::Write as _;

use formation_sim::reproduce::{Reproduction, Summary, run_filter};
use formation_sim::scenario_file::ScenarioSpec;
use formation_tracker::filter::FilterDesign;

use super::{SEEDS, median, verdict, workspace_root};
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
    ("MSE l12 [m^2]", |s| s.mse_l12, Target::Half),
    ("MSE alpha12 [rad^2]", |s| s.mse_alpha12, Target::Half),
    ("MSE beta12 [rad^2]", |s| s.mse_beta12, Target::None),
    ("MSE v1 [(m/s)^2]", |s| s.mse_v1, Target::None),
    ("MSE w1 [(rad/s)^2]", |s| s.mse_w1, Target::None),
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

fn table(
    md: &mut String,
    causal: &[Summary],
    smoothed: &[Summary],
    imm: &[Summary],
    targets: bool,
) {
    if targets {
        let _ = writeln!(
            md,
            "| figure | causal filter (dual UKF) | smoothed | smoothed / causal | target | result | causal IMM (reported) |\n\
             |---|---:|---:|---:|---|---|---:|"
        );
    } else {
        let _ = writeln!(
            md,
            "| figure | causal filter (dual UKF) | smoothed | smoothed / causal | causal IMM (reported) |\n|---|---:|---:|---:|---:|"
        );
    }
    for (name, f, target) in FIELDS {
        let c = median(causal.iter().map(f).collect());
        let s = median(smoothed.iter().map(f).collect());
        let i = median(imm.iter().map(f).collect());
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
        let _ = writeln!(md, " {i:.3e} |");
    }
}

/// The document, from the reference runs over [`SEEDS`] (with their smoothed summaries) and
/// the check seeds' causal and smoothed summaries.
pub(super) fn document(
    dual: &[Reproduction],
    check_dual: &[Reproduction],
    imm: &[Summary],
    check_imm: &[Summary],
) -> Result<String> {
    let causal = |runs: &[Reproduction]| -> Vec<Summary> {
        runs.iter().map(|r| r.summary.clone()).collect()
    };
    let smoothed = |runs: &[Reproduction]| -> Vec<Summary> {
        runs.iter().map(|r| r.smoothed_summary.clone()).collect()
    };
    let mut md = String::new();
    md.push_str(include_str!("smoothing_intro.md"));
    let _ = writeln!(
        md,
        "\n## Reference scenario, seeds 1..20 (medians, without bias)\n"
    );
    table(&mut md, &causal(dual), &smoothed(dual), imm, true);
    let _ = writeln!(
        md,
        "\n## Reference scenario, seeds 21..40 (never used for tuning)\n"
    );
    table(
        &mut md,
        &causal(check_dual),
        &smoothed(check_dual),
        check_imm,
        true,
    );
    let root = workspace_root()?;
    for name in ["l12-step.yaml", "hard-turn.yaml"] {
        eprintln!("dukf-table: smoothing on {name}");
        let spec = ScenarioSpec::load(&root.join("fixtures").join("scenarios").join(name))?;
        let mut dual_config = spec.filter_config();
        dual_config.tuning.design = FilterDesign::Dual;
        let (mut c, mut s, mut i) = (Vec::new(), Vec::new(), Vec::new());
        for seed in SEEDS {
            let run = run_filter(&spec.simulate(seed, false)?, &dual_config)?;
            c.push(run.summary);
            s.push(run.smoothed_summary);
            i.push(spec.reproduce(seed, false)?.summary);
        }
        let _ = writeln!(
            md,
            "\n## `fixtures/scenarios/{name}`, seeds 1..20 (medians, same tuning)\n"
        );
        table(&mut md, &c, &s, &i, false);
    }
    Ok(md)
}
