//! For linear models the UKF must be the linear Kalman filter, and the unscented transform
//! of a linear map must be exact.

use dukf::{Euclidean, Ukf, UtParams, unscented_transform};
use nalgebra::{SMatrix, SVector};
use proptest::prelude::*;

/// The bound for `alpha >= 1e-2`. Rounding in `f` (about `eps |f|`) reaches the mean through
/// the weights `1 / (2 alpha^2 (L + kappa))`, so for smaller alpha the agreement degrades as
/// `1 / alpha^2` (see `small_alpha_degrades_as_inverse_alpha_squared`).
const TOL: f64 = 1e-9;

fn matrix<const R: usize, const C: usize>(
    lo: f64,
    hi: f64,
) -> impl Strategy<Value = SMatrix<f64, R, C>> {
    prop::collection::vec(lo..hi, R * C).prop_map(|v| SMatrix::<f64, R, C>::from_column_slice(&v))
}

fn vector<const R: usize>(lo: f64, hi: f64) -> impl Strategy<Value = SVector<f64, R>> {
    matrix::<R, 1>(lo, hi)
}

/// A random symmetric positive definite matrix `B B^T + eps I`, with scale up to ~`N * s^2`.
fn spd<const N: usize>(s: f64, eps: f64) -> impl Strategy<Value = SMatrix<f64, N, N>> {
    matrix::<N, N>(-s, s)
        .prop_map(move |b| b * b.transpose() + SMatrix::<f64, N, N>::identity() * eps)
}

fn params() -> impl Strategy<Value = UtParams> {
    (
        prop_oneof![Just(1e-2), Just(UtParams::default().alpha), 1e-2..1.0f64],
        0.0..3.0f64,
        0.0..3.0f64,
    )
        .prop_map(|(a, b, k)| UtParams::new(a, b, k))
}

fn assert_close<const R: usize, const C: usize>(
    what: &str,
    got: &SMatrix<f64, R, C>,
    want: &SMatrix<f64, R, C>,
) -> Result<(), TestCaseError> {
    assert_within(what, got, want, TOL)
}

fn assert_within<const R: usize, const C: usize>(
    what: &str,
    got: &SMatrix<f64, R, C>,
    want: &SMatrix<f64, R, C>,
    tol: f64,
) -> Result<(), TestCaseError> {
    let err = (got - want).amax();
    prop_assert!(
        err <= tol,
        "{what}: max abs error {err:e}\n got {got}\n want {want}"
    );
    Ok(())
}

#[derive(Debug, Clone)]
struct LinearCase<const N: usize, const M: usize> {
    x: SVector<f64, N>,
    p: SMatrix<f64, N, N>,
    a: SMatrix<f64, N, N>,
    q: SMatrix<f64, N, N>,
    h: SMatrix<f64, M, N>,
    r: SMatrix<f64, M, M>,
    y: SVector<f64, M>,
    params: UtParams,
}

fn linear_case<const N: usize, const M: usize>() -> impl Strategy<Value = LinearCase<N, M>> {
    (
        vector::<N>(-5.0, 5.0),
        spd::<N>(1.0, 0.05),
        matrix::<N, N>(-1.5, 1.5),
        spd::<N>(0.5, 0.01),
        matrix::<M, N>(-2.0, 2.0),
        spd::<M>(0.5, 0.01),
        vector::<M>(-5.0, 5.0),
        params(),
    )
        .prop_map(|(x, p, a, q, h, r, y, params)| LinearCase {
            x,
            p,
            a,
            q,
            h,
            r,
            y,
            params,
        })
}

