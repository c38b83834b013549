//! The IMM tuning knobs the diagnostic examples (`dukf_imm_probe`, `dukf_nees_probe`) read
//! from the environment, so a sweep needs no rebuild: `JERK`, `SOJOURN`, `HELD`, `MU0`,
//! `FQ`, `CFQ`, `UT_ALPHA` (see `FilterTuning`'s fields). Unset or unparsable variables
//! leave the reference tuning.

use formation_filter::{FilterConfig, FilterDesign};
use nalgebra::{Vector2, Vector3};

/// The variable `name` as a number, if set and parsable.
pub fn env(name: &str) -> Option<f64> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

/// Sets the IMM design and every knob given in the environment.
pub fn tune(cfg: &mut FilterConfig) {
    let t = &mut cfg.tuning;
    t.design = FilterDesign::Imm;
    if let Some(j) = env("JERK") {
        t.imm.jerk = Vector2::new(j, j);
    }
    if let Some(s) = env("SOJOURN") {
        t.imm.sojourn = s;
    }
    if let Some(h) = env("HELD") {
        t.imm.held_rate_std = Vector2::new(h, h);
    }
    if let Some(m) = env("MU0") {
        t.imm.mu0_a = m;
    }
    if let Some(q) = env("FQ") {
        t.imm.formation_q = Vector3::new(q, q, q);
    }
    if let Some(q) = env("CFQ") {
        t.imm.controlled_formation_q = Vector3::new(q, q, q);
    }
    if let Some(a) = env("UT_ALPHA") {
        t.ut.alpha = a;
    }
}
