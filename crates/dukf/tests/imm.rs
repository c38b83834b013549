//! The interacting multiple-model filter: it reduces to its one filter when one model has
//! all the probability, picks the model that explains the data, and rejects bad input
//! without changing anything.
#![allow(clippy::unwrap_used)]

use dukf::{
    AngleMask, Euclidean, Imm, Ukf, UkfError, UtParams, mixture_mean, mixture_noise,
    sojourn_transition,
};
use nalgebra::{Matrix1, Matrix2, Vector1, Vector2};
use proptest::prelude::*;

const DT: f64 = 0.1;

fn member(x: Vector2<f64>) -> Ukf<2, Euclidean> {
    Ukf::new(x, Matrix2::identity(), Euclidean, UtParams::default()).unwrap()
}

/// Model 0: constant velocity; model 1: standing still (velocity forced to 0).
fn f(j: usize, x: &Vector2<f64>) -> Vector2<f64> {
    if j == 0 {
        Vector2::new(x[0] + DT * x[1], x[1])
    } else {
        Vector2::new(x[0], 0.0)
    }
}

fn h(x: &Vector2<f64>) -> Vector1<f64> {
    Vector1::new(x[0])
}

fn q() -> [Matrix2<f64>; 2] {
    [Matrix2::identity() * 1e-4, Matrix2::identity() * 1e-4]
}

fn imm() -> Imm<2, 2, Euclidean> {
    let pi = sojourn_transition::<2>(DT, 1.0).unwrap();
    Imm::new(
        [member(Vector2::zeros()), member(Vector2::zeros())],
        [0.5, 0.5],
        pi,
    )
    .unwrap()
}

#[test]
fn the_model_that_explains_the_data_wins() {
    // Moving at 1 unit/s: model 0.
    let mut moving = imm();
    for k in 1..=60 {
        let y = Vector1::new(DT * f64::from(k));
        moving
            .step(f, &q(), &y, h, &Matrix1::new(1e-3), &Euclidean)
            .unwrap();
    }
    assert!(
        moving.probabilities()[0] > 0.9,
        "{:?}",
        moving.probabilities()
    );
    assert!((moving.estimate().0[1] - 1.0).abs() < 0.1);
    // Standing at 2: both models explain it (model 0 with a velocity near 0), so neither
    // wins, and the combined estimate stands still at 2.
    let mut still = imm();
    for _ in 0..60 {
        still
            .step(
                f,
                &q(),
                &Vector1::new(2.0),
                h,
                &Matrix1::new(1e-3),
                &Euclidean,
            )
            .unwrap();
    }
    assert!(
        still.probabilities()[1] > 0.3,
        "{:?}",
        still.probabilities()
    );
    assert!((still.estimate().0[0] - 2.0).abs() < 0.05);
    assert!(still.estimate().0[1].abs() < 0.1);
}

#[test]
fn bad_input_is_rejected_and_nothing_changes() {
    let mut imm = imm();
    imm.step(
        f,
        &q(),
        &Vector1::new(0.1),
        h,
        &Matrix1::new(1e-3),
        &Euclidean,
    )
    .unwrap();
    let before = imm;
    let err = imm
        .step(
            f,
            &q(),
            &Vector1::new(f64::NAN),
            h,
            &Matrix1::new(1e-3),
            &Euclidean,
        )
        .unwrap_err();
    assert!(matches!(err, UkfError::NonFiniteVector { .. }), "{err:?}");
    let mut bad_q = q();
    bad_q[1][(0, 0)] = f64::INFINITY;
    let err = imm.predict_only(f, &bad_q).unwrap_err();
    assert!(matches!(err, UkfError::NonFiniteMatrix { .. }), "{err:?}");
    // A model whose process function returns NaN is named.
    let err = imm
        .step(
            |j, x| {
                if j == 1 {
                    Vector2::repeat(f64::NAN)
                } else {
                    f(j, x)
                }
            },
            &q(),
            &Vector1::new(0.2),
            h,
            &Matrix1::new(1e-3),
            &Euclidean,
        )
        .unwrap_err();
    assert!(matches!(err, UkfError::Imm { model: 1, .. }), "{err:?}");
    assert!(matches!(err.root(), UkfError::NonFiniteFunction { .. }));
    // An indefinite process noise (the covariance loses definiteness) is an error too.
    let indefinite = [Matrix2::identity() * -10.0, Matrix2::identity() * 1e-4];
    let err = imm
        .step(
            f,
            &indefinite,
            &Vector1::new(0.2),
            h,
            &Matrix1::new(1e-3),
            &Euclidean,
        )
        .unwrap_err();
    assert!(
        matches!(err.root(), UkfError::NotPositiveDefinite { .. }),
        "{err:?}"
    );
    assert_eq!(imm, before);
}

