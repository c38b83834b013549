//! The filter with angles: it must behave exactly like a Euclidean filter on the unwrapped
//! problem, wherever on the circle the estimate is (in particular across +-pi).

use core::f64::consts::PI;

use dukf::{AngleMask, Euclidean, Ukf, UtParams, wrap_angle};
use nalgebra::{Matrix2, Vector2};
use proptest::prelude::*;

/// A 2-state model: heading `theta` (an angle) and turn rate `r`.
/// `theta' = theta + dt r + 0.05 sin(theta)`, periodic in theta, so it commutes with wrapping.
fn f(x: &Vector2<f64>) -> Vector2<f64> {
    Vector2::new(x[0] + 0.1 * x[1] + 0.05 * x[0].sin(), 0.98 * x[1])
}

/// Measures the heading and a nonlinear function of it and the rate.
fn h(x: &Vector2<f64>) -> Vector2<f64> {
    Vector2::new(x[0], x[1] + 0.2 * x[0].cos())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Starting anywhere (unwrapped, possibly many turns away), with measurements on either
    /// side of the wrap, the AngleMask filter equals the Euclidean filter run on unwrapped
    /// numbers, modulo 2 pi, after every predict and update.
    #[test]
    fn angle_filter_equals_unwrapped_euclidean_filter(
        theta0 in -12.0..12.0f64,
        rate0 in -2.0..2.0f64,
        var in 0.001..0.2f64,
        offsets in prop::collection::vec((-0.3..0.3f64, -0.3..0.3f64), 1..12),
        alpha in 0.05..1.0f64,
    ) {
        let params = UtParams::new(alpha, 2.0, 0.0);
        let p0 = Matrix2::new(var, 0.3 * var, 0.3 * var, var);
        let q = Matrix2::new(1e-3, 0.0, 0.0, 1e-2);
        let r = Matrix2::new(0.01, 0.0, 0.0, 0.05);
        let state_space = AngleMask::new([true, false]);
        let meas_space = AngleMask::new([true, false]);
        let x0 = Vector2::new(theta0, rate0);
        let mut euclid = Ukf::new(x0, p0, Euclidean, params).unwrap();
        let mut angled = Ukf::new(x0, p0, state_space, params).unwrap();
        prop_assert!(angled.state()[0] > -PI && angled.state()[0] <= PI);
        for (k, (a, b)) in offsets.into_iter().enumerate() {
            euclid.predict(f, &q).unwrap();
            angled.predict(f, &q).unwrap();
            // A measurement near the Euclidean prediction, given unwrapped to one filter and
            // wrapped to the other.
            let y = h(euclid.state()) + Vector2::new(a, b);
            euclid.update(&y, h, &r, &Euclidean).unwrap();
            angled.update(&Vector2::new(wrap_angle(y[0]), y[1]), h, &r, &meas_space).unwrap();
            let (e, g) = (euclid.state(), angled.state());
            prop_assert!(g[0] > -PI && g[0] <= PI, "step {k}: heading {} not wrapped", g[0]);
            prop_assert!(wrap_angle(e[0] - g[0]).abs() < 1e-9, "step {k}: heading {} vs {}", g[0], e[0]);
            prop_assert!((e[1] - g[1]).abs() < 1e-9, "step {k}: rate {} vs {}", g[1], e[1]);
            prop_assert!((euclid.covariance() - angled.covariance()).amax() < 1e-9, "step {k}");
        }
    }
}

/// The concrete case from the spec: estimate just below pi, measurement just above -pi.
/// The innovation is the short way round (+0.1), not -2 pi + 0.1, and the estimate moves
/// across the wrap.
#[test]
fn update_across_the_wrap_takes_the_short_way() {
    let space = AngleMask::new([true, false]);
    let mut ukf = Ukf::new(
        Vector2::new(PI - 0.05, 0.0),
        Matrix2::identity() * 0.01,
        space,
        UtParams::default(),
    )
    .unwrap();
    let y = Vector2::new(-PI + 0.05, 0.0);
    let report = ukf
        .update(&y, |x| *x, &(Matrix2::identity() * 0.01), &space)
        .unwrap();
    assert!(
        (report.innovation[0] - 0.1).abs() < 1e-12,
        "innovation {}",
        report.innovation[0]
    );
    // Equal variances: the posterior is halfway, at pi exactly (which wraps to pi).
    assert!(
        wrap_angle(ukf.state()[0] - PI).abs() < 1e-12,
        "state {}",
        ukf.state()[0]
    );
    assert!((ukf.covariance()[(0, 0)] - 0.005).abs() < 1e-12);
}

/// Predict-only frames: the covariance grows by Q (plus the model's spread) every frame.
#[test]
fn predict_only_grows_the_covariance() {
    let mut ukf = Ukf::new(
        Vector2::new(0.3, 0.1),
        Matrix2::identity() * 0.01,
        AngleMask::new([true, false]),
        UtParams::default(),
    )
    .unwrap();
    let q = Matrix2::new(1e-3, 0.0, 0.0, 1e-3);
    let mut last = *ukf.covariance();
    for k in 0..30 {
        ukf.predict(f, &q).unwrap();
        let p = *ukf.covariance();
        // P_k - P_{k-1} - Q is not required to be PSD for a contracting model, but the
        // diagonal must grow here (the rate is barely damped, theta integrates it).
        assert!(
            p[(0, 0)] > last[(0, 0)],
            "frame {k}: {} <= {}",
            p[(0, 0)],
            last[(0, 0)]
        );
        assert!(p.symmetric_eigenvalues().min() > 0.0);
        last = p;
    }
}
