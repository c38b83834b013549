//! Issue #30: drive the default filter into model mismatch and check that it notices.
//!
//! The reference scenario with the follower's controller on the filter's estimate (as on a
//! robot), its wheels executing 0.9 of the commanded speed with white noise of 0.03 m/s and
//! 0.03 rad/s, and its odometry reporting what they executed with 0.01 m/s and 0.01 rad/s of
//! noise. The IMM is told the follower's controller, so its model B assumes that the
//! formation moves as the controller commands, which a 10 % slow wheel breaks.
//!
//! How the filter notices, per held-out seed, one of two ways:
//! - the IMM's probability of model B, a running likelihood-ratio test of B's innovations
//!   against model A's (an accelerating leader, which assumes nothing of the follower's
//!   controller): with exact wheels B keeps a quarter or more of the probability after 2 s,
//!   with the slow wheel it falls below 0.15 and below half that (seeds 101, 102: 0.32 ->
//!   0.06, 0.43 -> 0.05; `FormationFilter::model_probabilities`). A robot has this test;
//! - or, where B was weak already with exact wheels (seed 103: 0.15 -> 0.10), the formation
//!   NEES leaves its 95 % band (4.16 against a top of 3.36), which only a simulation sees.
//!
//! Its `l12` estimate stays within 2x the error of a random walk tuned on other seeds (seeds
//! 101, 102: 5.4e-4 against 6.0e-4).

#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use formation_sim::reproduce::{
    Baseline, ClosedLoop, Reproduction, baseline, paper_filter_config, run_closed_loop,
};
use formation_sim::scenario::{
    Control, PAPER_X0, Scenario, ScenarioConfig, Simulation, reference_leader_inputs,
};
use unicycle::Actuation;

/// The scenario with wheels at `scale` of the commanded speed, on seed `seed`.
fn config(seed: u64, scale: f64) -> ScenarioConfig {
    let mut config = ScenarioConfig::reference(seed).with_control(Control::Estimate);
    config.actuation = Actuation {
        scale: [scale, 1.0],
        noise_std: [0.03, 0.03],
    };
    config.odometry_noise_std = [0.01, 0.01];
    config
}

fn run(seed: u64, scale: f64) -> (Scenario, Reproduction) {
    let config = config(seed, scale);
    let simulation = Simulation::new(&config, reference_leader_inputs, &[]).unwrap();
    let filter = paper_filter_config(config.d, config.dt);
    run_closed_loop(simulation, &filter, true).unwrap()
}

/// The mean probability of model B (the follower's controller holds) over the frames after
/// 2 s, as the filter reports it after each frame.
fn model_b_after_2s(seed: u64, scale: f64) -> f64 {
    let config = config(seed, scale);
    let simulation = Simulation::new(&config, reference_leader_inputs, &[]).unwrap();
    let filter = paper_filter_config(config.d, config.dt);
    let mut run = ClosedLoop::new(simulation, &filter, true, false).unwrap();
    let mut b = Vec::new();
    while let Some(step) = run.next() {
        let (sample, _) = step.unwrap();
        if sample.t > 2.0 {
            b.push(run.run().filter().model_probabilities().unwrap()[1]);
        }
    }
    b.iter().sum::<f64>() / b.len() as f64
}

/// Mean formation NEES over the frames after 2 s, and how many frames.
fn nees_after_2s(r: &Reproduction) -> (f64, usize) {
    let after: Vec<f64> = r
        .records
        .iter()
        .zip(&r.consistency)
        .filter(|(rec, _)| rec.t > 2.0)
        .map(|(_, c)| c.nees_formation)
        .collect();
    (after.iter().sum::<f64>() / after.len() as f64, after.len())
}

fn x0() -> [f64; 3] {
    [PAPER_X0[3], PAPER_X0[4], PAPER_X0[5]]
}

#[test]
fn a_slow_wheel_is_noticed_and_the_estimate_stays_within_twice_a_random_walk() {
    // The random walk's q for l12, chosen on seeds 1..3 from the documented grid (1e-10..1,
    // half decades), then used on seeds 101..103.
    let grid: Vec<f64> = (0..=20)
        .map(|k| 10f64.powf(-10.0 + 0.5 * f64::from(k)))
        .collect();
    let tuning: Vec<Scenario> = (1..=3).map(|s| run(s, 0.9).0).collect();
    let score = |q: f64| -> f64 {
        tuning
            .iter()
            .map(|s| baseline(s, &x0(), Baseline::RandomWalk { q })[0])
            .sum()
    };
    let q = grid
        .iter()
        .copied()
        .min_by(|a, b| score(*a).total_cmp(&score(*b)))
        .unwrap();
    let mut noticed = Vec::new();
    for seed in 101..=103 {
        let (scenario, filtered) = run(seed, 0.9);
        let (nees, n) = nees_after_2s(&filtered);
        // The mean of n chi-square(3) draws: 3 +- 1.96 sqrt(6 / n) holds 95 % of consistent
        // runs.
        let upper = 3.0 + 1.96 * (6.0 / n as f64).sqrt();
        let by_nees = nees > upper;
        // What the robot has: model B's probability, a likelihood-ratio test on innovations.
        let (exact, slow) = (model_b_after_2s(seed, 1.0), model_b_after_2s(seed, 0.9));
        let by_model_b = exact > 0.25 && slow < 0.15 && slow < 0.5 * exact;
        assert!(
            by_nees || by_model_b,
            "seed {seed}: not noticed: NEES {nees:.2} (band top {upper:.2}), model B's \
             probability {exact:.3} with exact wheels, {slow:.3} slow"
        );
        noticed.push((by_nees, by_model_b));
        let walk = baseline(&scenario, &x0(), Baseline::RandomWalk { q })[0];
        let ours = filtered.summary.mse.l12;
        assert!(
            ours <= 2.0 * walk,
            "seed {seed}: l12 MSE {ours:.3e} against the random walk's {walk:.3e} (q {q:e})"
        );
    }
    // Both tests did some of the noticing (seeds 101 and 102 by model B, 103 by NEES): the
    // assertion above is not carried by one of them alone.
    assert!(
        noticed.iter().any(|n| n.0) && noticed.iter().any(|n| n.1),
        "{noticed:?}"
    );
}
