//! `wrap_angle`: the same cases in every crate that keeps a copy (`unicycle`, `dukf`), so the
//! copies cannot drift apart.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::f64::consts::{PI, TAU};

use proptest::prelude::*;
use unicycle::wrap_angle;

#[test]
fn edges_and_non_finite_input() {
    assert_eq!(wrap_angle(PI), PI);
    assert_eq!(wrap_angle(-PI), PI);
    assert_eq!(wrap_angle(0.0), 0.0);
    assert_eq!(wrap_angle(-0.0), -0.0);
    assert_eq!(wrap_angle(3.0 * PI), PI);
    assert_eq!(wrap_angle(-3.0 * PI), PI);
    assert!((wrap_angle(TAU + 0.5) - 0.5).abs() < 1e-12);
    assert!((wrap_angle(-TAU - 0.5) + 0.5).abs() < 1e-12);
    assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
    assert!(wrap_angle(f64::NAN).is_nan());
    assert!(wrap_angle(f64::INFINITY).is_nan());
    assert!(wrap_angle(f64::NEG_INFINITY).is_nan());
}

proptest! {
    /// Angles in `(-pi, pi]` come back bit for bit.
    #[test]
    fn in_range_angles_are_unchanged(a in -PI..=PI) {
        prop_assume!(a > -PI);
        prop_assert_eq!(wrap_angle(a).to_bits(), a.to_bits());
    }

    /// The result lies in `(-pi, pi]` and differs from the input by a whole number of turns.
    #[test]
    fn wraps_into_the_half_open_interval(a in -1e4..1e4f64) {
        let w = wrap_angle(a);
        prop_assert!(w > -PI && w <= PI, "{a} -> {w}");
        let turns = (a - w) / TAU;
        prop_assert!((turns - turns.round()).abs() < 1e-9, "{a} -> {w}");
    }
}
