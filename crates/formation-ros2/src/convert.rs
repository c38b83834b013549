//! From messages to what the pipeline takes (grey pixels, a calibration, the follower's
//! inputs), and from the tracker's report to messages.
//!
//! Input conversions go through the same functions as `track` on a bag
//! (`formation_io::bag::pixels`), so that a frame gives the same pixels whether it was
//! recorded or received live.

use formation_io::bag::{cdr, pixels};
use formation_io::frames::GreyImage;
use formation_tracker::mount::CameraMount;
use formation_tracker::tracker::{LeaderReport, Status};
use nalgebra::{Matrix3, Rotation3, SMatrix, UnitQuaternion, Vector3};
use unicycle::{Formation, PlanarPose};

use crate::Ros2Error;
use crate::msg;

/// Decodes a raw image into `grey` (any encoding `track` reads from bags).
///
/// # Errors
/// [`Ros2Error::Message`] naming the field: an unsupported encoding, a size over
/// `max_side`, or a step or data length that does not match the size.
pub fn image_to_grey(
    img: &msg::Image,
    grey: &mut GreyImage,
    max_side: usize,
) -> Result<(), Ros2Error> {
    let view = cdr::Image {
        stamp_ns: 0,
        frame_id: String::new(),
        height: img.height,
        width: img.width,
        encoding: img.encoding.clone(),
        is_bigendian: img.is_bigendian != 0,
        step: img.step,
        data: &img.data.0,
    };
    pixels::raw_to_grey(&view, grey, max_side).map_err(|e| message("Image", e))
}

/// Decodes a compressed image (JPEG or PNG) into `grey`.
///
/// # Errors
/// [`Ros2Error::Message`]: another format, or data that does not decode.
pub fn compressed_to_grey(
    img: &msg::CompressedImage,
    grey: &mut GreyImage,
    max_side: usize,
) -> Result<(), Ros2Error> {
    let view = cdr::CompressedImage {
        stamp_ns: 0,
        format: img.format.clone(),
        data: &img.data.0,
    };
    pixels::compressed_to_grey(&view, grey, max_side).map_err(|e| message("CompressedImage", e))
}

/// The calibration of a `CameraInfo`, with the checks of a `camera_info` file.
///
/// # Errors
/// [`Ros2Error::Message`]: a zero or non-finite focal length, an unknown distortion model,
/// and everything else `pose` refuses.
pub fn calibration(info: &msg::CameraInfo) -> Result<pose::Camera, Ros2Error> {
    let view = cdr::CameraInfo {
        stamp_ns: 0,
        height: info.height,
        width: info.width,
        distortion_model: info.distortion_model.clone(),
        d: info.d.clone(),
        k: info.k.0,
    };
    pixels::calibration(&view).map_err(|e| message("CameraInfo", e))
}

/// The `CameraInfo` of a calibration (what a camera driver publishes): `K`, `D` and the
/// distortion model, `R` the identity and `P = [K | 0]`.
pub fn camera_info(camera: &pose::Camera, header: msg::Header) -> msg::CameraInfo {
    let k = camera.intrinsics.matrix();
    let mut kk = [0.0; 9];
    let mut p = [0.0; 12];
    for r in 0..3 {
        for c in 0..3 {
            kk[r * 3 + c] = k[(r, c)];
            p[r * 4 + c] = k[(r, c)];
        }
    }
    msg::CameraInfo {
        header,
        height: camera.height,
        width: camera.width,
        distortion_model: camera.distortion.model().name().to_owned(),
        d: camera.distortion.coefficients(),
        k: msg::F64Array(kk),
        r: msg::F64Array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
        p: msg::F64Array(p),
        ..msg::CameraInfo::default()
    }
}

/// The follower's own `(v2, w2)` from a twist, checked as `track` checks a bag's.
///
/// # Errors
/// [`Ros2Error::Message`]: a non-finite value, or one outside a follower's range.
pub fn follower_inputs(kind: &'static str, twist: &msg::Twist) -> Result<(f64, f64), Ros2Error> {
    let s = cdr::TwistSample::checked(None, twist.linear.x, twist.angular.z)
        .map_err(|e| message(kind, e))?;
    Ok((s.v, s.w))
}

fn message(kind: &'static str, reason: String) -> Ros2Error {
    Ros2Error::Message { kind, reason }
}

/// The frames the published messages are expressed in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameIds {
    /// The follower's body frame (x forward, y left, z up, origin at its reference point
    /// on the ground): `base_link` by default.
    pub base: String,
    /// The camera's optical frame (x right, y down, z forward): the image's
    /// `header.frame_id`.
    pub camera: String,
    /// Prefix of each leader's body frame: `leader_` gives `leader_1`, `leader_2`, ...
    pub leader_prefix: String,
}

