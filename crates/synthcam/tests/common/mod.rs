//! Scene pieces shared by the tests, examples and benches: the crate itself renders whatever
//! geometry it is given, so the rig and the mount used here are built by hand.
#![allow(dead_code, unreachable_pub)] // each test target uses a different subset
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use synthcam::{FacePlacement, PosedCamera, SynthError};
use unicycle::PlanarPose;

/// Apothem of a regular octagon with side `width`.
pub fn octagon_apothem(width: f64) -> f64 {
    width / (2.0 * (std::f64::consts::PI / 8.0).tan())
}

/// Five faces of an octagon 0.18 m wide, centres 0.30 m up, facing yaw +90, +135, 180,
/// -135, -90 degrees, each `height` tall (a test rig like the tracker's reference rig).
pub fn octagon_faces(height: f64) -> Result<[FacePlacement; 5], SynthError> {
    let (width, a) = (0.18, octagon_apothem(0.18));
    Ok([90.0f64, 135.0, 180.0, -135.0, -90.0].map(|yaw_deg| {
        let (s, c) = yaw_deg.to_radians().sin_cos();
        FacePlacement {
            centre: Point3::new(a * c, a * s, 0.30),
            normal: Vector3::new(c, s, 0.0),
            up: Vector3::z(),
            width,
            height,
        }
    }))
}

/// PosedCamera -> body of a camera `d` ahead of the reference point at `height`, panned `pan`
/// (left positive) and tilted `tilt` (down positive); level, it looks along body x with image
/// x = body -y and image y = body -z.
pub fn mount(d: f64, height: f64, pan: f64, tilt: f64) -> Isometry3<f64> {
    let r0 = Rotation3::from_matrix_unchecked(Matrix3::new(
        0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
    ));
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), pan)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), tilt)
        * r0;
    Isometry3::from_parts(
        Translation3::new(d, 0.0, height),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// `pose`'s intrinsics from a horizontal field of view in degrees.
pub fn intrinsics(w: usize, h: usize, hfov_deg: f64) -> pose::Intrinsics {
    pose::Intrinsics::from_hfov(hfov_deg.to_radians(), w as u32, h as u32).unwrap()
}

/// A `w x h` camera with the given field of view (degrees) on a robot at `robot`.
pub fn camera(
    w: usize,
    h: usize,
    hfov_deg: f64,
    mount: &Isometry3<f64>,
    robot: PlanarPose,
) -> Result<PosedCamera, SynthError> {
    PosedCamera::on_robot(intrinsics(w, h, hfov_deg), w, h, mount, &robot)
}
