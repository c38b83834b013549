//! Single-marker pose in OpenCV's conventions (`solvePnP` with `SOLVEPNP_IPPE_SQUARE`).

use nalgebra::{Matrix3, Point2, Rotation3, Vector3};
use pose::{Distortion, Intrinsics, Pose, PoseError, PoseSolver, marker_corners};
use proptest::prelude::*;

fn camera() -> Intrinsics {
    Intrinsics::square_pixels(900.0, 900.0, 639.5, 359.5).expect("valid camera")
}

/// A marker facing the camera (its +z towards the camera), tilted by up to `tilt` radians.
fn facing(rx: f64, ry: f64, rz: f64, t: Vector3<f64>) -> Pose {
    let flip = Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let tilt = Rotation3::from_euler_angles(rx, ry, rz);
    Pose::from_matrix(&(flip * tilt).into_inner(), t)
}

fn project(k: &Intrinsics, d: &Distortion, pose: &Pose, side: f64) -> [Point2<f64>; 4] {
    marker_corners(side, side)
        .expect("valid side")
        .map(|p| d.distort_pixel(k, &k.project(&pose.transform_point(&p)).expect("in front")))
}

#[test]
fn a_frontal_upright_marker_has_opencv_axes() {
    let k = camera();
    // 100 mm marker 1 m straight ahead, upright: top-left corner up and to the left.
    let s = 0.1;
    let f = 900.0;
    let corners = [
        Point2::new(639.5 - f * 0.05, 359.5 - f * 0.05),
        Point2::new(639.5 + f * 0.05, 359.5 - f * 0.05),
        Point2::new(639.5 + f * 0.05, 359.5 + f * 0.05),
        Point2::new(639.5 - f * 0.05, 359.5 + f * 0.05),
    ];
    let m = PoseSolver::new(k).solve_square_marker(&corners, s).unwrap();
    // x right, y up, z out of the face: the camera's x, -y, -z.
    let r = m.best.pose.rotation_matrix();
    assert!(
        (r - Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))).amax() < 1e-9,
        "{r}"
    );
    assert!((m.best.pose.translation - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-9);
    assert!(m.best.rms < 1e-9);
    // The covariance is symmetric and positive definite.
    let c = m.best.covariance;
    assert!((c - c.transpose()).amax() < 1e-12 * c.amax());
    assert!(c.cholesky().is_some());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Noise-free corners through each lens model give back the pose, and the two candidates
    /// are ordered by their reprojection RMS.
    #[test]
    fn the_pose_is_recovered_through_each_lens_model(
        rx in -0.9f64..0.9, ry in -0.9f64..0.9, rz in -3.1f64..3.1,
        x in -0.3f64..0.3, y in -0.2f64..0.2, z in 0.5f64..3.0, side in 0.03f64..0.3,
        model in 0usize..3,
    ) {
        let k = camera();
        let d = [
            Distortion::plumb_bob(-0.12, 0.035, 0.001, -0.0005, 0.0).unwrap(),
            Distortion::rational_polynomial([0.1, -0.02, 0.0006, -0.0004, 0.001, 0.35, 0.01, 0.001]).unwrap(),
            Distortion::equidistant(0.05, -0.01, 0.002, -0.0003).unwrap(),
        ][model];
        let truth = facing(rx, ry, rz, Vector3::new(x, y, z));
        let corners = project(&k, &d, &truth, side);
        let m = PoseSolver::new(k).with_distortion(d).solve_square_marker(&corners, side).unwrap();
        prop_assert!(m.best.pose.rotation_angle_to(&truth) < 1e-6);
        prop_assert!((m.best.pose.translation - truth.translation).norm() < 1e-6 * z);
        prop_assert!(m.best.rms <= m.alternative.rms);
        if let Some(ratio) = m.ambiguity_ratio() {
            prop_assert!(ratio >= 1.0);
        }
    }
}

#[test]
fn a_rectangular_marker_uses_width_along_the_top_edge() {
    let k = camera();
    let truth = facing(0.3, -0.2, 0.4, Vector3::new(0.05, -0.02, 1.2));
    let model = marker_corners(0.14, 0.12).unwrap();
    let corners = model.map(|p| k.project(&truth.transform_point(&p)).unwrap());
    let m = PoseSolver::new(k)
        .solve_marker(&corners, 0.14, 0.12)
        .unwrap();
    assert!(m.best.pose.rotation_angle_to(&truth) < 1e-7);
    // Swapping width and height does not fit.
    let swapped = PoseSolver::new(k)
        .solve_marker(&corners, 0.12, 0.14)
        .unwrap();
    assert!(swapped.best.rms > 1.0, "{}", swapped.best.rms);
}

#[test]
fn bad_input_is_typed() {
    let k = camera();
    let solver = PoseSolver::new(k);
    let good = [
        Point2::new(600.0, 320.0),
        Point2::new(680.0, 320.0),
        Point2::new(680.0, 400.0),
        Point2::new(600.0, 400.0),
    ];
    for side in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        let e = solver.solve_square_marker(&good, side).unwrap_err();
        assert!(matches!(e, PoseError::InvalidMarkerSize { .. }), "{e}");
        assert!(e.to_string().contains("metres"), "{e}");
    }
    let mut bad = good;
    bad[2].x = f64::NAN;
    assert!(matches!(
        solver.solve_square_marker(&bad, 0.1),
        Err(PoseError::NonFinite {
            which: "image",
            index: 2
        })
    ));
    // Three corners on one line: no pose, a typed error rather than NaN.
    let line = [
        Point2::new(600.0, 320.0),
        Point2::new(640.0, 320.0),
        Point2::new(680.0, 320.0),
        Point2::new(600.0, 400.0),
    ];
    match solver.solve_square_marker(&line, 0.1) {
        Err(_) => {}
        Ok(m) => assert!(m.best.rms > 1.0 && m.best.pose.is_finite(), "{m:?}"),
    }
}