impl FrameIds {
    /// The body frame of leader `robot`.
    pub fn leader(&self, robot: u32) -> String {
        format!("{}{robot}", self.leader_prefix)
    }
}

/// What the node publishes for one leader in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LeaderMessages {
    /// The leader's body pose in the camera's optical frame.
    pub pose_camera: msg::PoseWithCovarianceStamped,
    /// The leader's body pose in the follower's body frame.
    pub pose_base: msg::PoseWithCovarianceStamped,
    /// The leader's speed and turn rate, in its own body frame.
    pub twist: msg::TwistWithCovarianceStamped,
    /// The formation variables and velocities with their covariance ([`variables`]).
    pub variables: msg::Float64MultiArray,
    /// The follower's body frame to the leader's, for `/tf`.
    pub transform: msg::TransformStamped,
}

/// The rows and columns of the formation message ([`variables`]).
pub const VARIABLES_COLUMNS: [&str; 5] = ["l12", "alpha12", "beta12", "v1", "w1"];

/// Status codes in row 0 of the formation message.
pub fn status_code(status: Status) -> f64 {
    match status {
        Status::Tracking => 0.0,
        Status::Coasting => 1.0,
        Status::Lost => 2.0,
    }
}

/// The formation message: a `Float64MultiArray` of 7 rows by 5 columns, row-major.
///
/// - row 0: `[stamp_s, robot, status, since_seen_s, l12_std]`: the image's stamp in
///   seconds since the epoch, the leader's id, 0 tracking / 1 coasting / 2 lost, seconds
///   since the last accepted measurement, and the standard deviation of `l12` (m);
/// - row 1: the estimate `[l12 (m), alpha12 (rad), beta12 (rad), v1 (m/s), w1 (rad/s)]`;
/// - rows 2 to 6: its 5 x 5 covariance, row by row, in the same order.
///
/// The layout's two dimensions say so (`rows: stamp_robot_status_since_std, estimate,
/// covariance x5` and `l12,alpha12,beta12,v1,w1`).
pub fn variables(report: &LeaderReport, stamp: msg::Time) -> msg::Float64MultiArray {
    let f = &report.formation;
    let stamp_s = f64::from(stamp.sec) + f64::from(stamp.nanosec) * 1e-9;
    let mut data = vec![
        stamp_s,
        f64::from(report.robot),
        status_code(report.status),
        report.since_seen,
        report.l12_std,
        f.l12,
        f.alpha12,
        f.beta12,
        report.v1,
        report.w1,
    ];
    for row in &report.covariance {
        data.extend_from_slice(row);
    }
    msg::Float64MultiArray {
        layout: msg::MultiArrayLayout {
            dim: vec![
                msg::MultiArrayDimension {
                    label: "rows: stamp_robot_status_since_std, estimate, covariance x5".into(),
                    size: 7,
                    stride: 35,
                },
                msg::MultiArrayDimension {
                    label: VARIABLES_COLUMNS.join(","),
                    size: 5,
                    stride: 5,
                },
            ],
            data_offset: 0,
        },
        data,
    }
}

/// The leader's body pose in the follower's body frame, from the formation variables.
fn base_pose(f: &Formation, d: f64) -> Result<PlanarPose, Ros2Error> {
    f.leader_pose(&PlanarPose::default(), d)
        .map_err(|e| Ros2Error::Estimate(format!("the leader's pose: {e}")))
}

/// A pose as (rotation, translation) of a parent frame.
type Pose3 = (Rotation3<f64>, Vector3<f64>);

/// The 6-vector difference of two nearby poses: translation, then the small rotation taking
/// `b` to `a` as a rotation vector in the parent frame (from the skew part of the relative
/// rotation: exact to second order, where an arccosine loses half the digits of a
/// microradian angle).
fn pose_delta(a: &Pose3, b: &Pose3) -> [f64; 6] {
    let t = a.1 - b.1;
    let m = (a.0 * b.0.inverse()).into_inner();
    let r = Vector3::new(
        m[(2, 1)] - m[(1, 2)],
        m[(0, 2)] - m[(2, 0)],
        m[(1, 0)] - m[(0, 1)],
    ) * 0.5;
    [t.x, t.y, t.z, r.x, r.y, r.z]
}

