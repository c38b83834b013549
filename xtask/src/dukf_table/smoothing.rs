//! `docs/smoothing.md`: the offline smoother against the causal filter (IMM) on the reference
//! scenario (seeds 1..20 and the never-tuned 21..40) and the scenario fixtures. Written by
//! `cargo xtask dukf-table` from the same runs as `docs/dukf-reproduction.md`.

use std::fmt::Write as _;

use formation_sim::reproduce::{Reproduction, Summary};
use formation_sim::scenario_file::ScenarioSpec;

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

fn table(md: &mut String, causal: &[Summary], smoothed: &[Summary], targets: bool) {
    if targets {
        let _ = writeln!(
            md,
            "| figure | causal filter (IMM) | smoothed | smoothed / causal | target | result |\n\
             |---|---:|---:|---:|---|---|"
        );
    } else {
        let _ = writeln!(
            md,
            "| figure | causal filter (IMM) | smoothed | smoothed / causal |\n|---|---:|---:|---:|"
        );
    }
    for (name, f, target) in FIELDS {
        let c = median(causal.iter().map(f).collect());
        let s = median(smoothed.iter().map(f).collect());
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
        let _ = writeln!(md);
    }
}

/// The document, from the reference runs over [`SEEDS`] (with their smoothed summaries) and
/// the check seeds' causal and smoothed summaries.
pub(super) fn document(
    runs: &[Reproduction],
    check_smoothed: &[Summary],
    check: &[Summary],
) -> Result<String> {
    let causal: Vec<Summary> = runs.iter().map(|r| r.summary.clone()).collect();
    let smoothed: Vec<Summary> = runs.iter().map(|r| r.smoothed_summary.clone()).collect();
    let mut md = String::new();
    md.push_str(include_str!("smoothing_intro.md"));
    let _ = writeln!(
        md,
        "\n## Reference scenario, seeds 1..20 (medians, without bias)\n"
    );
    table(&mut md, &causal, &smoothed, true);
    let _ = writeln!(
        md,
        "\n## Reference scenario, seeds 21..40 (never used for tuning)\n"
    );
    table(&mut md, check, check_smoothed, true);
    let root = workspace_root()?;
    for name in ["l12-step.yaml", "hard-turn.yaml"] {
        eprintln!("dukf-table: smoothing on {name}");
        let spec = ScenarioSpec::load(&root.join("fixtures").join("scenarios").join(name))?;
        let (mut c, mut s) = (Vec::new(), Vec::new());
        for seed in SEEDS {
            let run = spec.reproduce(seed, false)?;
            c.push(run.summary);
            s.push(run.smoothed_summary);
        }
        let _ = writeln!(
            md,
            "\n## `fixtures/scenarios/{name}`, seeds 1..20 (medians, same tuning)\n"
        );
        table(&mut md, &c, &s, false);
    }
    Ok(md)
}
