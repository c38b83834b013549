//! Scenario files (YAML or JSON, `formation_sim::scenario_file::ScenarioSpec`): never a
//! panic, and an accepted scenario has a positive frame rate and duration and finite leader
//! inputs over its whole run.

use std::path::Path;

use formation_sim::scenario_file::ScenarioSpec;

/// Parses `data` as a scenario file (YAML when the first byte is even, else JSON).
pub fn run(data: &[u8]) {
    let json = data.first().is_some_and(|b| b % 2 == 1);
    let text = String::from_utf8_lossy(data.get(1..).unwrap_or_default());
    let Ok(spec) = ScenarioSpec::parse(&text, json, Path::new("fuzz.yaml")) else {
        return;
    };
    assert!(spec.frame_rate.is_finite() && spec.frame_rate > 0.0);
    assert!(spec.duration.is_finite() && spec.duration > 0.0);
    for k in 0..=16 {
        let t = spec.duration * f64::from(k) / 16.0;
        let u = spec.leader_inputs(t);
        assert!(
            u.v.is_finite() && u.w.is_finite(),
            "leader inputs at t = {t}: {u:?}"
        );
    }
}
