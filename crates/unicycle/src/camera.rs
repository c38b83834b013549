//! The camera mount, and the measurement transform of spec 2.5: from a leader's pose in the
//! camera frame to the formation variables `(l12, alpha12, beta12)`.
//!
//! The paper writes the transform for a level camera at marker height
//! (`theta_t = atan2(-x_c, z_c)`, `l12 = sqrt(x_c^2 + z_c^2)`, `alpha12 = theta_t - theta_m`,
//! `beta12 = theta_p + theta_t`). We go through the full mount instead (spec 2.5, *beyond*):
//! the leader's pose is carried from the camera frame into the follower's body frame through
//! the mount (offset `d` ahead of the reference point, height, pan, tilt), and the planar
//! formation variables of spec 2.3 are read there, measured from the camera point
//! `(d, 0)` of the follower's body frame. For a level camera this reduces exactly to the
//! paper's formulas; for a tilted or raised camera it stays right where they do not.
//!
//! Frames (spec 2.1): body frames x forward, y left, z up; the camera frame is OpenCV's
//! (x right, y down, z along the optical axis).

use nalgebra::{Matrix3, Rotation3, SVector, Vector3};

use crate::angle::wrap_angle;

/// Where and how the camera sits on the follower.
/// With the `serde` feature it reads and writes as `{offset, height, pan, tilt}`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CameraMount {
    /// Distance of the camera's optical centre ahead of the follower's reference point, in
    /// metres (the paper's `d`).
    pub offset: f64,
    /// Height of the optical centre above the ground, in metres.
    pub height: f64,
    /// Pan: rotation of the camera about the follower's vertical axis, radians, left positive
    /// (the paper's `theta_p`).
    pub pan: f64,
    /// Tilt: rotation of the optical axis below the horizontal, radians, down positive.
    pub tilt: f64,
}

impl Default for CameraMount {
    /// The reference mount: 0.5 m ahead, at the markers' centre height (0.30 m), level,
    /// looking straight ahead.
    fn default() -> Self {
        Self {
            offset: 0.5,
            height: 0.30,
            pan: 0.0,
            tilt: 0.0,
        }
    }
}

/// Axes of a level, unpanned camera expressed in the body frame: the camera's x (right) is
/// the body's -y, its y (down) is the body's -z, its z (optical axis) is the body's x.
fn level_camera_axes() -> Matrix3<f64> {
    Matrix3::new(
        0.0, 0.0, 1.0, //
        -1.0, 0.0, 0.0, //
        0.0, -1.0, 0.0,
    )
}

impl CameraMount {
    /// Rotation taking camera-frame vectors to the follower's body frame.
    pub fn camera_to_body_rotation(&self) -> Rotation3<f64> {
        let pan = Rotation3::from_axis_angle(&Vector3::z_axis(), self.pan);
        // A positive rotation about the body's y (left) axis turns x (forward) downwards.
        let tilt = Rotation3::from_axis_angle(&Vector3::y_axis(), self.tilt);
        pan * tilt * Rotation3::from_matrix_unchecked(level_camera_axes())
    }

    /// Position of the optical centre in the follower's body frame.
    pub fn camera_position(&self) -> Vector3<f64> {
        Vector3::new(self.offset, 0.0, self.height)
    }

    /// The rotation and translation taking the body frame of a leader standing on the floor
    /// at `(x, y)` with heading `theta` (metres, radians, in the follower's body frame) into
    /// this camera's frame: the pose a solver would report for the leader's rig.
    pub fn leader_to_camera(&self, x: f64, y: f64, theta: f64) -> (Rotation3<f64>, Vector3<f64>) {
        let body_to_cam = self.camera_to_body_rotation().inverse();
        let yaw = Rotation3::from_axis_angle(&Vector3::z_axis(), theta);
        let t_body = Vector3::new(x, y, 0.0) - self.camera_position();
        (body_to_cam * yaw, body_to_cam * t_body)
    }

    /// Whether every field is a finite number.
    pub fn is_finite(&self) -> bool {
        self.offset.is_finite()
            && self.height.is_finite()
            && self.pan.is_finite()
            && self.tilt.is_finite()
    }
}

