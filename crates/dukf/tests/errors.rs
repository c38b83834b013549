//! Bad input gives typed errors and leaves the filter unchanged; a covariance that loses
//! definiteness is repaired by the documented jitter or reported.

use dukf::{
    AngleMask, Covariance, DualFilter, DualUkf, Euclidean, Function, Input, JitterPolicy, Ukf,
    UkfError, UtParams, factor_repaired,
};
use nalgebra::{Matrix2, Matrix3, SMatrix, SVector, Vector2, Vector3};
use proptest::prelude::*;

fn filter() -> Ukf<3, AngleMask<3>> {
    Ukf::new(
        Vector3::new(1.0, 2.0, 0.5),
        Matrix3::from_diagonal(&Vector3::new(0.1, 0.2, 0.05)),
        AngleMask::new([false, false, true]),
        UtParams::default(),
    )
    .expect("valid filter")
}

fn f(x: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        x[0] + 0.1 * x[2].cos(),
        x[1] + 0.1 * x[2].sin(),
        x[2] + 0.05,
    )
}

fn h(x: &Vector3<f64>) -> Vector2<f64> {
    Vector2::new(x[0].hypot(x[1]), x[1].atan2(x[0]))
}

const MEAS: AngleMask<2> = AngleMask::new([false, true]);

#[test]
fn non_finite_measurement_is_rejected_and_filter_unchanged() {
    let mut ukf = filter();
    let before = ukf;
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let err = ukf
            .update(&Vector2::new(2.0, bad), h, &Matrix2::identity(), &MEAS)
            .unwrap_err();
        assert!(
            matches!(
                err,
                UkfError::NonFiniteVector {
                    input: Input::Measurement,
                    index: 1,
                    ..
                }
            ),
            "{err:?}"
        );
        assert_eq!(ukf, before);
    }
    assert!(
        err_text(&ukf.update(&Vector2::new(f64::NAN, 0.0), h, &Matrix2::identity(), &MEAS))
            .contains("measurement y component 0")
    );
}

#[test]
fn non_finite_noise_is_rejected_and_filter_unchanged() {
    let mut ukf = filter();
    let before = ukf;
    let mut r = Matrix2::identity();
    r[(0, 1)] = f64::NAN;
    let err = ukf
        .update(&Vector2::new(2.0, 1.0), h, &r, &MEAS)
        .unwrap_err();
    assert!(
        matches!(
            err,
            UkfError::NonFiniteMatrix {
                input: Input::MeasurementNoise,
                row: 0,
                col: 1,
                ..
            }
        ),
        "{err:?}"
    );
    let mut q = Matrix3::identity();
    q[(2, 2)] = f64::INFINITY;
    let err = ukf.predict(f, &q).unwrap_err();
    assert!(
        matches!(
            err,
            UkfError::NonFiniteMatrix {
                input: Input::ProcessNoise,
                row: 2,
                col: 2,
                ..
            }
        ),
        "{err:?}"
    );
    assert_eq!(ukf, before);
}

#[test]
fn non_finite_process_output_is_reported_with_its_sigma_point() {
    let mut ukf = filter();
    let before = ukf;
    // NaN only for sigma points on the plus side of x[0]: point 1 (first plus column).
    let x0 = ukf.state()[0];
    let err = ukf
        .predict(
            |x| {
                if x[0] > x0 + 1e-9 {
                    Vector3::new(f64::NAN, 0.0, 0.0)
                } else {
                    f(x)
                }
            },
            &Matrix3::identity(),
        )
        .unwrap_err();
    assert!(matches!(
        err,
        UkfError::NonFiniteFunction { function: Function::Process, sigma_point: 1, component: 0, value } if value.is_nan()
    ));
    assert_eq!(ukf, before);
}

#[test]
fn non_finite_measurement_function_output_is_rejected() {
    let mut ukf = filter();
    let before = ukf;
    let err = ukf
        .update(
            &Vector2::new(2.0, 1.0),
            |x| Vector2::new(1.0 / (x[2] - 0.5), 0.0),
            &Matrix2::identity(),
            &MEAS,
        )
        .unwrap_err();
    // x[2] == 0.5 exactly at the centre sigma point only.
    assert!(
        matches!(err, UkfError::NonFiniteFunction { function: Function::Measurement, sigma_point: 0, component: 0, value } if value.is_infinite()),
        "{err:?}"
    );
    assert!(err.to_string().contains("measurement function"));
    assert_eq!(ukf, before);
}

