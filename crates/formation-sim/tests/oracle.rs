//! The held-out table's oracle (issue #30): the default filter handed the leader's true
//! inputs before every step. Knowing more, it must track the leader's velocities and the
//! formation better than the same filter without them, on every seed.

#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use formation_sim::reproduce::ClosedLoop;
use formation_sim::scenario_file::ScenarioSpec;

#[test]
fn handed_the_leaders_inputs_the_filter_knows_its_velocities() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenarios");
    let spec = ScenarioSpec::load(&root.join("reference-actuation.yaml")).unwrap();
    let config = spec.filter_config();
    for seed in [101, 102] {
        let run = |oracle: bool| {
            let simulation = spec.simulation(seed, false).unwrap();
            let mut l = ClosedLoop::new(simulation, &config, true, true).unwrap();
            if oracle {
                l = l.oracle();
            }
            l.collect_run().unwrap().1.summary
        };
        let (plain, oracle) = (run(false), run(true));
        // Pinned to the truth: velocity errors are the pinned variance's, not the filter's.
        assert!(
            oracle.rms_v1_after_2s < 0.01 && oracle.rms_w1_after_2s < 0.01,
            "seed {seed}: oracle velocity errors {} m/s, {} rad/s",
            oracle.rms_v1_after_2s,
            oracle.rms_w1_after_2s
        );
        assert!(plain.rms_v1_after_2s > 2.0 * oracle.rms_v1_after_2s);
        assert!(
            oracle.mse.l12 < plain.mse.l12,
            "seed {seed}: l12 {} oracle, {} plain",
            oracle.mse.l12,
            plain.mse.l12
        );
    }
}
