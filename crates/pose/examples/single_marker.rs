//! The pose of one 65 mm square marker seen by a camera with lens distortion, as OpenCV's
//! `solvePnP(..., SOLVEPNP_IPPE_SQUARE)` would give it: corners in OpenCV's order (top-left
//! as printed, then clockwise), marker frame x right, y up, z out of the face.
//!
//! Run with `cargo run -p formation-pose --example single_marker`.

use nalgebra::{Point2, Rotation3, Vector3};
use pose::{Distortion, Intrinsics, Pose, PoseError, PoseSolver, marker_corners};

fn main() -> Result<(), PoseError> {
    // A 640x480 camera (the Duckietown robots' calibration is of this kind) with barrel
    // distortion.
    let k = Intrinsics::square_pixels(320.0, 318.0, 319.5, 239.5)?;
    let lens = Distortion::plumb_bob(-0.25, 0.05, 0.001, -0.0005, 0.0)?;
    let side = 0.065;

    // Where the marker really is: 40 cm ahead, a little left, turned 30 degrees.
    let face_camera = Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let turn = Rotation3::from_axis_angle(&Vector3::y_axis(), 30f64.to_radians());
    let truth = Pose::from_matrix(
        &(face_camera * turn).into_inner(),
        Vector3::new(-0.05, 0.02, 0.4),
    );
    // The corners a detector would report (distorted pixels).
    let mut corners = [Point2::origin(); 4];
    for (c, p) in corners.iter_mut().zip(marker_corners(side, side)?) {
        *c = lens.distort_pixel(&k, &k.project(&truth.transform_point(&p))?);
    }

    let marker = PoseSolver::new(k)
        .with_distortion(lens)
        .solve_square_marker(&corners, side)?;
    let b = &marker.best;
    println!(
        "rotation vector {:.4?} rad, translation {:.4?} m, reprojection {:.2e} px",
        b.pose.rotation.as_slice(),
        b.pose.translation.as_slice(),
        b.rms
    );
    println!(
        "alternative: translation {:.4?} m, reprojection {:.3} px",
        marker.alternative.pose.translation.as_slice(),
        marker.alternative.rms
    );
    println!(
        "translation standard deviations (0.1 px corner noise floor): {:.2?} mm",
        (3..6)
            .map(|i| b.covariance[(i, i)].sqrt() * 1e3)
            .collect::<Vec<_>>()
    );
    println!(
        "error against the truth: {:.2e} rad, {:.2e} m",
        b.pose.rotation_angle_to(&truth),
        (b.pose.translation - truth.translation).norm()
    );
    Ok(())
}
