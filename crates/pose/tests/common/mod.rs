//! Shared scenes for the integration tests: the reference marker face and three octagon faces.
#![allow(dead_code)]

use nalgebra::{Point2, Point3, Rotation3, Vector3};
use pose::{Intrinsics, Pose};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// Marker width and height (spec 3.3: 140 mm x 120 mm).
pub const MARKER_W: f64 = 0.14;
pub const MARKER_H: f64 = 0.12;
/// Octagon face width (spec 3.3).
pub const FACE_W: f64 = 0.18;
/// Marker centre height on the rig (spec 3.3).
pub const MARKER_Z: f64 = 0.30;

/// The reference camera: 640x480, 60 degree horizontal field of view.
pub fn camera() -> Intrinsics {
    Intrinsics::from_hfov(60f64.to_radians(), 640, 480).expect("valid camera")
}

/// One marker face in its own frame (x right, y down, z = 0 into the face), corners clockwise
/// from the top left as seen by a camera looking along +z.
pub fn face_model() -> [Point3<f64>; 4] {
    let (w, h) = (MARKER_W / 2.0, MARKER_H / 2.0);
    [
        Point3::new(-w, -h, 0.0),
        Point3::new(w, -h, 0.0),
        Point3::new(w, h, 0.0),
        Point3::new(-w, h, 0.0),
    ]
}

/// Corners (4 per face) of the markers on three adjacent faces of a regular octagon with
/// 0.18 m faces, in the rig body frame (x forward, y left, z up): outward normals at yaw
/// 135, 180 and -135 degrees (faces 2, 3, 4 of spec 3.3), 45 degrees apart.
pub fn three_faces_model() -> Vec<Point3<f64>> {
    let apothem = FACE_W / (2.0 * (std::f64::consts::PI / 8.0).tan());
    let mut pts = Vec::with_capacity(12);
    for yaw_deg in [135.0f64, 180.0, -135.0] {
        let yaw = yaw_deg.to_radians();
        let n = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
        let tangent = Vector3::z().cross(&n); // horizontal, along the face
        let c = n * apothem + Vector3::new(0.0, 0.0, MARKER_Z);
        for (a, b) in [(-1.0, 1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
            pts.push(Point3::from(
                c + tangent * (a * MARKER_W / 2.0) + Vector3::z() * (b * MARKER_H / 2.0),
            ));
        }
    }
    pts
}

/// A random rotation of at most `max_tilt` radians about a random axis perpendicular to the
/// optical axis, then a random roll about it: the face normal stays within `max_tilt` of the
/// line of sight direction.
pub fn random_face_pose(rng: &mut ChaCha8Rng, depth: (f64, f64), max_tilt: f64) -> Pose {
    random_face_pose_tilted(rng, depth, (0.0, max_tilt))
}

/// As [`random_face_pose`] with the tilt (angle between the face normal and the optical axis)
/// drawn uniformly from `tilt` (radians).
pub fn random_face_pose_tilted(rng: &mut ChaCha8Rng, depth: (f64, f64), tilt: (f64, f64)) -> Pose {
    let z = rng.random_range(depth.0..depth.1);
    // Keep the face centre well inside the image: |x/z| < 0.35, |y/z| < 0.25.
    let x = rng.random_range(-0.35..0.35) * z;
    let y = rng.random_range(-0.25..0.25) * z;
    let tilt = rng.random_range(tilt.0..tilt.1);
    let phi = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let roll = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), roll)
        * Rotation3::from_scaled_axis(Vector3::new(phi.cos(), phi.sin(), 0.0) * tilt);
    Pose::from_matrix(r.matrix(), Vector3::new(x, y, z))
}

/// A random pose of the octagon rig seen from behind by a camera: leader yaw within
/// +-50 degrees, small pitch and roll, 0.8 m to 3 m away.
pub fn random_rig_pose(rng: &mut ChaCha8Rng) -> Pose {
    // Body axes in the camera frame: forward = +z, left = -x, up = -y.
    let base = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
        0.0, -1.0, 0.0, //
        0.0, 0.0, -1.0, //
        1.0, 0.0, 0.0,
    ));
    let yaw = rng.random_range(-50f64..50.0).to_radians();
    let pitch = rng.random_range(-8f64..8.0).to_radians();
    let roll = rng.random_range(-8f64..8.0).to_radians();
    let r = base * Rotation3::from_euler_angles(roll, pitch, yaw);
    let z = rng.random_range(0.8..3.0);
    let x = rng.random_range(-0.25..0.25) * z;
    let y = rng.random_range(-0.1..0.2) * z;
    Pose::from_matrix(r.matrix(), Vector3::new(x, y, z))
}

/// Noise-free pixels of the model under `pose`.
pub fn project_all(k: &Intrinsics, pose: &Pose, model: &[Point3<f64>]) -> Vec<Point2<f64>> {
    model
        .iter()
        .map(|p| {
            k.project(&pose.transform_point(p))
                .expect("model in front of the camera")
        })
        .collect()
}

/// Largest translation difference.
pub fn translation_error(a: &Pose, b: &Pose) -> f64 {
    (a.translation - b.translation).norm()
}