/// The 6x6 covariance of `pose_of(formation)` by central differences over `(l12, alpha12,
/// beta12)`: `J C J^T`.
fn pose_covariance(
    f: &Formation,
    c: &Matrix3<f64>,
    pose_of: impl Fn(&Formation) -> Result<Pose3, Ros2Error>,
) -> Result<[f64; 36], Ros2Error> {
    let mut j = SMatrix::<f64, 6, 3>::zeros();
    for i in 0..3 {
        let h = 1e-5;
        let shifted = |s: f64| {
            let mut g = *f;
            match i {
                0 => g.l12 += s,
                1 => g.alpha12 += s,
                _ => g.beta12 += s,
            }
            pose_of(&g)
        };
        let (plus, minus) = (shifted(h)?, shifted(-h)?);
        let d = pose_delta(&plus, &minus);
        for (r, v) in d.iter().enumerate() {
            j[(r, i)] = v / (2.0 * h);
        }
    }
    let cov = j * c * j.transpose();
    let mut out = [0.0; 36];
    for r in 0..6 {
        for k in 0..6 {
            out[r * 6 + k] = 0.5 * (cov[(r, k)] + cov[(k, r)]);
        }
    }
    Ok(out)
}

fn quaternion(r: &Rotation3<f64>) -> msg::Quaternion {
    let q = UnitQuaternion::from_rotation_matrix(r);
    msg::Quaternion {
        x: q.i,
        y: q.j,
        z: q.k,
        w: q.w,
    }
}