#[test]
fn singular_predicted_covariance_is_repaired_and_reported() {
    // f maps both components onto the first: P- = [[1, 1], [1, 1]] exactly, singular.
    let mut ukf = Ukf::new(
        Vector2::new(0.0, 0.0),
        Matrix2::identity(),
        Euclidean,
        UtParams::new(1.0, 2.0, 0.0),
    )
    .unwrap();
    let report = ukf
        .predict(|x| Vector2::new(x[0], x[0]), &Matrix2::zeros())
        .unwrap();
    let policy = JitterPolicy::default();
    assert!(report.jitter > 0.0, "a singular covariance needs jitter");
    assert!(report.jitter <= policy.max_relative * 1.0 + 1e-18);
    // The stored covariance is the jittered one and matches its factor.
    let p = ukf.covariance();
    assert!((p - Matrix2::new(1.0, 1.0, 1.0, 1.0)).amax() <= report.jitter + 1e-15);
    assert!((p[(0, 0)] - 1.0 - report.jitter).abs() < 1e-15);
    let l = ukf.covariance_factor();
    assert!((l * l.transpose() - p).amax() < 1e-12);
}

#[test]
fn repair_can_be_disabled_and_then_it_is_an_error() {
    let mut ukf = Ukf::new(
        Vector2::new(0.0, 0.0),
        Matrix2::identity(),
        Euclidean,
        UtParams::new(1.0, 2.0, 0.0),
    )
    .unwrap();
    ukf.set_jitter_policy(JitterPolicy::DISABLED).unwrap();
    let before = ukf;
    let err = ukf
        .predict(|x| Vector2::new(x[0], x[0]), &Matrix2::zeros())
        .unwrap_err();
    assert_eq!(
        err,
        UkfError::NotPositiveDefinite {
            which: Covariance::Predicted,
            max_jitter: 0.0
        }
    );
    assert_eq!(ukf, before);
}