/// Runs predict then update in both filters and compares after each.
fn check_linear<const N: usize, const M: usize>(c: &LinearCase<N, M>) -> Result<(), TestCaseError> {
    let mut ukf = Ukf::new(c.x, c.p, Euclidean, c.params).expect("valid case");
    prop_assert_eq!(ukf.initial_jitter(), 0.0);

    // Kalman filter prediction.
    let x_pred = c.a * c.x;
    let p_pred = c.a * c.p * c.a.transpose() + c.q;
    let pr = ukf.predict(|x| c.a * x, &c.q).expect("predict");
    prop_assert_eq!(pr.jitter, 0.0);
    assert_close("predicted mean", ukf.state(), &x_pred)?;
    assert_close("predicted covariance", ukf.covariance(), &p_pred)?;

    // Kalman filter update.
    let s = c.h * p_pred * c.h.transpose() + c.r;
    let s_inv = s.try_inverse().expect("S is SPD");
    let k = p_pred * c.h.transpose() * s_inv;
    let nu = c.y - c.h * x_pred;
    let x_upd = x_pred + k * nu;
    let p_upd = (SMatrix::<f64, N, N>::identity() - k * c.h) * p_pred;
    let ur = ukf
        .update(&c.y, |x| c.h * x, &c.r, &Euclidean)
        .expect("update");
    assert_close("innovation", &ur.innovation, &nu)?;
    assert_close("innovation covariance", &ur.innovation_covariance, &s)?;
    let nis = (nu.transpose() * s_inv * nu)[(0, 0)];
    prop_assert!(
        (ur.nis - nis).abs() <= TOL * (1.0 + nis),
        "nis {} vs {}",
        ur.nis,
        nis
    );
    assert_close("updated mean", ukf.state(), &x_upd)?;
    assert_close("updated covariance", ukf.covariance(), &p_upd)?;
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn ukf_equals_kalman_filter_4x2(c in linear_case::<4, 2>()) {
        check_linear(&c)?;
    }

    #[test]
    fn ukf_equals_kalman_filter_6x3(c in linear_case::<6, 3>()) {
        check_linear(&c)?;
    }

    #[test]
    fn unscented_transform_of_linear_map_is_exact(
        x in vector::<5>(-5.0, 5.0),
        p in spd::<5>(1.0, 0.05),
        a in matrix::<3, 5>(-2.0, 2.0),
        b in vector::<3>(-3.0, 3.0),
        params in params(),
    ) {
        let t = unscented_transform(&x, &p, |v| a * v + b, &Euclidean, &Euclidean, params)
            .expect("valid transform");
        assert_close("mean", &t.mean, &(a * x + b))?;
        assert_close("covariance", &t.covariance, &(a * p * a.transpose()))?;
        assert_close("cross-covariance", &t.cross_covariance, &(p * a.transpose()))?;
    }

    /// With alpha = 1e-3 the sigma points are 1e-3 sigma apart and the weights ~1e5, so the
    /// transform is still exact in exact arithmetic but rounding is amplified ~1e4 times
    /// more than at alpha = 0.1: the agreement is 1e-7, not 1e-9.
    #[test]
    fn small_alpha_degrades_as_inverse_alpha_squared(
        x in vector::<5>(-5.0, 5.0),
        p in spd::<5>(1.0, 0.05),
        a in matrix::<3, 5>(-2.0, 2.0),
    ) {
        let params = UtParams::new(1e-3, 2.0, 0.0);
        let t = unscented_transform(&x, &p, |v| a * v, &Euclidean, &Euclidean, params)
            .expect("valid transform");
        assert_within("mean", &t.mean, &(a * x), 1e-7)?;
        assert_within("covariance", &t.covariance, &(a * p * a.transpose()), 1e-7)?;
    }
}

/// Several predict/update cycles keep matching (errors do not accumulate past the bound).
#[test]
fn ukf_tracks_kalman_filter_over_many_steps() {
    let a = SMatrix::<f64, 2, 2>::new(1.0, 0.1, 0.0, 1.0);
    let h = SMatrix::<f64, 1, 2>::new(1.0, 0.0);
    let q = SMatrix::<f64, 2, 2>::new(1e-4, 0.0, 0.0, 1e-3);
    let r = SMatrix::<f64, 1, 1>::new(0.05);
    let mut x = SVector::<f64, 2>::new(0.0, 1.0);
    let mut p = SMatrix::<f64, 2, 2>::identity();
    let mut ukf = Ukf::new(x, p, Euclidean, UtParams::default()).unwrap();
    for k in 0..200 {
        let y = SVector::<f64, 1>::new((f64::from(k) * 0.37).sin());
        x = a * x;
        p = a * p * a.transpose() + q;
        let s = h * p * h.transpose() + r;
        let kg = p * h.transpose() * s.try_inverse().unwrap();
        x += kg * (y - h * x);
        p = (SMatrix::<f64, 2, 2>::identity() - kg * h) * p;
        ukf.predict(|v| a * v, &q).unwrap();
        ukf.update(&y, |v| h * v, &r, &Euclidean).unwrap();
        assert!(
            (ukf.state() - x).amax() < TOL,
            "step {k}: {} vs {x}",
            ukf.state()
        );
        assert!((ukf.covariance() - p).amax() < TOL, "step {k}");
    }
}
