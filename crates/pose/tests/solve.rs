//! End-to-end solver tests: recovery of random poses, both planar candidates, noise, bad input.

mod common;

use common::*;
use nalgebra::{Point2, Point3, Vector3};
use pose::{Distortion, Pose, PoseError, PoseSolver, SolverOptions};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// One face, noise-free: one of the two refined candidates is the true pose (1e-6).
    #[test]
    fn one_face_noise_free_recovers_truth(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let k = camera();
        let truth = random_face_pose(&mut rng, (0.3, 3.0), 70f64.to_radians());
        let model = face_model();
        let image = project_all(&k, &truth, &model);
        let solver = PoseSolver::new(k);
        let sol = solver.solve(&model, &image).unwrap();
        prop_assert!(sol.coplanar);
        let alt = sol.alternative.unwrap();
        let best_err = sol.best.pose.rotation_angle_to(&truth).max(translation_error(&sol.best.pose, &truth));
        let alt_err = alt.pose.rotation_angle_to(&truth).max(translation_error(&alt.pose, &truth));
        prop_assert!(best_err.min(alt_err) < 1e-6, "best {best_err:e}, alternative {alt_err:e}");
        // Noise-free: the best candidate reprojects exactly.
        prop_assert!(sol.rms() < 1e-6);
        let [c0, c1] = solver.planar_candidates(&model, &image).unwrap();
        prop_assert!(c0.rms <= c1.rms);
        prop_assert_eq!(c0.pose, sol.best.pose);
    }

    /// Three octagon faces (12 points), noise-free: POSIT + LM recovers the pose to 1e-6.
    #[test]
    fn three_faces_noise_free_recovers_truth(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let k = camera();
        let truth = random_rig_pose(&mut rng);
        let model = three_faces_model();
        let image = project_all(&k, &truth, &model);
        let sol = PoseSolver::new(k).solve(&model, &image).unwrap();
        prop_assert!(!sol.coplanar);
        prop_assert!(sol.alternative.is_none());
        prop_assert!(sol.pose().rotation_angle_to(&truth) < 1e-6, "rotation error {}", sol.pose().rotation_angle_to(&truth));
        prop_assert!(translation_error(&sol.pose(), &truth) < 1e-6);
        prop_assert!(sol.rms() < 1e-6);
    }

    /// Two faces (8 points, non-coplanar) also go through POSIT + LM.
    #[test]
    fn two_faces_noise_free_recovers_truth(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let k = camera();
        let truth = random_rig_pose(&mut rng);
        let model = &three_faces_model()[4..];
        let image = project_all(&k, &truth, model);
        let sol = PoseSolver::new(k).solve(model, &image).unwrap();
        prop_assert!(sol.pose().rotation_angle_to(&truth) < 1e-6);
        prop_assert!(translation_error(&sol.pose(), &truth) < 1e-6);
    }

    /// Refining from a perturbed pose (a tracker's prediction) returns to the truth.
    #[test]
    fn refine_from_prediction(seed in any::<u64>(), dw in prop::array::uniform3(-0.1f64..0.1), dt in prop::array::uniform3(-0.05f64..0.05)) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let k = camera();
        let truth = random_rig_pose(&mut rng);
        let model = three_faces_model();
        let image = project_all(&k, &truth, &model);
        let start = Pose::new(truth.rotation + Vector3::from(dw), truth.translation + Vector3::from(dt));
        let est = PoseSolver::new(k).refine(&model, &image, &start).unwrap();
        prop_assert!(est.converged);
        prop_assert!(est.pose.rotation_angle_to(&truth) < 1e-6);
        prop_assert!(translation_error(&est.pose, &truth) < 1e-6);
    }

    /// With lens distortion: pixels distorted by the model are undistorted before solving.
    #[test]
    fn distorted_pixels_are_undistorted(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let k = camera();
        let d = Distortion::plumb_bob(-0.12, 0.035, 0.001, -0.0005, 0.0).unwrap();
        let truth = random_rig_pose(&mut rng);
        let model = three_faces_model();
        let image: Vec<_> = project_all(&k, &truth, &model).iter().map(|m| d.distort_pixel(&k, m)).collect();
        let sol = PoseSolver::new(k).with_distortion(d).solve(&model, &image).unwrap();
        prop_assert!(sol.pose().rotation_angle_to(&truth) < 1e-6);
        prop_assert!(translation_error(&sol.pose(), &truth) < 1e-6);
        // Without the distortion model the same pixels give a worse fit.
        let plain = PoseSolver::new(k).solve(&model, &image).unwrap();
        prop_assert!(plain.rms() > sol.rms());
    }

    /// The same through the rational and fisheye models: the solver undistorts with whatever
    /// model the calibration has.
    #[test]
    fn rational_and_fisheye_pixels_are_undistorted(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let k = camera();
        let truth = random_rig_pose(&mut rng);
        let model = three_faces_model();
        for d in [
            Distortion::rational_polynomial([0.1, -0.02, 0.0006, -0.0004, 0.001, 0.35, 0.01, 0.001]).unwrap(),
            Distortion::equidistant(0.05, -0.01, 0.002, -0.0003).unwrap(),
        ] {
            let image: Vec<_> = project_all(&k, &truth, &model).iter().map(|m| d.distort_pixel(&k, m)).collect();
            let sol = PoseSolver::new(k).with_distortion(d).solve(&model, &image).unwrap();
            prop_assert!(sol.pose().rotation_angle_to(&truth) < 1e-6, "{d:?}");
            prop_assert!(translation_error(&sol.pose(), &truth) < 1e-6, "{d:?}");
        }
    }
}

