//! The dual filter: exact against two Kalman filters for a linear model, identifies
//! parameters of a nonlinear one, and coasts through frames without measurements.

use core::f64::consts::PI;

use dukf::{AngleMask, DualUkf, Euclidean, Ukf, UtParams, wrap_angle};
use nalgebra::{Matrix2, Matrix3, SMatrix, SVector, Vector2, Vector3};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn matrix<const R: usize, const C: usize>(
    lo: f64,
    hi: f64,
) -> impl Strategy<Value = SMatrix<f64, R, C>> {
    prop::collection::vec(lo..hi, R * C).prop_map(|v| SMatrix::<f64, R, C>::from_column_slice(&v))
}

fn spd<const N: usize>(s: f64, eps: f64) -> impl Strategy<Value = SMatrix<f64, N, N>> {
    matrix::<N, N>(-s, s)
        .prop_map(move |b| b * b.transpose() + SMatrix::<f64, N, N>::identity() * eps)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// `x' = A x + B w`, `y = H x`: the state filter is a Kalman filter with `w` fixed at its
    /// estimate, and the parameter filter a Kalman filter on the random walk `w` observed
    /// through `g(w) = H (A x^ + B w)`. Three steps, compared after each to 1e-9.
    #[test]
    fn dual_equals_two_kalman_filters_for_a_linear_model(
        a in matrix::<3, 3>(-1.0, 1.0),
        b in matrix::<3, 2>(-1.0, 1.0),
        hm in matrix::<2, 3>(-1.0, 1.0),
        x0 in matrix::<3, 1>(-2.0, 2.0),
        w0 in matrix::<2, 1>(-2.0, 2.0),
        px in spd::<3>(1.0, 0.05),
        pw in spd::<2>(1.0, 0.05),
        q in spd::<3>(0.3, 0.01),
        rr in spd::<2>(0.3, 0.01),
        r in spd::<2>(0.5, 0.01),
        ys in prop::collection::vec(matrix::<2, 1>(-3.0, 3.0), 3),
    ) {
        let params = UtParams::new(0.5, 2.0, 0.0);
        let sx = Ukf::new(x0, px, Euclidean, params).unwrap();
        let sw = Ukf::new(w0, pw, Euclidean, params).unwrap();
        let mut dual = DualUkf::new(sx, sw, q, rr, Euclidean).unwrap();
        let (mut x, mut p, mut w, mut pw) = (x0, px, w0, pw);
        for y in &ys {
            // State Kalman filter with w held at its estimate.
            let xp = a * x + b * w;
            let pp = a * p * a.transpose() + q;
            let s = hm * pp * hm.transpose() + r;
            let k = pp * hm.transpose() * s.try_inverse().unwrap();
            let x_new = xp + k * (y - hm * xp);
            let p_new = pp - k * s * k.transpose();
            // Parameter Kalman filter: random walk, observed through H B w + H A x^_{k-1}.
            let hw = hm * b;
            let pwp = pw + rr;
            let sw = hw * pwp * hw.transpose() + r;
            let kw = pwp * hw.transpose() * sw.try_inverse().unwrap();
            let w_new = w + kw * (y - hm * (a * x + b * w));
            let pw_new = pwp - kw * sw * kw.transpose();
            (x, p, w, pw) = (x_new, p_new, w_new, pw_new);

            dual.step(|xs: &SVector<f64, 3>, ws: &SVector<f64, 2>| a * xs + b * ws, |xs: &SVector<f64, 3>| hm * xs, y, &r)
                .unwrap();
            prop_assert!((dual.state() - x).amax() < 1e-9, "state {} vs {}", dual.state(), x);
            prop_assert!((dual.state_covariance() - p).amax() < 1e-9);
            prop_assert!((dual.parameters() - w).amax() < 1e-9, "params {} vs {}", dual.parameters(), w);
            prop_assert!((dual.parameter_covariance() - pw).amax() < 1e-9);
        }
    }
}