#[test]
fn indefinite_noise_is_not_hidden_by_the_repair() {
    let mut ukf = filter();
    let before = ukf;
    // R = -I: S = H P H^T - I is clearly indefinite; jitter up to 1e-6 cannot fix it.
    let err = ukf
        .update(&Vector2::new(2.0, 1.0), h, &(-Matrix2::identity()), &MEAS)
        .unwrap_err();
    assert!(
        matches!(
            err,
            UkfError::NotPositiveDefinite {
                which: Covariance::Innovation,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("not positive definite"));
    assert_eq!(ukf, before);
    // Likewise an initial covariance with a real negative eigenvalue.
    let err = Ukf::new(
        Vector2::zeros(),
        Matrix2::new(1.0, 0.0, 0.0, -0.01),
        Euclidean,
        UtParams::default(),
    )
    .unwrap_err();
    assert!(matches!(
        err,
        UkfError::NotPositiveDefinite {
            which: Covariance::Initial,
            ..
        }
    ));
}

#[test]
fn factor_repaired_symmetrises_then_jitters() {
    // Asymmetric but with a positive definite symmetric part: no jitter, symmetrised.
    let m = Matrix2::new(2.0, 0.4, 0.0, 1.0);
    let r = factor_repaired(&m, &JitterPolicy::default(), Covariance::Initial).unwrap();
    assert_eq!(r.jitter, 0.0);
    assert_eq!(r.covariance, Matrix2::new(2.0, 0.2, 0.2, 1.0));
    // Slightly indefinite by rounding: repaired by the smallest jitter that works.
    let m = Matrix2::new(1.0, 1.0, 1.0, 1.0 - 1e-13);
    let r = factor_repaired(&m, &JitterPolicy::default(), Covariance::Predicted).unwrap();
    assert!(
        r.jitter >= 1e-12 && r.jitter <= 1e-10,
        "jitter {}",
        r.jitter
    );
    assert!((r.factor * r.factor.transpose() - r.covariance).amax() < 1e-12);
    // Non-finite entries are not factorised.
    let m = Matrix2::new(1.0, 0.0, 0.0, f64::INFINITY);
    assert!(matches!(
        factor_repaired(&m, &JitterPolicy::default(), Covariance::Updated),
        Err(UkfError::NonFiniteEstimate { .. })
    ));
}

#[test]
fn overflow_is_an_error_not_a_nan_state() {
    let mut ukf = filter();
    let before = ukf;
    let err = ukf
        .predict(|x| x * 1e300, &Matrix3::identity())
        .unwrap_err();
    assert!(
        matches!(
            err,
            UkfError::NonFiniteEstimate {
                which: Covariance::Predicted
            }
        ),
        "{err:?}"
    );
    assert_eq!(ukf, before);
}

#[test]
fn invalid_parameters_and_policies_are_rejected() {
    let bad = [
        UtParams::new(0.0, 2.0, 0.0),
        UtParams::new(-1.0, 2.0, 0.0),
        UtParams::new(f64::NAN, 2.0, 0.0),
        UtParams::new(1.0, 2.0, -3.0), // L + kappa = 0 for L = 3
    ];
    for params in bad {
        let err = Ukf::new(Vector3::zeros(), Matrix3::identity(), Euclidean, params).unwrap_err();
        assert!(
            matches!(err, UkfError::InvalidParameters { dimension: 3, .. }),
            "{params:?}: {err:?}"
        );
    }
    let mut ukf = filter();
    for policy in [
        JitterPolicy {
            initial_relative: 1e-6,
            growth: 10.0,
            max_relative: 1e-9,
        },
        JitterPolicy {
            initial_relative: 1e-12,
            growth: 1.0,
            max_relative: 1e-6,
        },
        JitterPolicy {
            initial_relative: 1e-12,
            growth: 10.0,
            max_relative: f64::INFINITY,
        },
    ] {
        assert!(matches!(
            ukf.set_jitter_policy(policy),
            Err(UkfError::InvalidJitterPolicy { .. })
        ));
    }
    assert_eq!(ukf.jitter_policy(), &JitterPolicy::default());
    let x = SVector::<f64, 3>::new(0.0, f64::NAN, 0.0);
    let err = Ukf::new(x, Matrix3::identity(), Euclidean, UtParams::default()).unwrap_err();
    assert!(matches!(
        err,
        UkfError::NonFiniteVector {
            input: Input::State,
            index: 1,
            ..
        }
    ));
}

fn dual() -> DualUkf<3, 2, 2, AngleMask<3>, Euclidean, AngleMask<2>> {
    let params = Ukf::new(
        Vector2::new(1.0, 0.2),
        Matrix2::identity(),
        Euclidean,
        UtParams::default(),
    )
    .expect("valid dual filter");
    DualUkf::new(
        filter(),
        params,
        Matrix3::identity() * 1e-4,
        Matrix2::identity() * 1e-4,
        MEAS,
    )
    .expect("valid dual filter")
}

fn fw(x: &Vector3<f64>, w: &Vector2<f64>) -> Vector3<f64> {
    let dt = 0.1;
    Vector3::new(
        x[0] + dt * w[0] * x[2].cos(),
        x[1] + dt * w[0] * x[2].sin(),
        x[2] + dt * w[1],
    )
}

#[test]
fn dual_rejects_bad_input_and_changes_neither_filter() {
    let mut d = dual();
    let before = d;
    let err = d
        .step(fw, h, &Vector2::new(f64::NAN, 0.0), &Matrix2::identity())
        .unwrap_err();
    assert!(matches!(
        err,
        UkfError::NonFiniteVector {
            input: Input::Measurement,
            ..
        }
    ));
    // A model that fails only for parameter sigma points (w[0] above its mean): the state
    // filter alone would succeed, but the step fails as a whole.
    let w0 = d.parameters()[0];
    let err = d
        .step(
            |x: &Vector3<f64>, w: &Vector2<f64>| {
                if w[0] > w0 + 1e-12 {
                    Vector3::repeat(f64::NAN)
                } else {
                    fw(x, w)
                }
            },
            h,
            &Vector2::new(2.2, 1.1),
            &(Matrix2::identity() * 0.01),
        )
        .unwrap_err();
    match &err {
        UkfError::Dual {
            filter: DualFilter::Parameter,
            source,
        } => {
            assert!(matches!(
                **source,
                UkfError::NonFiniteFunction {
                    function: Function::Measurement,
                    ..
                }
            ));
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(err.to_string().starts_with("dual UKF parameter filter:"));
    assert_eq!(d, before);
    let err = d
        .predict_only(|_: &Vector3<f64>, _: &Vector2<f64>| Vector3::repeat(f64::INFINITY))
        .unwrap_err();
    assert!(matches!(
        err,
        UkfError::Dual {
            filter: DualFilter::State,
            ..
        }
    ));
    assert_eq!(d, before);
    let mut q = Matrix3::identity();
    q[(1, 0)] = f64::NAN;
    assert!(d.set_process_noise(q).is_err());
    assert_eq!(d, before);
}

fn err_text<T>(r: &Result<T, UkfError>) -> String {
    r.as_ref()
        .err()
        .map(ToString::to_string)
        .unwrap_or_default()
}

fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -10.0..10.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(-1e308),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Whatever the measurement and noise, a step either succeeds with a finite estimate or
    /// fails and leaves the filter as it was: never a NaN state.
    #[test]
    fn never_a_nan_state(
        ys in prop::collection::vec((any_f64(), any_f64()), 1..6),
        r_diag in (any_f64(), any_f64()),
    ) {
        let mut d = dual();
        let r = SMatrix::<f64, 2, 2>::from_diagonal(&Vector2::new(r_diag.0, r_diag.1));
        for (a, b) in ys {
            let before = d;
            match d.step(fw, h, &Vector2::new(a, b), &r) {
                Ok(report) => {
                    prop_assert!(d.state().iter().all(|v| v.is_finite()));
                    prop_assert!(d.parameters().iter().all(|v| v.is_finite()));
                    prop_assert!(d.state_covariance().iter().all(|v| v.is_finite()));
                    prop_assert!(report.state.nis.is_finite());
                }
                Err(_) => prop_assert_eq!(d, before),
            }
            let before = d;
            if d.predict_only(fw).is_err() {
                prop_assert_eq!(d, before);
            }
        }
    }
}
