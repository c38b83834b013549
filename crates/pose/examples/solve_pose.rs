//! Pose of one marker face and of three octagon faces from noisy pixels, with both planar
//! candidates, the covariance, and a calibration file.
//!
//! Run: `cargo run -p formation-pose --example solve_pose`

use nalgebra::{Point2, Point3, Vector3};
use pose::{Intrinsics, Pose, PoseSolver};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The reference camera: 640x480, 60 degree horizontal field of view.
    let k = Intrinsics::from_hfov(60f64.to_radians(), 640, 480)?;
    let solver = PoseSolver::new(k);

    // One 140 mm x 120 mm marker, corners in its own frame (metres), seen at 1 m, tilted 35 deg.
    let face = [
        Point3::new(-0.07, -0.06, 0.0),
        Point3::new(0.07, -0.06, 0.0),
        Point3::new(0.07, 0.06, 0.0),
        Point3::new(-0.07, 0.06, 0.0),
    ];
    let truth = Pose::new(
        Vector3::new(0.0, 35f64.to_radians(), 0.0),
        Vector3::new(0.1, 0.05, 1.0),
    );
    // A fixed pattern of +-0.3 px errors stands in for detector noise.
    let wobble = [(0.3, -0.2), (-0.25, 0.3), (0.2, 0.25), (-0.3, -0.3)];
    let pixels: Vec<Point2<f64>> = face
        .iter()
        .zip(wobble)
        .map(|(p, (du, dv))| {
            k.project(&truth.transform_point(p))
                .map(|m| Point2::new(m.x + du, m.y + dv))
        })
        .collect::<Result<_, _>>()?;

    let sol = solver.solve(&face, &pixels)?;
    println!("one face (coplanar: {})", sol.coplanar);
    report("  best       ", &sol.best.pose, &truth, sol.best.rms);
    if let Some(alt) = sol.alternative {
        report("  alternative", &alt.pose, &truth, alt.rms);
    }
    match sol.ambiguity_ratio() {
        Some(r) => println!("  ambiguity ratio (alternative rms / best rms): {r:.2}"),
        None => println!("  both candidates converged to the same pose"),
    }
    let sd: Vec<String> = (0..6)
        .map(|i| format!("{:.2e}", sol.best.covariance[(i, i)].sqrt()))
        .collect();
    println!(
        "  standard deviations [wx wy wz tx ty tz]: {}",
        sd.join(" ")
    );

    // Three faces of the octagon rig (12 corners), rig frame x forward, y left, z up.
    let apothem = 0.09 / (std::f64::consts::PI / 8.0).tan();
    let mut rig = Vec::new();
    for yaw in [135f64, 180.0, -135.0] {
        let n = Vector3::new(yaw.to_radians().cos(), yaw.to_radians().sin(), 0.0);
        let tangent = Vector3::z().cross(&n);
        let c = n * apothem + Vector3::new(0.0, 0.0, 0.3);
        for (a, b) in [(-1.0, 1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
            rig.push(Point3::from(
                c + tangent * (0.07 * a) + Vector3::z() * (0.06 * b),
            ));
        }
    }
    // Leader 1.8 m ahead, turned 20 degrees, seen from behind (body x -> camera z).
    let base = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
        0.0, -1.0, 0.0, //
        0.0, 0.0, -1.0, //
        1.0, 0.0, 0.0,
    ));
    let r = base * nalgebra::Rotation3::from_euler_angles(0.0, 0.0, 20f64.to_radians());
    let rig_truth = Pose::from_matrix(r.matrix(), Vector3::new(-0.2, 0.25, 1.8));
    let rig_pixels: Vec<Point2<f64>> = rig
        .iter()
        .map(|p| k.project(&rig_truth.transform_point(p)))
        .collect::<Result<_, _>>()?;
    let sol = solver.solve(&rig, &rig_pixels)?;
    println!("three faces (coplanar: {})", sol.coplanar);
    report("  POSIT + LM ", &sol.best.pose, &rig_truth, sol.best.rms);

    // A tracker refines its prediction instead of starting over.
    let predicted = Pose::new(
        rig_truth.rotation + Vector3::new(0.02, -0.03, 0.01),
        rig_truth.translation + Vector3::new(0.03, 0.0, -0.05),
    );
    let refined = solver.refine(&rig, &rig_pixels, &predicted)?;
    report("  refined    ", &refined.pose, &rig_truth, refined.rms);

    // Camera files (feature `calib`).
    #[cfg(feature = "calib")]
    {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/calibration/opencv_640x480.yaml"
        );
        let cal = pose::Camera::from_file(path)?;
        let with_lens = PoseSolver::new(cal.intrinsics).with_distortion(cal.distortion);
        let distorted: Vec<Point2<f64>> = rig
            .iter()
            .map(|p| cal.project(&rig_truth.transform_point(p)))
            .collect::<Result<_, _>>()?;
        let sol = with_lens.solve(&rig, &distorted)?;
        println!("with the calibration in opencv_640x480.yaml");
        report("  undistorted", &sol.best.pose, &rig_truth, sol.best.rms);
    }
    Ok(())
}

fn report(label: &str, pose: &Pose, truth: &Pose, rms: f64) {
    println!(
        "{label}: rotation error {:.3} deg, translation error {:.2} mm, rms {:.3} px",
        pose.rotation_angle_to(truth).to_degrees(),
        (pose.translation - truth.translation).norm() * 1000.0,
        rms
    );
}