/// 0.3 px Gaussian noise on the corners of one face at 1 m (640x480, 60 degrees HFOV):
/// returns, per trial, the rotation error (degrees) of the chosen and of the other candidate.
fn noisy_face_trials(seed: u64, trials: usize, tilt_deg: (f64, f64)) -> Vec<(f64, f64)> {
    let k = camera();
    let model = face_model();
    let solver = PoseSolver::new(k);
    let noise = Normal::new(0.0, 0.3).expect("valid sigma");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..trials)
        .map(|_| {
            let truth = random_face_pose_tilted(
                &mut rng,
                (1.0, 1.0 + 1e-9),
                (tilt_deg.0.to_radians(), tilt_deg.1.to_radians()),
            );
            let image: Vec<Point2<f64>> = project_all(&k, &truth, &model)
                .into_iter()
                .map(|m| Point2::new(m.x + noise.sample(&mut rng), m.y + noise.sample(&mut rng)))
                .collect();
            let sol = solver.solve(&model, &image).expect("solvable view");
            let alt = sol.alternative.expect("coplanar: two candidates");
            (
                sol.pose().rotation_angle_to(&truth).to_degrees(),
                alt.pose.rotation_angle_to(&truth).to_degrees(),
            )
        })
        .collect()
}

/// The task's accuracy target: with 0.3 px noise on one 140 mm face at 1 m, the chosen
/// candidate's rotation error is below 2 degrees in >= 99% of 1000 seeded trials, for faces
/// tilted 40 to 70 degrees from the optical axis. (Closer to fronto-parallel the Cramer-Rao
/// bound itself is 1-2 degrees RMS, so no solver meets 2 degrees there; the next test shows
/// that what fails there is precision, not flips.)
#[test]
fn one_face_noise_rotation_error_below_2_degrees() {
    let errs = noisy_face_trials(20261121, 1000, (40.0, 70.0));
    let good = errs.iter().filter(|(e, _)| *e < 2.0).count();
    let mut chosen: Vec<f64> = errs.iter().map(|(e, _)| *e).collect();
    chosen.sort_by(f64::total_cmp);
    assert!(
        good >= 990,
        "only {good}/1000 below 2 degrees; median {}, p99 {}",
        chosen[500],
        chosen[990]
    );
}

/// No pose flips: over tilts 0 to 70 degrees, the chosen candidate is off by more than 2
/// degrees while the other one is within 2 degrees in at most 1% of trials.
#[test]
fn one_face_noise_flips_are_rare() {
    let errs = noisy_face_trials(7, 1000, (0.0, 70.0));
    let flips = errs
        .iter()
        .filter(|(e, alt)| *e >= 2.0 && *alt < 2.0)
        .count();
    assert!(flips <= 10, "{flips}/1000 flips");
}

