//! Angle handling: wrapping, wrapped residuals and circular means, including across +-pi.

use core::f64::consts::{PI, TAU};

use dukf::{AngleMask, SigmaPoints, Space, UtParams, Weights, circular_mean, wrap_angle};
use nalgebra::{SMatrix, SVector, Vector2};
use proptest::prelude::*;

/// Distance on the circle.
fn circ_dist(a: f64, b: f64) -> f64 {
    wrap_angle(a - b).abs()
}

#[test]
fn wrap_angle_edges() {
    assert_eq!(wrap_angle(PI), PI);
    assert_eq!(wrap_angle(-PI), PI);
    assert_eq!(wrap_angle(0.0), 0.0);
    assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
    assert!((wrap_angle(-3.0 * PI) - PI).abs() < 1e-12);
    assert!((wrap_angle(TAU + 0.5) - 0.5).abs() < 1e-12);
    assert!(wrap_angle(f64::NAN).is_nan());
}

#[test]
fn mean_of_points_straddling_pi_is_pi() {
    let e = 0.1;
    let m = circular_mean(&[(0.5, PI - e), (0.5, -PI + e)]).unwrap();
    assert!(circ_dist(m, PI) < 1e-12, "mean {m}, want pi (not 0)");
    // Unequal weights: 0.75 at pi - e, 0.25 at -pi + e -> pi - e/2.
    let m = circular_mean(&[(0.75, PI - e), (0.25, -PI + e)]).unwrap();
    assert!(circ_dist(m, PI - e / 2.0) < 1e-12, "mean {m}");
}

#[test]
fn circular_mean_rejects_bad_samples() {
    assert_eq!(circular_mean(&[]), None);
    assert_eq!(circular_mean(&[(1.0, f64::NAN)]), None);
    assert_eq!(circular_mean(&[(1.0, 0.0), (-1.0, 1.0)]), None);
}

/// Sigma points of the angle component around the centre `c` with offsets `d_j`.
fn sigma_set(c: f64, plus: [f64; 2], minus: [f64; 2]) -> SigmaPoints<2, 2> {
    // Component 0 is the angle, component 1 a plain value.
    let mut s = SigmaPoints {
        center: Vector2::new(wrap_angle(c), 1.0),
        plus: SMatrix::<f64, 2, 2>::zeros(),
        minus: SMatrix::<f64, 2, 2>::zeros(),
    };
    for j in 0..2 {
        s.plus[(0, j)] = wrap_angle(c + plus[j]);
        s.plus[(1, j)] = 1.0 + plus[j];
        s.minus[(0, j)] = wrap_angle(c + minus[j]);
        s.minus[(1, j)] = 1.0 + minus[j];
    }
    s
}

#[test]
fn angle_mask_mean_of_sigma_points_straddling_pi() {
    let space = AngleMask::new([true, false]);
    let w = Weights::new(UtParams::new(1.0, 2.0, 0.0), 2).unwrap();
    let s = sigma_set(PI, [0.2, 0.1], [-0.2, -0.1]);
    let m = space.weighted_mean(&s, &w);
    assert!(
        circ_dist(m[0], PI) < 1e-12,
        "angle mean {} should be pi",
        m[0]
    );
    assert!((m[1] - 1.0).abs() < 1e-12);
    // The naive mean of the wrapped values would be near 0: show that is what we avoid.
    let naive: f64 = s.weighted(&w).map(|(wi, p)| wi * p[0]).sum();
    assert!(circ_dist(naive, PI) > 1.0);
}