#[test]
fn invalid_probabilities_are_rejected() {
    let m = member(Vector2::zeros());
    let pi = Matrix2::new(0.9, 0.1, 0.1, 0.9);
    for mu in [[0.7, 0.7], [-0.5, 1.5], [f64::NAN, 1.0]] {
        assert!(matches!(
            Imm::new([m, m], mu, pi),
            Err(UkfError::InvalidModelProbabilities { .. })
        ));
    }
    let bad = Matrix2::new(0.9, 0.2, 0.1, 0.9);
    assert!(Imm::new([m, m], [0.5, 0.5], bad).is_err());
    assert!(sojourn_transition::<2>(0.0, 1.0).is_err());
    assert!(sojourn_transition::<2>(0.1, f64::NAN).is_err());
}

#[test]
fn the_structure_can_be_replaced_and_a_dropped_model_stays_out() {
    let mut imm = imm();
    let before = imm;
    // A bad row or bad probabilities change nothing.
    let bad = Matrix2::new(0.9, 0.2, 0.1, 0.9);
    assert!(imm.set_structure(bad, [0.5, 0.5]).is_err());
    assert!(imm.set_structure(Matrix2::identity(), [0.7, 0.7]).is_err());
    assert_eq!(imm, before);
    // Model 1 dropped: probability 0 and no transition into it.
    let pi = Matrix2::new(1.0, 0.0, 1.0, 0.0);
    imm.set_structure(pi, [1.0, 0.0]).unwrap();
    assert_eq!(imm.transition(), &pi);
    for k in 1..=20 {
        let y = Vector1::new(DT * f64::from(k));
        let report = imm
            .step(f, &q(), &y, h, &Matrix1::new(1e-3), &Euclidean)
            .unwrap();
        assert_eq!(report.probabilities, [1.0, 0.0]);
    }
}

proptest! {
    /// With all the probability on model 0 and no switching, the IMM is exactly model 0's
    /// filter (model 1 never mixes in).
    #[test]
    fn one_certain_model_is_the_plain_ukf(ys in proptest::collection::vec(-5.0..5.0f64, 1..30)) {
        let pi = Matrix2::identity();
        let mut imm = Imm::new([member(Vector2::zeros()), member(Vector2::zeros())], [1.0, 0.0], pi).unwrap();
        let mut ukf = member(Vector2::zeros());
        for y in ys {
            let y = Vector1::new(y);
            imm.step(f, &q(), &y, h, &Matrix1::new(0.1), &Euclidean).unwrap();
            ukf.predict(|x| f(0, x), &q()[0]).unwrap();
            ukf.update(&y, h, &Matrix1::new(0.1), &Euclidean).unwrap();
        }
        let (x, p) = imm.estimate();
        prop_assert!((x - ukf.state()).amax() < 1e-9);
        prop_assert!((p - ukf.covariance()).amax() < 1e-9);
        prop_assert_eq!(imm.probabilities()[1], 0.0);
    }

    /// The probabilities stay a distribution whatever the data.
    #[test]
    fn probabilities_sum_to_one(ys in proptest::collection::vec(-50.0..50.0f64, 1..30)) {
        let mut imm = imm();
        for y in ys {
            imm.step(f, &q(), &Vector1::new(y), h, &Matrix1::new(0.01), &Euclidean).unwrap();
            let mu = imm.probabilities();
            prop_assert!((mu[0] + mu[1] - 1.0).abs() < 1e-12);
            prop_assert!(mu.iter().all(|m| (0.0..=1.0).contains(m)));
        }
    }
}

/// The mixture of a model set as one transition: its mean is the probability-weighted mean
/// (on the circle for angles, across the seam), its noise the weighted noises plus the
/// weighted spread of the predictions.
#[test]
fn a_mixture_is_the_weighted_mean_and_the_noises_plus_the_spread() {
    let outs = [Vector2::new(1.0, 3.0), Vector2::new(2.0, -3.0)];
    let p = [0.25, 0.75];
    let plain = mixture_mean(&Euclidean, &outs, &p);
    assert!((plain - Vector2::new(1.75, -1.5)).amax() < 1e-15, "{plain}");
    // With the second component an angle, 3 and -3 rad are 0.283 rad apart across pi: the
    // mean lies between them on that short arc, not near 0.
    let angles = AngleMask::new([false, true]);
    let m = mixture_mean(&angles, &outs, &p);
    let gap = 2.0 * std::f64::consts::PI - 6.0;
    assert!((m[0] - 1.75).abs() < 1e-15);
    assert!(
        (dukf::wrap_angle(m[1] - 3.0) - 0.75 * gap).abs() < 1e-12,
        "{m}"
    );
    let q = [Matrix2::identity() * 0.1, Matrix2::identity() * 0.3];
    let got = mixture_noise(&Euclidean, &outs, &plain, |j| q[j], &p);
    let mut want = Matrix2::zeros();
    for j in 0..2 {
        let d = outs[j] - plain;
        want += (q[j] + d * d.transpose()) * p[j];
    }
    assert!((got - want).amax() < 1e-15, "{got} vs {want}");
    assert_eq!(got, got.transpose());
    // One certain model: its own prediction and noise, no spread.
    let one = mixture_mean(&Euclidean, &outs, &[0.0, 1.0]);
    assert_eq!(one, outs[1]);
    assert_eq!(
        mixture_noise(&Euclidean, &outs, &one, |j| q[j], &[0.0, 1.0]),
        q[1]
    );
}