fn square_points() -> (Vec<Point3<f64>>, Vec<Point2<f64>>) {
    let k = camera();
    let model = face_model().to_vec();
    let truth = Pose::new(Vector3::new(0.2, 0.3, 0.0), Vector3::new(0.0, 0.0, 1.0));
    let image = project_all(&k, &truth, &model);
    (model, image)
}

#[test]
fn too_few_points() {
    let (model, image) = square_points();
    let e = PoseSolver::new(camera())
        .solve(&model[..3], &image[..3])
        .unwrap_err();
    assert_eq!(e, PoseError::TooFewPoints { needed: 4, got: 3 });
}

#[test]
fn mismatched_lengths() {
    let (model, image) = square_points();
    let e = PoseSolver::new(camera())
        .solve(&model, &image[..3])
        .unwrap_err();
    assert_eq!(e, PoseError::LengthMismatch { model: 4, image: 3 });
}

#[test]
fn coincident_points() {
    let (mut model, image) = square_points();
    model[3] = model[1];
    let e = PoseSolver::new(camera()).solve(&model, &image).unwrap_err();
    assert_eq!(
        e,
        PoseError::CoincidentPoints {
            first: 1,
            second: 3
        }
    );
}

#[test]
fn collinear_points() {
    let model: Vec<_> = (0..5)
        .map(|i| Point3::new(0.05 * i as f64, 0.02 * i as f64, 0.0))
        .collect();
    let image: Vec<_> = (0..5)
        .map(|i| Point2::new(300.0 + 10.0 * i as f64, 200.0 + 4.0 * i as f64))
        .collect();
    let e = PoseSolver::new(camera()).solve(&model, &image).unwrap_err();
    assert!(matches!(e, PoseError::CollinearPoints { .. }), "{e:?}");
}

#[test]
fn non_finite_input() {
    let (mut model, mut image) = square_points();
    image[2].x = f64::NAN;
    let solver = PoseSolver::new(camera());
    assert_eq!(
        solver.solve(&model, &image).unwrap_err(),
        PoseError::NonFinite {
            which: "image",
            index: 2
        }
    );
    image[2].x = 100.0;
    model[1].z = f64::INFINITY;
    assert_eq!(
        solver.solve(&model, &image).unwrap_err(),
        PoseError::NonFinite {
            which: "model",
            index: 1
        }
    );
    let (model, image) = square_points();
    let bad = Pose::new(Vector3::new(f64::NAN, 0.0, 0.0), Vector3::z());
    assert_eq!(
        solver.refine(&model, &image, &bad).unwrap_err(),
        PoseError::NonFinite {
            which: "initial pose",
            index: 0
        }
    );
}

#[test]
fn initial_pose_behind_camera() {
    let (model, image) = square_points();
    let behind = Pose::new(Vector3::zeros(), Vector3::new(0.0, 0.0, -1.0));
    let e = PoseSolver::new(camera())
        .refine(&model, &image, &behind)
        .unwrap_err();
    assert!(
        matches!(e, PoseError::PointBehindCamera { index: 0, z } if z < 0.0),
        "{e:?}"
    );
}

#[test]
fn not_converged_carries_estimate() {
    let (model, image) = square_points();
    let mut opts = SolverOptions::default();
    opts.lm.max_iterations = 1;
    let start = Pose::new(Vector3::new(0.0, 0.0, 0.3), Vector3::new(0.05, 0.0, 1.3));
    let e = PoseSolver::new(camera())
        .with_options(opts)
        .refine(&model, &image, &start)
        .unwrap_err();
    match e {
        PoseError::NotConverged {
            iterations,
            estimate,
        } => {
            assert_eq!(iterations, 1);
            assert!(estimate.is_finite());
            assert_ne!(estimate, start);
        }
        other => panic!("expected NotConverged, got {other:?}"),
    }
}

#[test]
fn planar_candidates_rejects_non_coplanar() {
    let k = camera();
    let model = three_faces_model();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let image = project_all(&k, &random_rig_pose(&mut rng), &model);
    assert!(matches!(
        PoseSolver::new(k).planar_candidates(&model, &image),
        Err(PoseError::Degenerate { .. })
    ));
}

