//! The unscented transform of a nonlinear map: weights and moments checked against closed
//! forms, so `W0_c` (the `beta` term) and `kappa` are exercised, not only the linear case.

use dukf::{Euclidean, UtParams, Weights, unscented_transform};
use nalgebra::{Matrix1, Vector1};
use proptest::prelude::*;

#[test]
fn weights_follow_the_scaled_formulas() {
    // L = 6, a = 0.5, b = 2, kappa = 1: lambda = 0.25 * 7 - 6 = -4.25, L + lambda = 1.75.
    let w = Weights::new(UtParams::new(0.5, 2.0, 1.0), 6).unwrap();
    assert!((w.lambda - -4.25).abs() < 1e-15);
    assert!((w.mean0 - -4.25 / 1.75).abs() < 1e-15);
    assert!((w.cov0 - (-4.25 / 1.75 + 1.0 - 0.25 + 2.0)).abs() < 1e-15);
    assert!((w.other - 1.0 / 3.5).abs() < 1e-15);
    assert!((w.gamma - 1.75f64.sqrt()).abs() < 1e-15);
    // Mean weights sum to one.
    assert!((w.mean0 + 12.0 * w.other - 1.0).abs() < 1e-14);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// For scalar x ~ N(m, s^2) and y = x^2: E[y] = m^2 + s^2 exactly for any parameters, and
    /// the scaled transform's variance is 4 m^2 s^2 + (b + a^2 kappa) s^4 (exact, 2 s^4, at
    /// b = 2, kappa = 0). Derivation: points m +- g s with g^2 = a^2 (1 + kappa).
    #[test]
    fn square_of_a_gaussian(
        m in -3.0..3.0f64,
        s in 0.05..2.0f64,
        a in 0.05..1.0f64,
        b in 0.0..3.0f64,
        kappa in 0.0..3.0f64,
    ) {
        let t = unscented_transform(
            &Vector1::new(m),
            &Matrix1::new(s * s),
            |x| Vector1::new(x[0] * x[0]),
            &Euclidean,
            &Euclidean,
            UtParams::new(a, b, kappa),
        )
        .unwrap();
        let mean = m * m + s * s;
        let var = 4.0 * m * m * s * s + (b + a * a * kappa) * s.powi(4);
        let scale = 1.0 / (a * a); // rounding is amplified by the weights
        prop_assert!((t.mean[0] - mean).abs() < 1e-12 * scale * (1.0 + mean), "{} vs {mean}", t.mean[0]);
        prop_assert!((t.covariance[(0, 0)] - var).abs() < 1e-11 * scale * (1.0 + var), "{} vs {var}", t.covariance[(0, 0)]);
        // Cross-covariance E[(x - m)(y - E y)] = 2 m s^2.
        prop_assert!((t.cross_covariance[(0, 0)] - 2.0 * m * s * s).abs() < 1e-12 * scale * (1.0 + var));
    }
}