/// A target on a circle: state `[x, y, heading]`, unknown `[speed, turn rate]`, measured
/// by range, bearing (from the origin) and heading with noise. The parameter estimate
/// converges. (The heading must be measured: `g(w) = h(f(x^, w))` looks one step ahead, and
/// one step of turning moves no position, so without it the turn rate is unobservable.)
#[test]
fn dual_identifies_speed_and_turn_rate() {
    let dt = 0.05;
    let (v, w) = (1.2, 0.4);
    let f = |x: &SVector<f64, 3>, p: &Vector2<f64>| {
        SVector::<f64, 3>::new(
            x[0] + dt * p[0] * x[2].cos(),
            x[1] + dt * p[0] * x[2].sin(),
            x[2] + dt * p[1],
        )
    };
    let h = |x: &SVector<f64, 3>| Vector3::new(x[0].hypot(x[1]), x[1].atan2(x[0]), x[2]);
    let mut truth = SVector::<f64, 3>::new(4.0, 0.0, PI / 2.0);
    let state = Ukf::new(
        SVector::<f64, 3>::new(3.8, 0.2, 1.4),
        SMatrix::<f64, 3, 3>::from_diagonal(&SVector::<f64, 3>::new(0.1, 0.1, 0.1)),
        AngleMask::new([false, false, true]),
        UtParams::default(),
    )
    .unwrap();
    let params = Ukf::new(
        Vector2::zeros(),
        Matrix2::identity(),
        Euclidean,
        UtParams::default(),
    )
    .unwrap();
    let mut dual = DualUkf::new(
        state,
        params,
        SMatrix::<f64, 3, 3>::identity() * 1e-6,
        Matrix2::identity() * 1e-6,
        AngleMask::new([false, true, true]),
    )
    .unwrap();
    let r = Matrix3::from_diagonal(&Vector3::new(
        0.02f64.powi(2),
        0.01f64.powi(2),
        0.05f64.powi(2),
    ));
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (nr, nb, nh) = (
        Normal::new(0.0, 0.02).unwrap(),
        Normal::new(0.0, 0.01).unwrap(),
        Normal::new(0.0, 0.05).unwrap(),
    );
    let mut err_late = 0.0;
    let steps = 600; // 30 s, more than one lap of the circle (2 pi / 0.4 = 15.7 s).
    for k in 0..steps {
        truth = f(&truth, &Vector2::new(v, w));
        truth[2] = wrap_angle(truth[2]);
        let m = h(&truth);
        let y = Vector3::new(
            m[0] + nr.sample(&mut rng),
            wrap_angle(m[1] + nb.sample(&mut rng)),
            wrap_angle(m[2] + nh.sample(&mut rng)),
        );
        dual.step(f, h, &y, &r).unwrap();
        if k >= steps - 100 {
            err_late += (dual.state().fixed_rows::<2>(0) - truth.fixed_rows::<2>(0)).norm() / 100.0;
        }
    }
    let est = dual.parameters();
    assert!((est[0] - v).abs() < 0.1, "speed {} vs {v}", est[0]);
    assert!((est[1] - w).abs() < 0.05, "turn rate {} vs {w}", est[1]);
    assert!(
        err_late < 0.05,
        "mean position error over the last 5 s: {err_late}"
    );
    // The heading crossed +-pi several times on the way.
    assert!(wrap_angle(dual.state()[2] - truth[2]).abs() < 0.2);
}

#[test]
fn predict_only_coasts_with_growing_covariance() {
    let state = Ukf::new(
        Vector2::new(0.0, 1.0),
        Matrix2::identity() * 0.01,
        Euclidean,
        UtParams::default(),
    )
    .unwrap();
    let params = Ukf::new(
        Vector2::new(0.5, -0.1),
        Matrix2::identity() * 0.02,
        Euclidean,
        UtParams::default(),
    )
    .unwrap();
    let rr = Matrix2::new(1e-3, 0.0, 0.0, 2e-3);
    // No measurement is ever given, so M must be named.
    let mut dual: DualUkf<2, 2, 1, _, _, _> =
        DualUkf::new(state, params, Matrix2::identity() * 1e-4, rr, Euclidean).unwrap();
    let f =
        |x: &Vector2<f64>, w: &Vector2<f64>| Vector2::new(x[0] + 0.1 * x[1] + w[0], x[1] + w[1]);
    let mut last_trace = dual.state_covariance().trace();
    for k in 1..=10 {
        let before_w = *dual.parameters();
        let before_pw = *dual.parameter_covariance();
        let x_before = *dual.state();
        dual.predict_only(f).unwrap();
        // Parameters keep their mean; their covariance grows by exactly Rr.
        assert_eq!(dual.parameters(), &before_w);
        assert!((dual.parameter_covariance() - (before_pw + rr)).amax() < 1e-15);
        // The state moves by the model with w at its estimate and its covariance grows.
        assert!(
            (dual.state() - f(&x_before, &before_w)).amax() < 1e-12,
            "step {k}"
        );
        let trace = dual.state_covariance().trace();
        assert!(trace > last_trace, "step {k}: {trace} <= {last_trace}");
        last_trace = trace;
    }
}