#[test]
fn covariance_is_symmetric_positive_and_scales_with_noise() {
    let k = camera();
    let model = three_faces_model();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let truth = random_rig_pose(&mut rng);
    let clean = project_all(&k, &truth, &model);
    let solver = PoseSolver::new(k);
    let c0 = solver.solve(&model, &clean).unwrap().best.covariance;
    assert!((c0 - c0.transpose()).amax() <= 1e-12 * c0.amax());
    assert!(c0.cholesky().is_some());
    // Noise-free residual: the covariance uses the 0.1 px floor.
    let noise = Normal::new(0.0, 2.0).unwrap();
    let noisy: Vec<_> = clean
        .iter()
        .map(|m| Point2::new(m.x + noise.sample(&mut rng), m.y + noise.sample(&mut rng)))
        .collect();
    let c1 = solver.solve(&model, &noisy).unwrap().best.covariance;
    // 2 px noise is ~20x the floor: variances grow by a factor of order 400.
    assert!(
        c1[(5, 5)] > 50.0 * c0[(5, 5)],
        "{} vs {}",
        c1[(5, 5)],
        c0[(5, 5)]
    );
}

#[test]
fn ambiguity_ratio_reports_flip() {
    let k = camera();
    let model = face_model();
    // Oblique, far view: two distinct candidates.
    let truth = Pose::new(Vector3::new(0.0, 0.6, 0.0), Vector3::new(0.05, 0.0, 2.5));
    let image = project_all(&k, &truth, &model);
    let sol = PoseSolver::new(k).solve(&model, &image).unwrap();
    let ratio = sol.ambiguity_ratio().unwrap();
    assert!(ratio > 1.0, "{ratio}");
    let alt = sol.alternative.unwrap();
    assert!(alt.pose.rotation_angle_to(&truth) > 0.1);
}

/// Three faces with 0.3 px noise, 0.8 to 3 m: no wrong minimum (every rotation error below
/// 3 degrees) and >= 97% of 500 trials within 1 degree (the misses are 1.0-1.4 degrees at
/// 2-3 m, i.e. precision).
#[test]
fn three_faces_noise_rotation_error_small() {
    let k = camera();
    let model = three_faces_model();
    let solver = PoseSolver::new(k);
    let noise = Normal::new(0.0, 0.3).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let mut errs = Vec::new();
    for _ in 0..500 {
        let truth = random_rig_pose(&mut rng);
        let image: Vec<_> = project_all(&k, &truth, &model)
            .into_iter()
            .map(|m| Point2::new(m.x + noise.sample(&mut rng), m.y + noise.sample(&mut rng)))
            .collect();
        let sol = solver.solve(&model, &image).unwrap();
        errs.push(sol.pose().rotation_angle_to(&truth).to_degrees());
    }
    let worst = errs.iter().copied().fold(0.0, f64::max);
    let within = errs.iter().filter(|e| **e < 1.0).count();
    assert!(worst < 3.0, "worst rotation error {worst} degrees");
    assert!(within >= 485, "{within}/500 within 1 degree");
}

#[test]
fn undistortion_failure_is_reported_by_the_solver() {
    let (model, mut image) = square_points();
    image[1] = Point2::new(0.0, 0.0); // the image corner lies beyond the fold of k1 = -1
    let d = Distortion::plumb_bob(-1.0, 0.0, 0.0, 0.0, 0.0).unwrap();
    let e = PoseSolver::new(camera())
        .with_distortion(d)
        .solve(&model, &image)
        .unwrap_err();
    assert!(
        matches!(e, PoseError::UndistortionNotConverged { .. }),
        "{e:?}"
    );
}

#[test]
fn invalid_options_are_rejected() {
    let (model, image) = square_points();
    let opts = SolverOptions {
        min_pixel_sigma: f64::NAN,
        ..Default::default()
    };
    let e = PoseSolver::new(camera())
        .with_options(opts)
        .solve(&model, &image)
        .unwrap_err();
    assert!(
        matches!(
            e,
            PoseError::InvalidOptions {
                name: "min_pixel_sigma",
                ..
            }
        ),
        "{e:?}"
    );
    let mut opts = SolverOptions::default();
    opts.lm.step_tolerance = -1.0;
    let e = PoseSolver::new(camera())
        .with_options(opts)
        .refine(&model, &image, &Pose::identity())
        .unwrap_err();
    assert!(
        matches!(
            e,
            PoseError::InvalidOptions {
                name: "lm.step_tolerance",
                ..
            }
        ),
        "{e:?}"
    );
}