fn vector(v: &Vector3<f64>) -> msg::Vector3 {
    msg::Vector3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

/// Everything published for `report` at `stamp`, the camera mounted as `mount`.
///
/// Poses are of the leader's body frame (its reference point on the ground, x forward);
/// their covariance is the formation covariance carried through the geometry (z, roll and
/// pitch follow from the ground plane, so their variances come only through the camera's
/// tilt and pan).
///
/// # Errors
/// [`Ros2Error::Estimate`] for an estimate that gives no pose (non-finite values, or
/// `l12` at or below 1 mm).
pub fn leader_messages(
    report: &LeaderReport,
    mount: &CameraMount,
    stamp: msg::Time,
    frames: &FrameIds,
) -> Result<LeaderMessages, Ros2Error> {
    let f = report.formation;
    let c = Matrix3::from_fn(|r, k| report.covariance[r][k]);
    if !c.iter().all(|v| v.is_finite()) || !report.v1.is_finite() || !report.w1.is_finite() {
        return Err(Ros2Error::Estimate(format!(
            "robot {}: a non-finite velocity or covariance",
            report.robot
        )));
    }
    let d = mount.offset;
    let in_base = |g: &Formation| -> Result<Pose3, Ros2Error> {
        let p = base_pose(g, d)?;
        Ok((
            Rotation3::from_axis_angle(&Vector3::z_axis(), p.theta),
            Vector3::new(p.x, p.y, 0.0),
        ))
    };
    let in_camera = |g: &Formation| -> Result<Pose3, Ros2Error> {
        let p = base_pose(g, d)?;
        Ok(mount.leader_to_camera(p.x, p.y, p.theta))
    };
    let header = |frame_id: &str| msg::Header {
        stamp,
        frame_id: frame_id.to_owned(),
    };
    let stamped =
        |frame_id: &str, pose: &Pose3, covariance: [f64; 36]| msg::PoseWithCovarianceStamped {
            header: header(frame_id),
            pose: msg::PoseWithCovariance {
                pose: msg::Pose {
                    position: vector(&pose.1),
                    orientation: quaternion(&pose.0),
                },
                covariance: msg::F64Array(covariance),
            },
        };
    let base = in_base(&f)?;
    let camera = in_camera(&f)?;
    let pose_base = stamped(&frames.base, &base, pose_covariance(&f, &c, in_base)?);
    let pose_camera = stamped(&frames.camera, &camera, pose_covariance(&f, &c, in_camera)?);
    let leader = frames.leader(report.robot);
    let mut twist_cov = [0.0; 36];
    twist_cov[0] = report.covariance[3][3];
    twist_cov[5] = report.covariance[3][4];
    twist_cov[30] = report.covariance[4][3];
    twist_cov[35] = report.covariance[4][4];
    let twist = msg::TwistWithCovarianceStamped {
        header: header(&leader),
        twist: msg::TwistWithCovariance {
            twist: msg::Twist {
                linear: msg::Vector3 {
                    x: report.v1,
                    ..msg::Vector3::default()
                },
                angular: msg::Vector3 {
                    z: report.w1,
                    ..msg::Vector3::default()
                },
            },
            covariance: msg::F64Array(twist_cov),
        },
    };
    let transform = msg::TransformStamped {
        header: header(&frames.base),
        child_frame_id: leader,
        transform: msg::Transform {
            translation: vector(&base.1),
            rotation: quaternion(&base.0),
        },
    };
    Ok(LeaderMessages {
        pose_camera,
        pose_base,
        twist,
        variables: variables(report, stamp),
        transform,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use formation_tracker::tracker::MeasurementUse;

    fn report(l12: f64, alpha12: f64, beta12: f64) -> LeaderReport {
        let mut covariance = [[0.0; 5]; 5];
        let stds = [0.01, 0.02, 0.005, 0.05, 0.1];
        for (i, s) in stds.iter().enumerate() {
            covariance[i][i] = s * s;
        }
        covariance[0][1] = 1e-5;
        covariance[1][0] = 1e-5;
        LeaderReport {
            robot: 3,
            status: Status::Tracking,
            measurement: MeasurementUse::Updated,
            lost: None,
            hypotheses: 1,
            candidate: None,
            nis: Some(1.0),
            formation: Formation {
                l12,
                alpha12,
                beta12,
            },
            v1: 0.3,
            w1: -0.1,
            l12_std: stds[0],
            alpha12_std: stds[1],
            beta12_std: stds[2],
            v1_std: stds[3],
            w1_std: stds[4],
            covariance,
            since_seen: 0.0,
        }
    }

    fn frames() -> FrameIds {
        FrameIds {
            base: "base_link".into(),
            camera: "camera".into(),
            leader_prefix: "leader_".into(),
        }
    }

    #[test]
    fn a_leader_straight_ahead_is_on_the_optical_axis() {
        let mount = CameraMount::default();
        let m = leader_messages(
            &report(1.5, 0.0, 0.0),
            &mount,
            msg::Time::from_ns(7),
            &frames(),
        )
        .unwrap();
        let p = m.pose_base.pose.pose.position;
        assert!(
            (p.x - (mount.offset + 1.5)).abs() < 1e-12 && p.y.abs() < 1e-12,
            "{p:?}"
        );
        // Camera frame: z forward, x right, y down; the leader's reference point is on the
        // ground, `height` below the optical centre.
        let c = m.pose_camera.pose.pose.position;
        assert!((c.z - 1.5).abs() < 1e-12 && c.x.abs() < 1e-12, "{c:?}");
        assert!((c.y - mount.height).abs() < 1e-12, "{c:?}");
        assert_eq!(m.transform.child_frame_id, "leader_3");
        assert_eq!(m.pose_camera.header.frame_id, "camera");
        assert_eq!(m.twist.header.frame_id, "leader_3");
    }

    #[test]
    fn pose_covariance_carries_the_formation_covariance() {
        let mount = CameraMount::default();
        let r = report(2.0, 0.3, 0.2);
        let m = leader_messages(&r, &mount, msg::Time::default(), &frames()).unwrap();
        let cov = m.pose_base.pose.covariance.0;
        // The variance along the line of sight is l12's; across it, (l12 sigma_beta)^2.
        let zeta = 0.2f64;
        let along = cov[0] * zeta.cos().powi(2)
            + cov[7] * zeta.sin().powi(2)
            + 2.0 * cov[1] * zeta.sin() * zeta.cos();
        assert!((along - 1e-4).abs() < 1e-8, "{along}");
        let across = cov[0] * zeta.sin().powi(2) + cov[7] * zeta.cos().powi(2)
            - 2.0 * cov[1] * zeta.sin() * zeta.cos();
        assert!((across - (2.0 * 0.005f64).powi(2)).abs() < 1e-8, "{across}");
        // Yaw = beta12 - alpha12: its variance is sigma_a^2 + sigma_b^2 (no cross term).
        assert!(
            (cov[35] - (0.02f64.powi(2) + 0.005f64.powi(2))).abs() < 1e-9,
            "{}",
            cov[35]
        );
        // Symmetric, and no variance in z, roll or pitch on the ground plane.
        for r in 0..6 {
            for k in 0..6 {
                assert!((cov[r * 6 + k] - cov[k * 6 + r]).abs() < 1e-15);
            }
        }
        assert!(cov[14].abs() < 1e-15 && cov[21].abs() < 1e-15 && cov[28].abs() < 1e-15);
    }

    #[test]
    fn the_formation_message_has_its_documented_layout() {
        let r = report(2.0, 0.3, 0.2);
        let stamp = msg::Time {
            sec: 12,
            nanosec: 500_000_000,
        };
        let v = variables(&r, stamp);
        assert_eq!(v.data.len(), 35);
        assert_eq!(v.layout.dim[0].size * v.layout.dim[1].size, 35);
        assert_eq!(&v.data[..5], &[12.5, 3.0, 0.0, 0.0, r.l12_std]);
        assert_eq!(&v.data[5..10], &[2.0, 0.3, 0.2, 0.3, -0.1]);
        assert_eq!(v.data[10 + 1], 1e-5);
        assert_eq!(v.data[10 + 4 * 5 + 4], r.covariance[4][4]);
    }

    #[test]
    fn an_estimate_without_a_pose_is_an_error() {
        let e = leader_messages(
            &report(0.0, 0.0, 0.0),
            &CameraMount::default(),
            msg::Time::default(),
            &frames(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("pose"), "{e}");
    }
}
