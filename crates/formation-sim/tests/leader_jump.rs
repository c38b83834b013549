//! #30: the IMM's manoeuvre hypothesis J (`unicycle::LeaderJump`) follows a leader whose
//! velocity steps and turn rate flips (`fixtures/scenarios/abrupt-leader.yaml`, the follower
//! on its estimate), where the reference model set, sized for smooth motion, lags and is
//! overconfident.

#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

use formation_sim::scenario_file::ScenarioSpec;
use nalgebra::Vector2;
use unicycle::LeaderJump;

#[test]
fn the_jump_hypothesis_follows_an_abrupt_leader() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenarios/abrupt-leader.yaml"
    );
    let spec = ScenarioSpec::load(std::path::Path::new(path)).unwrap();
    let reference = spec.filter_config();
    let mut jump = reference.clone();
    jump.tuning.imm.jump = Some(LeaderJump {
        velocity_std: Vector2::new(0.05, 0.1),
        sojourn: 0.2,
        onset: 10.0,
    });
    // Seeds the held-out table does not use (docs/dukf-held-out.md: 1..20 and 101..120).
    let mut runs = 0;
    for seed in 201..=203 {
        let (_, without) = spec.run(seed, false, &reference, false).unwrap();
        let (_, with) = spec.run(seed, false, &jump, false).unwrap();
        let (a, b) = (&without.summary, &with.summary);
        assert!(
            b.mse.alpha12 < 0.5 * a.mse.alpha12,
            "seed {seed}: alpha12 {:.3e} with J, {:.3e} without",
            b.mse.alpha12,
            a.mse.alpha12
        );
        assert!(
            b.rms_w1_after_2s < a.rms_w1_after_2s,
            "seed {seed}: w1 {} with J, {} without",
            b.rms_w1_after_2s,
            a.rms_w1_after_2s
        );
        // Less overconfident: the formation NEES averaged over the run falls.
        let nees = |r: &formation_sim::reproduce::Reproduction| {
            r.consistency.iter().map(|c| c.nees_formation).sum::<f64>() / r.consistency.len() as f64
        };
        assert!(
            nees(&with) < 0.6 * nees(&without),
            "seed {seed}: NEES {} with J, {} without",
            nees(&with),
            nees(&without)
        );
        runs += 1;
    }
    assert_eq!(runs, 3);
}
