//! The unscented RTS smoother: on linear-Gaussian models it must be the textbook linear RTS
//! smoother; across the `pi` seam it must agree with the same smoother on unwrapped angles;
//! bad histories are typed errors.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use dukf::{
    AngleMask, Euclidean, Gaussian, RtsSmoother, Ukf, UkfError, UtParams, filter_and_smooth,
    wrap_angle,
};
use nalgebra::{Matrix1, Matrix2, SMatrix, SVector, Vector1, Vector2};
use proptest::prelude::*;

const N: usize = 3;
const M: usize = 2;
type Mn = SMatrix<f64, N, N>;
type Vn = SVector<f64, N>;
/// A mean and covariance per step.
type Moments = Vec<(Vn, Mn)>;

fn matrix<const R: usize, const C: usize>(
    lo: f64,
    hi: f64,
) -> impl Strategy<Value = SMatrix<f64, R, C>> {
    prop::collection::vec(lo..hi, R * C).prop_map(|v| SMatrix::<f64, R, C>::from_column_slice(&v))
}

fn spd<const D: usize>(s: f64, eps: f64) -> impl Strategy<Value = SMatrix<f64, D, D>> {
    matrix::<D, D>(-s, s)
        .prop_map(move |b| b * b.transpose() + SMatrix::<f64, D, D>::identity() * eps)
}

#[derive(Debug, Clone)]
struct Case {
    x0: Vn,
    p0: Mn,
    a: Mn,
    q: Mn,
    h: SMatrix<f64, M, N>,
    r: SMatrix<f64, M, M>,
    /// One measurement per step after the first; `None` is a predict-only step.
    ys: Vec<Option<SVector<f64, M>>>,
    params: UtParams,
}

fn case() -> impl Strategy<Value = Case> {
    (
        matrix::<N, 1>(-3.0, 3.0),
        spd::<N>(1.0, 0.05),
        matrix::<N, N>(-0.8, 0.8),
        spd::<N>(0.4, 0.01),
        matrix::<M, N>(-2.0, 2.0),
        spd::<M>(0.5, 0.01),
        prop::collection::vec(
            prop::option::weighted(0.7, matrix::<M, 1>(-3.0, 3.0)),
            1..12,
        ),
        prop_oneof![Just(1e-1), Just(1.0), 1e-2..1.0f64],
        0.0..3.0f64,
    )
        .prop_map(|(x0, p0, a, q, h, r, ys, alpha, beta)| Case {
            x0,
            p0,
            a: a + Mn::identity() * 0.5,
            q,
            h,
            r,
            ys,
            params: UtParams::new(alpha, beta, 0.0),
        })
}

/// The textbook linear Kalman filter, keeping every filtered estimate and every prediction.
/// The gain comes from a Cholesky solve and the covariance from the Joseph form: with an
/// explicit inverse and `(I - K H) P`, the reference itself erred by up to 5e-7 (relative) on
/// draws whose covariances had condition numbers near 1e5, and the comparison failed on the
/// reference's rounding, not the UKF's.
fn kalman(c: &Case) -> (Moments, Moments) {
    let (mut x, mut p) = (c.x0, c.p0);
    let mut filtered = vec![(x, p)];
    let mut predicted = Vec::new();
    for y in &c.ys {
        x = c.a * x;
        p = c.a * p * c.a.transpose() + c.q;
        predicted.push((x, p));
        if let Some(y) = y {
            let s = c.h * p * c.h.transpose() + c.r;
            let k = s.cholesky().unwrap().solve(&(c.h * p)).transpose();
            x += k * (y - c.h * x);
            let ikh = Mn::identity() - k * c.h;
            p = ikh * p * ikh.transpose() + k * c.r * k.transpose();
        }
        filtered.push((x, p));
    }
    (filtered, predicted)
}

/// The textbook linear RTS smoother, its gain from a Cholesky solve (not an explicit inverse
/// of the predicted covariance, whose rounding grows with the square of its conditioning).
fn rts(c: &Case, filtered: &[(Vn, Mn)], predicted: &[(Vn, Mn)]) -> Moments {
    let mut out = filtered.to_vec();
    for k in (0..filtered.len() - 1).rev() {
        let (m, p) = filtered[k];
        let (mp, pp) = predicted[k];
        let g = pp.cholesky().unwrap().solve(&(c.a * p)).transpose();
        let (ms, ps) = out[k + 1];
        out[k] = (m + g * (ms - mp), p + g * (ps - pp) * g.transpose());
    }
    out
}