fn angle() -> impl Strategy<Value = f64> {
    -PI..=PI
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn wrapped_values_are_in_half_open_interval(a in -1e4..1e4f64) {
        let w = wrap_angle(a);
        prop_assert!(w > -PI && w <= PI, "wrap({a}) = {w}");
        // Same point on the circle.
        let k = ((a - w) / TAU).round();
        prop_assert!((a - w - k * TAU).abs() < 1e-9 * (1.0 + a.abs()));
    }

    #[test]
    fn residuals_stay_in_half_open_interval(a in -50.0..50.0f64, b in -50.0..50.0f64, l in -10.0..10.0f64) {
        let space = AngleMask::new([true, false]);
        let r = space.residual(&Vector2::new(a, l), &Vector2::new(b, 0.0));
        prop_assert!(r[0] > -PI && r[0] <= PI, "residual {}", r[0]);
        prop_assert!((r[1] - l).abs() < 1e-12);
        // And add undoes it.
        let back = space.add(&Vector2::new(b, 0.0), &r);
        prop_assert!(circ_dist(back[0], a) < 1e-9);
    }

    /// Points spread less than pi/2 either side of any centre (including near +-pi) average
    /// to the centre plus the weighted mean offset, on the circle.
    #[test]
    fn circular_mean_matches_offset_mean(
        c in angle(),
        offsets in prop::collection::vec((0.1..1.0f64, -1.5..1.5f64), 1..8),
    ) {
        let total: f64 = offsets.iter().map(|o| o.0).sum();
        let want = c + offsets.iter().map(|&(w, d)| w * d).sum::<f64>() / total;
        let samples: Vec<(f64, f64)> = offsets.iter().map(|&(w, d)| (w, wrap_angle(c + d))).collect();
        let got = circular_mean(&samples).unwrap();
        prop_assert!(circ_dist(got, want) < 1e-9, "got {got}, want {}", wrap_angle(want));
        prop_assert!(got > -PI && got <= PI);
    }

    /// Samples at pi - e and -pi + e (any mix of weights) average near pi, never near 0.
    #[test]
    fn straddling_samples_average_to_pi(e in 1e-6..0.5f64, w1 in 0.1..1.0f64, w2 in 0.1..1.0f64) {
        let got = circular_mean(&[(w1, PI - e), (w2, -PI + e)]).unwrap();
        let want = PI - e + (w2 / (w1 + w2)) * 2.0 * e;
        prop_assert!(circ_dist(got, want) < 1e-9, "got {got}, want {want}");
        prop_assert!(circ_dist(got, PI) <= e + 1e-12);
    }

    /// The AngleMask mean of a sigma-point set (UKF weights, large and mixed-sign for small
    /// alpha) equals the centre plus the weighted mean offset, and rotating every point
    /// rotates the mean. The points are shaped like real sigma points: `+-gamma u_j` plus a
    /// second-order asymmetry `gamma^2 v_j`, so the mean offset stays O(1) for every alpha.
    #[test]
    fn angle_mask_mean_is_rotation_equivariant(
        c in angle(),
        u in [-1.0..1.0f64, -1.0..1.0f64],
        v in [-0.25..0.25f64, -0.25..0.25f64, -0.25..0.25f64, -0.25..0.25f64],
        alpha in prop_oneof![Just(1e-3), 0.05..1.0f64],
        shift in angle(),
    ) {
        let space = AngleMask::new([true, false]);
        let w = Weights::new(UtParams::new(alpha, 2.0, 0.0), 2).unwrap();
        let g = w.gamma;
        let plus = [g * u[0] + g * g * v[0], g * u[1] + g * g * v[1]];
        let minus = [-g * u[0] + g * g * v[2], -g * u[1] + g * g * v[3]];
        let s = sigma_set(c, plus, minus);
        let offset: f64 = plus.iter().chain(minus.iter()).sum::<f64>() * w.other;
        let m = space.weighted_mean(&s, &w);
        prop_assert!(m[0] > -PI && m[0] <= PI);
        // Rounding of the wrapped points (~1e-16) is multiplied by the weights (~1/alpha^2).
        let tol = 1e-12 * (1.0 + w.other.abs());
        prop_assert!(circ_dist(m[0], c + offset) < tol, "got {}, want {}", m[0], wrap_angle(c + offset));
        let rotated = sigma_set(c + shift, plus, minus);
        let mr = space.weighted_mean(&rotated, &w);
        prop_assert!(circ_dist(mr[0], m[0] + shift) < tol);
    }
}

#[test]
fn angle_mask_from_indices() {
    let mask = AngleMask::<6>::from_indices(&[2, 4, 5]).unwrap();
    assert_eq!(mask.angles(), &[false, false, true, false, true, true]);
    assert!(mask.is_angle(4) && !mask.is_angle(3) && !mask.is_angle(99));
    assert!(matches!(
        AngleMask::<3>::from_indices(&[3]),
        Err(dukf::UkfError::AngleIndexOutOfRange {
            index: 3,
            dimension: 3
        })
    ));
    let x = SVector::<f64, 6>::new(0.0, 0.0, 4.0, 7.0, -4.0, PI);
    let n = mask.normalize(&x);
    assert_eq!(n[3], 7.0);
    assert!((n[2] - (4.0 - TAU)).abs() < 1e-12 && (n[4] - (TAU - 4.0)).abs() < 1e-12 && n[5] == PI);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Widely spread points (some crossing the antipode of the first estimate) take the
    /// iterative path: the result is still a weighted mean on the circle, i.e. the wrapped
    /// residuals from it sum to zero under the weights.
    #[test]
    fn angle_mask_mean_of_wide_sets_is_a_fixed_point(
        c in angle(),
        plus in [-3.0..3.0f64, -3.0..3.0f64],
        minus in [-3.0..3.0f64, -3.0..3.0f64],
    ) {
        let space = AngleMask::new([true, false]);
        // alpha = 1, kappa = 1: all weights positive (W0 = 1/3, Wi = 1/6).
        let w = Weights::new(UtParams::new(1.0, 2.0, 1.0), 2).unwrap();
        let s = sigma_set(c, plus, minus);
        let m = space.weighted_mean(&s, &w)[0];
        let balance: f64 = s.weighted(&w).map(|(wi, p)| wi * wrap_angle(p[0] - m)).sum();
        prop_assert!(balance.abs() < 1e-9, "mean {m}: weighted residuals sum to {balance}");
    }
}