/// Errors of the measurement transform.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeasurementError {
    /// A pose or mount entry is NaN or infinite.
    #[error("non-finite {what} in the measurement transform")]
    NonFinite {
        /// Which input was not finite.
        what: &'static str,
    },
    /// The leader's reference point coincides with the camera point on the ground plane, so
    /// the bearings are undefined (spec 2.4: the model is singular at `l12 = 0`).
    #[error("leader at planar distance {l12:.3e} m from the camera point: bearings undefined")]
    Coincident {
        /// The planar distance found.
        l12: f64,
    },
}

/// Smallest planar distance for which the bearings are defined (1 mm).
pub const MIN_L12: f64 = 1e-3;

/// The formation variables of a leader seen by the follower's camera:
/// `[l12, alpha12, beta12]`.
///
/// `rotation` and `translation` take the leader's body frame (the rig frame: x forward, y
/// left, z up, origin at its reference point on the ground) into the camera frame.
pub fn formation_from_camera_pose(
    rotation: &Rotation3<f64>,
    translation: &Vector3<f64>,
    mount: &CameraMount,
) -> Result<SVector<f64, 3>, MeasurementError> {
    if !translation.iter().all(|v| v.is_finite())
        || !rotation.matrix().iter().all(|v| v.is_finite())
    {
        return Err(MeasurementError::NonFinite {
            what: "leader pose",
        });
    }
    if !mount.is_finite() {
        return Err(MeasurementError::NonFinite {
            what: "camera mount",
        });
    }
    let cam_to_body = mount.camera_to_body_rotation();
    // Leader reference point relative to the camera point, in the follower's body frame.
    let rel = cam_to_body * translation;
    let l12 = rel.x.hypot(rel.y);
    if l12 < MIN_L12 {
        return Err(MeasurementError::Coincident { l12 });
    }
    let beta12 = rel.y.atan2(rel.x);
    // The leader's forward axis in the follower's body frame gives its relative heading.
    let leader_x = cam_to_body * rotation * Vector3::x();
    let heading = leader_x.y.atan2(leader_x.x);
    let alpha12 = wrap_angle(beta12 - heading);
    Ok(SVector::<f64, 3>::new(l12, alpha12, beta12))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Pose of a planar body `(x, y, theta)` as (rotation, translation) into the world.
    fn planar(x: f64, y: f64, theta: f64) -> (Rotation3<f64>, Vector3<f64>) {
        (
            Rotation3::from_axis_angle(&Vector3::z_axis(), theta),
            Vector3::new(x, y, 0.0),
        )
    }

    /// Spec 2.3 from world poses, written out independently of the code under test.
    fn formation_2_3(q1: (f64, f64, f64), q2: (f64, f64, f64), d: f64) -> [f64; 3] {
        let x2c = q2.0 + d * q2.2.cos();
        let y2c = q2.1 + d * q2.2.sin();
        let l12 = (q1.0 - x2c).hypot(q1.1 - y2c);
        let zeta = (q1.1 - y2c).atan2(q1.0 - x2c);
        [l12, wrap_angle(zeta - q1.2), wrap_angle(zeta - q2.2)]
    }

    fn camera_pose_of_leader(
        q1: (f64, f64, f64),
        q2: (f64, f64, f64),
        mount: &CameraMount,
    ) -> (Rotation3<f64>, Vector3<f64>) {
        let (r1, t1) = planar(q1.0, q1.1, q1.2);
        let (r2, t2) = planar(q2.0, q2.1, q2.2);
        // World pose of the camera.
        let r_wc = r2 * mount.camera_to_body_rotation();
        let t_wc = t2 + r2 * mount.camera_position();
        let r_cw = r_wc.inverse();
        (r_cw * r1, r_cw * (t1 - t_wc))
    }

    fn angle_close(a: f64, b: f64, tol: f64) -> bool {
        wrap_angle(a - b).abs() <= tol
    }

    proptest! {
        /// `leader_to_camera` is the camera pose of a leader seen by a follower at the origin.
        #[test]
        fn leader_to_camera_is_the_pose_from_the_origin(
            x in -5.0..5.0f64, y in -5.0..5.0f64, th in -3.1..3.1f64,
            d in 0.0..0.8f64, h in 0.0..1.0f64, pan in -1.0..1.0f64, tilt in -0.5..0.5f64,
        ) {
            let mount = CameraMount { offset: d, height: h, pan, tilt };
            let (r, t) = mount.leader_to_camera(x, y, th);
            let (rw, tw) = camera_pose_of_leader((x, y, th), (0.0, 0.0, 0.0), &mount);
            prop_assert!((r.matrix() - rw.matrix()).norm() < 1e-12);
            prop_assert!((t - tw).norm() < 1e-12);
        }

        /// Spec 2.5: for random poses and mounts, the path camera pose -> mount -> 2.3 gives
        /// the same formation variables as 2.3 applied to the world poses.
        #[test]
        fn mount_path_equals_world_formula(
            x1 in -5.0..5.0f64, y1 in -5.0..5.0f64, th1 in -3.1..3.1f64,
            x2 in -5.0..5.0f64, y2 in -5.0..5.0f64, th2 in -3.1..3.1f64,
            d in 0.0..0.8f64, h in 0.0..1.0f64, pan in -1.0..1.0f64, tilt in -0.5..0.5f64,
        ) {
            let mount = CameraMount { offset: d, height: h, pan, tilt };
            let q1 = (x1, y1, th1);
            let q2 = (x2, y2, th2);
            let want = formation_2_3(q1, q2, d);
            prop_assume!(want[0] > 0.05);
            let (r, t) = camera_pose_of_leader(q1, q2, &mount);
            let got = formation_from_camera_pose(&r, &t, &mount).unwrap();
            prop_assert!((got[0] - want[0]).abs() < 1e-9, "l12 {} vs {}", got[0], want[0]);
            prop_assert!(angle_close(got[1], want[1], 1e-9), "alpha12 {} vs {}", got[1], want[1]);
            prop_assert!(angle_close(got[2], want[2], 1e-9), "beta12 {} vs {}", got[2], want[2]);
        }
    }

    /// The paper's level-camera formulas are the special case of a level mount.
    #[test]
    fn level_camera_matches_paper_formulas() {
        let mount = CameraMount {
            offset: 0.5,
            height: 0.3,
            pan: 0.2,
            tilt: 0.0,
        };
        let (r, t) = camera_pose_of_leader((2.0, 0.7, 0.4), (0.0, 0.0, 0.0), &mount);
        let got = formation_from_camera_pose(&r, &t, &mount).unwrap();
        let theta_t = (-t.x).atan2(t.z);
        let l12 = t.x.hypot(t.z);
        let leader_x_in_cam = r * Vector3::x();
        // Relative heading seen in the camera: the leader's forward axis projected on the
        // camera's x-z plane, measured left positive from the optical axis.
        let theta_m = (-leader_x_in_cam.x).atan2(leader_x_in_cam.z);
        assert!((got[0] - l12).abs() < 1e-12);
        assert!(angle_close(got[1], theta_t - theta_m, 1e-12));
        assert!(angle_close(got[2], mount.pan + theta_t, 1e-12));
    }

    #[test]
    fn rejects_non_finite_and_coincident() {
        let mount = CameraMount::default();
        let r = Rotation3::identity();
        assert!(matches!(
            formation_from_camera_pose(&r, &Vector3::new(f64::NAN, 0.0, 1.0), &mount),
            Err(MeasurementError::NonFinite { .. })
        ));
        let bad_mount = CameraMount {
            pan: f64::INFINITY,
            ..mount
        };
        assert!(matches!(
            formation_from_camera_pose(&r, &Vector3::new(0.0, 0.0, 1.0), &bad_mount),
            Err(MeasurementError::NonFinite { .. })
        ));
        // Straight above or below the camera: planar distance zero.
        assert!(matches!(
            formation_from_camera_pose(&r, &Vector3::new(0.0, 0.4, 0.0), &mount),
            Err(MeasurementError::Coincident { .. })
        ));
    }
}
