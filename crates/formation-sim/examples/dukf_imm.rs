//! Issue #15: the IMM design of `FormationFilter` (the default) against the baselines and the
//! dual UKF on the reference scenario and the fixtures, medians over a range of seeds.
//!
//! ```text
//! cargo run -p formation-sim --example dukf_imm [-- FIRST LAST]   (seeds, default 1 20)
//! ```
//! Environment overrides of the IMM tuning (for the measurements of
//! `docs/dukf-reproduction.md`): `JERK`, `SOJOURN`, `HELD` (held-rate std), `MU0`, `FQ`
//! (formation q), `CFQ` (formation q of model B with the controller known), `UT_ALPHA`,
//! `DESIGN=dual`, `FOLLOWER=0` (do not tell the IMM the follower's controller: the model set of
//! measurements 9-10; it is told by default, as in `reproduce dukf`).
#![allow(clippy::unwrap_used)]

use formation_filter::{FilterConfig, FilterDesign};
use formation_sim::reproduce::{Baseline, Reproduction, baseline, run_filter_with};
use formation_sim::scenario::{Scenario, ScenarioConfig, simulate};
use formation_sim::scenario_file::ScenarioSpec;

#[path = "common/median.rs"]
mod median;
use median::median;

#[path = "common/imm_tuning.rs"]
mod imm_tuning;

/// The IMM knobs of the environment, and `DESIGN=dual` for the dual UKF.
fn tune(cfg: &mut FilterConfig) {
    imm_tuning::tune(cfg);
    if std::env::var("DESIGN").is_ok_and(|d| d == "dual") {
        cfg.tuning.design = FilterDesign::Dual;
    }
}

fn mean_after_2s(
    run: &Reproduction,
    f: impl Fn(&formation_sim::reproduce::StepConsistency) -> f64,
) -> f64 {
    let v: Vec<f64> = run
        .records
        .iter()
        .zip(&run.consistency)
        .filter(|(r, _)| r.t > 2.0)
        .map(|(_, c)| f(c))
        .collect();
    v.iter().sum::<f64>() / v.len() as f64
}

fn report(label: &str, runs: &[(Scenario, FilterConfig)]) {
    let mut rows = vec![];
    let (mut rw, mut cv) = (vec![], vec![]);
    for (s, cfg) in runs {
        let run =
            run_filter_with(s, cfg, std::env::var("FOLLOWER").map_or(true, |v| v != "0")).unwrap();
        let x0 = [cfg.x0[3], cfg.x0[4], cfg.x0[5]];
        rw.push(baseline(s, &x0, Baseline::RANDOM_WALK));
        cv.push(baseline(s, &x0, Baseline::CONSTANT_VELOCITY));
        rows.push([
            run.summary.mse.l12,
            run.summary.mse.alpha12,
            run.summary.mse.beta12,
            run.summary.rms_v1_after_2s,
            run.summary.rms_w1_after_2s,
            mean_after_2s(&run, |c| c.nis),
            mean_after_2s(&run, |c| c.nees_formation),
            mean_after_2s(&run, |c| c.nees_velocity),
        ]);
    }
    let m = |i: usize| median(rows.iter().map(|r| r[i]).collect());
    let b = |v: &[[f64; 3]], i: usize| median(v.iter().map(|r| r[i]).collect());
    println!(
        "{label:<22} l12 {:.3e} ({:.2}x RW {:.3e}, CV {:.3e}) alpha12 {:.3e} ({:.2}x RW {:.3e}, CV {:.3e}) beta12 {:.3e} (RW {:.3e}, CV {:.3e}) | rms v1 {:.4} w1 {:.4} | NIS {:.2} NEESf {:.2} NEESv {:.2}",
        m(0),
        m(0) / b(&rw, 0).min(b(&cv, 0)),
        b(&rw, 0),
        b(&cv, 0),
        m(1),
        m(1) / b(&rw, 1).min(b(&cv, 1)),
        b(&rw, 1),
        b(&cv, 1),
        m(2),
        b(&rw, 2),
        b(&cv, 2),
        m(3),
        m(4),
        m(5),
        m(6),
        m(7)
    );
}

fn main() {
    let args: Vec<u64> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let (lo, hi) = (
        args.first().copied().unwrap_or(1),
        args.get(1).copied().unwrap_or(20),
    );
    let reference: Vec<(Scenario, FilterConfig)> = (lo..=hi)
        .map(|seed| {
            let c = ScenarioConfig::reference(seed);
            let mut cfg = formation_sim::reproduce::paper_filter_config(c.d, c.dt);
            tune(&mut cfg);
            (simulate(&c).unwrap(), cfg)
        })
        .collect();
    report("reference", &reference);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenarios");
    for name in ["l12-step.yaml", "hard-turn.yaml"] {
        let spec = ScenarioSpec::load(&root.join(name)).unwrap();
        let runs: Vec<(Scenario, FilterConfig)> = (lo..=hi)
            .map(|seed| {
                let mut cfg = spec.filter_config();
                tune(&mut cfg);
                (spec.simulate(seed, false).unwrap(), cfg)
            })
            .collect();
        report(name, &runs);
    }
}