/// The forward pass of the crate's UKF, keeping every filtered estimate.
fn ukf_history(c: &Case) -> Vec<Gaussian<N>> {
    let mut ukf = Ukf::new(c.x0, c.p0, Euclidean, c.params).unwrap();
    let mut out = vec![Gaussian::new(*ukf.state(), *ukf.covariance())];
    for y in &c.ys {
        ukf.predict(|x| c.a * x, &c.q).unwrap();
        if let Some(y) = y {
            ukf.update(y, |x| c.h * x, &c.r, &Euclidean).unwrap();
        }
        out.push(Gaussian::new(*ukf.state(), *ukf.covariance()));
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// With a linear process and an identity space, the URTSS run over the UKF's history is
    /// the linear RTS smoother run over the linear Kalman filter's, to 1e-9 (relative to the
    /// size of the numbers).
    #[test]
    fn linear_gaussian_equals_linear_rts(c in case()) {
        let (filtered, predicted) = kalman(&c);
        let want = rts(&c, &filtered, &predicted);
        let history = ukf_history(&c);
        let smoother = RtsSmoother::new(Euclidean, c.params).unwrap();
        let got = smoother.smooth(&history, |_, x| c.a * x, |_| c.q).unwrap();
        prop_assert_eq!(got.estimates.len(), want.len());
        // The backward pass alone sees no measurement: no likelihood to report.
        prop_assert_eq!(got.log_likelihood, None);
        // Two different computations (sigma points against Cholesky solves) agree to rounding:
        // the worst of 100,000 draws (covariance condition numbers up to 1e5) differed by
        // 1.7e-11, so 1e-9; a wrong gain or mean errs by 1e-2. (With an explicit inverse in
        // the reference the reference itself erred by 5e-7, and 1e-7 failed on it.)
        let tol = 1e-9;
        for (k, (g, (m, p))) in got.estimates.iter().zip(&want).enumerate() {
            let scale = 1.0 + m.amax().max(p.amax());
            let em = (g.mean - m).amax() / scale;
            let ep = (g.covariance - p).amax() / scale;
            prop_assert!(em <= tol, "step {}: mean error {:e}\n got {}\n want {}", k, em, g.mean, m);
            prop_assert!(ep <= tol, "step {}: covariance error {:e}\n got {}\n want {}", k, ep, g.covariance, p);
        }
        // Smoothing never loses information: Ps_k <= P_k (all eigenvalues of the difference
        // non-negative, up to rounding).
        for (g, f) in got.estimates.iter().zip(&history) {
            let d = f.covariance - g.covariance;
            let min = d.symmetric_eigenvalues().min();
            prop_assert!(min >= -1e-9 * (1.0 + f.covariance.amax()), "Ps > P: {}", min);
        }
    }

    /// A heading turning at a known rate, measured, smoothed with an `AngleMask` across the
    /// `pi` seam, equals the same smoother on the unwrapped heading, wrapped.
    #[test]
    fn angles_across_the_seam_match_unwrapped(
        start in 2.6..3.1f64,
        rate in 0.5..2.0f64,
        noise in prop::collection::vec(-0.05..0.05f64, 25),
    ) {
        let dt = 0.1;
        let f = |x: &Vector2<f64>| Vector2::new(x[0] + x[1] * dt, x[1]);
        let q = Matrix2::new(1e-4, 0.0, 0.0, 1e-3);
        let run = |wrap: bool| {
            let p0 = Matrix2::new(0.05, 0.0, 0.0, 0.5);
            let x0 = Vector2::new(start, 0.0);
            let mut history = Vec::new();
            let angles = AngleMask::new([true, false]);
            let mut ukf = Ukf::new(x0, p0, angles, UtParams::default()).unwrap();
            let mut lin = Ukf::new(x0, p0, Euclidean, UtParams::default()).unwrap();
            history.push(if wrap { Gaussian::new(*ukf.state(), *ukf.covariance()) }
                         else { Gaussian::new(*lin.state(), *lin.covariance()) });
            for (k, e) in noise.iter().enumerate() {
                let y = start + rate * dt * (k + 1) as f64 + e;
                if wrap {
                    ukf.predict(f, &q).unwrap();
                    ukf.update(&Vector1::new(wrap_angle(y)), |x| Vector1::new(x[0]),
                               &Matrix1::new(0.0025), &AngleMask::new([true])).unwrap();
                    history.push(Gaussian::new(*ukf.state(), *ukf.covariance()));
                } else {
                    lin.predict(f, &q).unwrap();
                    lin.update(&Vector1::new(y), |x| Vector1::new(x[0]),
                               &Matrix1::new(0.0025), &Euclidean).unwrap();
                    history.push(Gaussian::new(*lin.state(), *lin.covariance()));
                }
            }
            history
        };
        let wrapped = RtsSmoother::new(AngleMask::new([true, false]), UtParams::default())
            .unwrap()
            .smooth(&run(true), |_, x| f(x), |_| q)
            .unwrap();
        let unwrapped = RtsSmoother::new(Euclidean, UtParams::default())
            .unwrap()
            .smooth(&run(false), |_, x| f(x), |_| q)
            .unwrap();
        for (a, b) in wrapped.estimates.iter().zip(&unwrapped.estimates) {
            prop_assert!(wrap_angle(a.mean[0] - b.mean[0]).abs() < 1e-9, "{} vs {}", a.mean, b.mean);
            prop_assert!((a.mean[1] - b.mean[1]).abs() < 1e-9);
            prop_assert!((a.covariance - b.covariance).amax() < 1e-9);
        }
    }
}

#[test]
fn empty_history_is_an_error() {
    let s = RtsSmoother::<1, Euclidean>::new(Euclidean, UtParams::default()).unwrap();
    let err = s.smooth(&[], |_, x| *x, |_| Matrix1::new(1.0)).unwrap_err();
    assert_eq!(err, UkfError::EmptyHistory);
}

#[test]
fn one_estimate_is_its_own_smoothed_estimate() {
    let s = RtsSmoother::<1, Euclidean>::new(Euclidean, UtParams::default()).unwrap();
    let e = Gaussian::new(Vector1::new(2.0), Matrix1::new(0.5));
    let out = s.smooth(&[e], |_, x| *x, |_| Matrix1::new(1.0)).unwrap();
    assert_eq!(out.estimates, vec![e]);
}

#[test]
fn non_finite_inputs_are_errors_naming_the_step() {
    let s = RtsSmoother::<1, Euclidean>::new(Euclidean, UtParams::default()).unwrap();
    let good = Gaussian::new(Vector1::new(0.0), Matrix1::new(1.0));
    let bad = Gaussian::new(Vector1::new(f64::NAN), Matrix1::new(1.0));
    let err = s
        .smooth(&[good, bad, good], |_, x| *x, |_| Matrix1::new(1e-3))
        .unwrap_err();
    assert!(
        matches!(err, UkfError::Smoothing { step: 1, .. }),
        "{err:?}"
    );
    // A process that returns NaN at step 0.
    let err = s
        .smooth(
            &[good, good],
            |_, x| Vector1::new(if x[0] > 0.0 { f64::NAN } else { x[0] }),
            |_| Matrix1::new(1e-3),
        )
        .unwrap_err();
    assert!(
        matches!(err, UkfError::Smoothing { step: 0, .. }),
        "{err:?}"
    );
    assert!(
        matches!(err.root(), UkfError::NonFiniteFunction { .. }),
        "{err:?}"
    );
    // A non-finite noise.
    let err = s
        .smooth(&[good, good], |_, x| *x, |_| Matrix1::new(f64::INFINITY))
        .unwrap_err();
    assert!(
        matches!(err.root(), UkfError::NonFiniteMatrix { .. }),
        "{err:?}"
    );
}

#[test]
fn an_indefinite_filtered_covariance_is_a_typed_error() {
    let s = RtsSmoother::<2, Euclidean>::new(Euclidean, UtParams::default()).unwrap();
    let good = Gaussian::new(Vector2::zeros(), Matrix2::identity());
    let bad = Gaussian::new(Vector2::zeros(), Matrix2::new(1.0, 2.0, 2.0, 1.0));
    let err = s
        .smooth(&[bad, good], |_, x| *x, |_| Matrix2::identity() * 1e-3)
        .unwrap_err();
    assert!(
        matches!(err, UkfError::Smoothing { step: 0, .. }),
        "{err:?}"
    );
    assert!(
        matches!(err.root(), UkfError::NotPositiveDefinite { .. }),
        "{err:?}"
    );
}

/// `filter_and_smooth` (the forward UKF and the backward pass in one call, as the formation
/// filter's smoother uses it) equals the textbook linear Kalman filter and RTS smoother on
/// linear-Gaussian models, predict-only steps included; it asks for each step's noise once,
/// at the filtered mean of the step before. Run with an explicit runner so that the test
/// shows it exercised both kinds of step.
#[test]
fn filter_and_smooth_equals_the_linear_filter_and_smoother() {
    use proptest::test_runner::{Config, TestRunner};
    let mut runner = TestRunner::new(Config::with_cases(200));
    let counts = std::cell::Cell::new((0usize, 0usize, 0usize)); // cases, coasting, updates
    runner
        .run(&case(), |c| {
            let (filtered, predicted) = kalman(&c);
            let want = rts(&c, &filtered, &predicted);
            let start = Gaussian::new(c.x0, c.p0);
            let asked = std::cell::RefCell::new(Vec::new());
            let got = filter_and_smooth(
                Euclidean,
                c.params,
                &start,
                c.ys.len() + 1,
                |_, x| c.a * x,
                |k, m| {
                    asked.borrow_mut().push((k, *m));
                    c.q
                },
                |k| c.ys[k - 1].map(|y| (y, c.r)),
                |x| c.h * x,
                &Euclidean,
            )
            .unwrap();
            prop_assert_eq!(got.estimates.len(), want.len());
            for (k, (g, (m, p))) in got.estimates.iter().zip(&want).enumerate() {
                let scale = 1.0 + m.amax().max(p.amax());
                prop_assert!(
                    (g.mean - m).amax() / scale <= 1e-9,
                    "step {}: {} vs {}",
                    k,
                    g.mean,
                    m
                );
                // To 1e-9, as in `linear_gaussian_equals_linear_rts` (the reason is there).
                prop_assert!((g.covariance - p).amax() / scale <= 1e-9, "step {}", k);
            }
            // The forward pass's log-likelihood is the linear filter's: the sum over the
            // updates of log N(y - H x-; 0, H P- H^T + R).
            let want_ll: f64 =
                c.ys.iter()
                    .zip(&predicted)
                    .filter_map(|(y, (x, p))| y.map(|y| (y, x, p)))
                    .map(|(y, x, p)| {
                        let s = c.h * p * c.h.transpose() + c.r;
                        let nu = y - c.h * x;
                        let chol = s.cholesky().unwrap();
                        let nis = nu.dot(&chol.solve(&nu));
                        let log_det = 2.0 * chol.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
                        -0.5 * (nis + log_det + M as f64 * (2.0 * std::f64::consts::PI).ln())
                    })
                    .sum();
            let got_ll = got.log_likelihood.unwrap();
            prop_assert!(
                (got_ll - want_ll).abs() <= 1e-6 * (1.0 + want_ll.abs()),
                "log-likelihood {} vs {}",
                got_ll,
                want_ll
            );
            // One noise per transition, asked at the filtered mean of the step it leaves.
            let asked = asked.into_inner();
            prop_assert_eq!(asked.len(), c.ys.len());
            for (i, (k, m)) in asked.iter().enumerate() {
                prop_assert_eq!(*k, i);
                prop_assert!((m - filtered[i].0).amax() <= 1e-7 * (1.0 + m.amax()));
            }
            let (n, coast, upd) = counts.get();
            let coasting = c.ys.iter().any(Option::is_none);
            let updating = c.ys.iter().any(Option::is_some);
            counts.set((
                n + 1,
                coast + usize::from(coasting),
                upd + usize::from(updating),
            ));
            Ok(())
        })
        .unwrap();
    let (n, coast, upd) = counts.get();
    assert!(n >= 200, "{n} cases");
    assert!(
        coast > 20 && upd > 100,
        "{coast} cases with a predict-only step, {upd} with an update"
    );
}
