//! Robot poses from the markers read in one frame: group markers by robot, solve one joint
//! pose per robot from all its faces, reject a face that disagrees with the others, and turn
//! each pose into the formation variables `(l12, alpha12, beta12)` with their covariance.
//!
//! # Why a joint pose, and how a bad face is found
//! One face is a plane, and a plane seen from afar has two pose minima that trade places
//! under noise (spec 4.4). Two or more octagon faces are not coplanar, so solving them
//! together (POSIT, then Levenberg-Marquardt on all corners, `pose`) has a single minimum
//! and uses every corner. The price is that one wrong marker (a code misread as this robot's,
//! or a corner caught on a neighbouring edge) pulls the whole pose. So after the joint solve
//! each face's own reprojection RMS is checked: when one face is far above the others
//! (more than [`RobotConfig::outlier_px`] and [`RobotConfig::outlier_factor`] times the
//! median of the rest), the pose is solved leave-one-out and the face whose removal leaves
//! the best fit is dropped; this repeats while a face stands out and at least two faces
//! remain. With exactly two faces there is no majority: the smaller one in the image (the
//! less reliable) is dropped and the robot is solved from the other face alone.
//!
//! A robot seen through a single face gets both planar candidates from `pose`; the better
//! one is kept and the robot is marked `ambiguous` when the other's reprojection RMS is
//! within [`RobotConfig::ambiguity_ratio`] of it.
//!
//! # Formation variables
//! The pose (rig frame to camera frame) goes through the camera mount with
//! [`mount::formation_from_camera_pose`] (spec 2.5) and its 6x6 covariance (rotation
//! vector, translation) through [`mount::propagate_covariance`].

use nalgebra::{Matrix3, Point2, Point3, Rotation3, SMatrix, SVector, Vector3};
use pose::{PoseError, PoseSolver};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::mount::{self, CameraMount, MeasurementError};
use crate::rig::RigError;
use crate::rig::RigModel;

/// A marker read in an image: its dictionary entry and the outer corners of its black
/// border in the marker's own order NW, NE, SE, SW (pixel centres at integers).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerObservation {
    /// Dictionary entry.
    pub index: usize,
    /// Corners, marker order.
    pub corners: [Point2<f64>; 4],
}

/// Thresholds of [`measure_robots`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RobotConfig {
    /// Faces are checked for consistency only when one face's reprojection RMS under the
    /// joint pose exceeds this (pixels); leaving a face out must bring the RMS below half of
    /// it, or divide it by `outlier_factor`.
    pub outlier_px: f64,
    /// See `outlier_px`.
    pub outlier_factor: f64,
    /// A single face is `ambiguous` when the other candidate's RMS is below this multiple of
    /// the best one's.
    pub ambiguity_ratio: f64,
    /// Refine each pose on the ground plane: the leader stands on the floor the follower
    /// stands on and the camera mount is known, so only `(x, y, theta)` of the leader are
    /// free (see the module docs). Off: the 6-DOF pose of `pose` is reported as is.
    pub ground_plane: bool,
}

impl Default for RobotConfig {
    fn default() -> Self {
        Self {
            outlier_px: 1.0,
            outlier_factor: 3.0,
            ambiguity_ratio: 1.5,
            ground_plane: true,
        }
    }
}

/// Why a robot's pose could not be measured.
#[derive(Debug, Error)]
pub enum RobotError {
    /// The pose solver failed.
    #[error("robot {robot}: pose: {source}")]
    Pose {
        /// The robot.
        robot: u32,
        /// Why.
        source: PoseError,
    },
    /// The pose does not give formation variables (e.g. the leader on the camera point).
    #[error("robot {robot}: formation variables: {source}")]
    Measurement {
        /// The robot.
        robot: u32,
        /// Why.
        source: MeasurementError,
    },
    /// The rig has no geometry for a face the table maps to.
    #[error(transparent)]
    Rig(#[from] RigError),
}

/// Planar pose of a leader in the follower's body frame and its fit.
#[derive(Debug, Clone, Copy)]
struct Planar {
    q: Vector3<f64>,
    rms: f64,
    cov: Matrix3<f64>,
}

/// Reprojection residuals (2 per corner) of the planar pose `q`; `None` if a corner falls
/// behind the camera.
fn planar_residuals(
    q: &Vector3<f64>,
    faces: &[FaceObs],
    k: &pose::Intrinsics,
    mount: &CameraMount,
    out: &mut Vec<f64>,
) -> Option<()> {
    let (r, t) = mount.leader_to_camera(q.x, q.y, q.z);
    out.clear();
    for f in faces {
        for (m, i) in f.model.iter().zip(&f.image) {
            let p = k.project(&Point3::from(r * m.coords + t)).ok()?;
            out.push(p.x - i.x);
            out.push(p.y - i.y);
        }
    }
    Some(())
}

/// Levenberg-Marquardt on `(x, y, theta)` from `q0`; numerical Jacobian (three parameters,
/// a few dozen residuals: cheap), covariance `sigma^2 (J^T J)^-1` with the same noise floor
/// as `pose` (0.1 px).
fn refine_planar(
    q0: Vector3<f64>,
    faces: &[FaceObs],
    k: &pose::Intrinsics,
    mount: &CameraMount,
) -> Option<Planar> {
    let mut q = q0;
    let mut e = Vec::new();
    let mut ep = Vec::new();
    let mut em = Vec::new();
    planar_residuals(&q, faces, k, mount, &mut e)?;
    let mut cost: f64 = e.iter().map(|v| v * v).sum();
    let mut lambda = 1e-3;
    let n = e.len();
    let mut jac = vec![Vector3::zeros(); n];
    for _ in 0..100 {
        for j in 0..3 {
            let h = if j == 2 {
                1e-6
            } else {
                1e-6 * q[j].abs().max(0.1)
            };
            let mut qp = q;
            qp[j] += h;
            let mut qm = q;
            qm[j] -= h;
            planar_residuals(&qp, faces, k, mount, &mut ep)?;
            planar_residuals(&qm, faces, k, mount, &mut em)?;
            for i in 0..n {
                jac[i][j] = (ep[i] - em[i]) / (2.0 * h);
            }
        }
        let mut jtj = Matrix3::zeros();
        let mut jte = Vector3::zeros();
        for i in 0..n {
            jtj += jac[i] * jac[i].transpose();
            jte += jac[i] * e[i];
        }
        let mut improved = false;
        while lambda < 1e10 {
            let mut a = jtj;
            for d in 0..3 {
                a[(d, d)] *= 1.0 + lambda;
            }
            let Some(step) = a.lu().solve(&(-jte)) else {
                lambda *= 10.0;
                continue;
            };
            let qn = q + step;
            if planar_residuals(&qn, faces, k, mount, &mut ep).is_some() {
                let c: f64 = ep.iter().map(|v| v * v).sum();
                if c < cost {
                    let done = (cost - c) <= 1e-12 * cost.max(1e-30) || step.norm() < 1e-10;
                    q = qn;
                    cost = c;
                    std::mem::swap(&mut e, &mut ep);
                    lambda = (lambda / 10.0).max(1e-9);
                    improved = true;
                    if done {
                        lambda = 0.0;
                    }
                    break;
                }
            }
            lambda *= 10.0;
        }
        if !improved || lambda == 0.0 {
            break;
        }
    }
    if !q.iter().all(|v| v.is_finite()) {
        return None;
    }
    let mut jtj = Matrix3::zeros();
    for row in &jac {
        jtj += row * row.transpose();
    }
    let dof = (n as f64 - 3.0).max(1.0);
    let sigma2 = (cost / dof).max(0.01);
    let cov = jtj.try_inverse()? * sigma2;
    q.z = unicycle::wrap_angle(q.z);
    Some(Planar {
        q,
        rms: (cost / (n as f64 / 2.0)).sqrt(),
        cov,
    })
}

/// The planar pose `(x, y, theta)` in the follower's body frame nearest a 6-DOF pose.
fn planar_from_pose(p: &pose::Pose, mount: &CameraMount) -> Vector3<f64> {
    let cam_to_body = mount.camera_to_body_rotation();
    let r = cam_to_body * Rotation3::new(p.rotation);
    let t = cam_to_body * p.translation + mount.camera_position();
    let x_axis = r * Vector3::x();
    Vector3::new(t.x, t.y, x_axis.y.atan2(x_axis.x))
}

/// One robot measured in a frame, as the `detect` command writes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotMeasurement {
    /// Robot number.
    pub robot: u32,
    /// Faces used for the pose.
    pub faces: Vec<u8>,
    /// Faces read but rejected as inconsistent with the others.
    pub rejected_faces: Vec<u8>,
    /// Rotation vector, rig frame to camera frame (radians).
    pub rotation: [f64; 3],
    /// Rig origin in the camera frame (metres).
    pub translation: [f64; 3],
    /// Reprojection RMS over the faces used, pixels.
    pub reprojection_rms_px: f64,
    /// Planar distance from the camera point, metres.
    pub l12: f64,
    /// `alpha12`, radians.
    pub alpha12: f64,
    /// `beta12`, radians.
    pub beta12: f64,
    /// Covariance of `(l12, alpha12, beta12)`.
    pub covariance: [[f64; 3]; 3],
    /// A single face left two close pose candidates.
    pub ambiguous: bool,
    /// For a single face: the other candidate's RMS over the best's.
    pub ambiguity_ratio: Option<f64>,
    /// The pose was refined on the ground plane ([`RobotConfig::ground_plane`]).
    pub ground_plane: bool,
}

impl RobotMeasurement {
    /// The leader's heading relative to the camera robot's: `beta12 - alpha12`.
    pub fn relative_heading(&self) -> f64 {
        unicycle::wrap_angle(self.beta12 - self.alpha12)
    }
}

/// Everything [`measure_robots`] found in a frame.
#[derive(Debug, Default)]
pub struct FrameRobots {
    /// Robots measured, by robot number.
    pub robots: Vec<RobotMeasurement>,
    /// Markers whose entry is on no robot of the rig.
    pub unknown: Vec<usize>,
    /// Robots whose markers were read but whose pose failed.
    pub failures: Vec<RobotError>,
}

struct FaceObs {
    face: u8,
    model: [Point3<f64>; 4],
    image: [Point2<f64>; 4],
}

fn area(c: &[Point2<f64>; 4]) -> f64 {
    let mut a = 0.0;
    for i in 0..4 {
        let (p, q) = (c[i], c[(i + 1) % 4]);
        a += p.x * q.y - q.x * p.y;
    }
    (a / 2.0).abs()
}

/// Groups `markers` by robot through `rig`'s table and measures each robot.
pub fn measure_robots(
    markers: &[MarkerObservation],
    rig: &RigModel,
    solver: &PoseSolver,
    mount: &CameraMount,
    config: &RobotConfig,
) -> FrameRobots {
    let mut out = FrameRobots::default();
    let mut groups: Vec<(u32, Vec<FaceObs>)> = Vec::new();
    for m in markers {
        let Some((robot, face)) = rig.robot_face(m.index) else {
            out.unknown.push(m.index);
            continue;
        };
        let geometry = match rig.face(face) {
            Ok(g) => g,
            Err(e) => {
                out.failures.push(e.into());
                continue;
            }
        };
        let obs = FaceObs {
            face,
            model: geometry.corner_points(),
            image: m.corners,
        };
        let pos = match groups.iter().position(|(r, _)| *r == robot) {
            Some(p) => p,
            None => {
                groups.push((robot, Vec::new()));
                groups.len() - 1
            }
        };
        let group = &mut groups[pos].1;
        // The same face read twice: one is a wrong code; keep the larger quad.
        if let Some(prev) = group.iter_mut().find(|o| o.face == face) {
            if area(&obs.image) > area(&prev.image) {
                *prev = obs;
            }
        } else {
            group.push(obs);
        }
    }
    groups.sort_by_key(|(r, _)| *r);
    for (robot, faces) in groups {
        match measure_robot(robot, faces, solver, mount, config) {
            Ok(m) => out.robots.push(m),
            Err(e) => out.failures.push(e),
        }
    }
    out
}

/// Joint solve of `faces`; per-face RMS under the result.
fn joint(
    solver: &PoseSolver,
    faces: &[FaceObs],
    robot: u32,
) -> Result<(pose::PoseSolution, Vec<f64>), RobotError> {
    let model: Vec<Point3<f64>> = faces.iter().flat_map(|f| f.model).collect();
    let image: Vec<Point2<f64>> = faces.iter().flat_map(|f| f.image).collect();
    let sol = solver
        .solve(&model, &image)
        .map_err(|source| RobotError::Pose { robot, source })?;
    let p = sol.pose();
    let k = solver.intrinsics();
    let per_face = faces
        .iter()
        .map(|f| {
            let mut s = 0.0;
            for (m, i) in f.model.iter().zip(&f.image) {
                s += match k.project(&p.transform_point(m)) {
                    Ok(q) => (q - i).norm_squared(),
                    Err(_) => f64::INFINITY,
                };
            }
            (s / 4.0).sqrt()
        })
        .collect();
    Ok((sol, per_face))
}

fn measure_robot(
    robot: u32,
    mut faces: Vec<FaceObs>,
    solver: &PoseSolver,
    mount: &CameraMount,
    config: &RobotConfig,
) -> Result<RobotMeasurement, RobotError> {
    let mut rejected = Vec::new();
    let (mut sol, mut per_face) = joint(solver, &faces, robot)?;
    while faces.len() >= 2 && per_face.iter().any(|&r| r > config.outlier_px) {
        let drop = if faces.len() == 2 {
            // No majority: drop the smaller quad.
            usize::from(area(&faces[0].image) >= area(&faces[1].image))
        } else {
            // Leave one out: the face whose removal fits the rest best, if that is a clear
            // improvement.
            let mut best: Option<(usize, f64)> = None;
            for i in 0..faces.len() {
                let rest: Vec<FaceObs> = faces
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(_, f)| FaceObs {
                        face: f.face,
                        model: f.model,
                        image: f.image,
                    })
                    .collect();
                if let Ok((s, _)) = joint(solver, &rest, robot)
                    && best.is_none_or(|(_, r)| s.rms() < r)
                {
                    best = Some((i, s.rms()));
                }
            }
            match best {
                Some((i, r))
                    if r < sol.rms() / config.outlier_factor || r <= config.outlier_px / 2.0 =>
                {
                    i
                }
                _ => break,
            }
        };
        rejected.push(faces.remove(drop).face);
        (sol, per_face) = joint(solver, &faces, robot)?;
    }
    let p = sol.pose();
    let mut ratio = if sol.coplanar {
        sol.ambiguity_ratio()
    } else {
        None
    };
    let mut rms = sol.rms();
    let (rot, t, params, cov6) = if config.ground_plane {
        // Every candidate of the 6-DOF stage seeds a planar refinement; keep the best.
        let k = solver.intrinsics();
        let mut seeds = vec![planar_from_pose(&p, mount)];
        if let Some(alt) = &sol.alternative {
            seeds.push(planar_from_pose(&alt.pose, mount));
        }
        let fits: Vec<Planar> = seeds
            .into_iter()
            .filter_map(|q0| refine_planar(q0, &faces, k, mount))
            .collect();
        let best = fits
            .iter()
            .min_by(|a, b| a.rms.total_cmp(&b.rms))
            .copied()
            .ok_or(RobotError::Pose {
                robot,
                source: PoseError::Degenerate {
                    reason: "the ground-plane refinement did not converge",
                },
            })?;
        if sol.coplanar {
            ratio = fits
                .iter()
                .filter(|f| (f.q - best.q).norm() > 1e-4)
                .map(|f| f.rms / best.rms.max(1e-12))
                .reduce(f64::min);
        }
        rms = best.rms;
        let (r, t) = mount.leader_to_camera(best.q.x, best.q.y, best.q.z);
        let mut cov6 = SMatrix::<f64, 6, 6>::zeros();
        cov6.fixed_view_mut::<3, 3>(0, 0).copy_from(&best.cov);
        let params = SVector::<f64, 6>::new(best.q.x, best.q.y, best.q.z, 0.0, 0.0, 0.0);
        (r, t, params, cov6)
    } else {
        (
            Rotation3::new(p.rotation),
            p.translation,
            p.to_params(),
            sol.best.covariance,
        )
    };
    let f = mount::formation_from_camera_pose(&rot, &t, mount)
        .map_err(|source| RobotError::Measurement { robot, source })?;
    let cov = if config.ground_plane {
        mount::propagate_covariance(&params, &cov6, |q| {
            let (r, t) = mount.leader_to_camera(q[0], q[1], q[2]);
            mount::formation_from_camera_pose(&r, &t, mount)
        })
    } else {
        mount::propagate_covariance(&params, &cov6, |q| {
            let r = Rotation3::new(Vector3::new(q[0], q[1], q[2]));
            mount::formation_from_camera_pose(&r, &Vector3::new(q[3], q[4], q[5]), mount)
        })
    }
    .map_err(|source| RobotError::Measurement { robot, source })?;
    let rv = rot.scaled_axis();
    let mut face_numbers: Vec<u8> = faces.iter().map(|f| f.face).collect();
    face_numbers.sort_unstable();
    rejected.sort_unstable();
    Ok(RobotMeasurement {
        robot,
        faces: face_numbers,
        rejected_faces: rejected,
        rotation: rv.into(),
        translation: t.into(),
        reprojection_rms_px: rms,
        l12: f[0],
        alpha12: f[1],
        beta12: f[2],
        covariance: [
            [cov[(0, 0)], cov[(0, 1)], cov[(0, 2)]],
            [cov[(1, 0)], cov[(1, 1)], cov[(1, 2)]],
            [cov[(2, 0)], cov[(2, 1)], cov[(2, 2)]],
        ],
        ambiguous: ratio.is_some_and(|r| r < config.ambiguity_ratio),
        ambiguity_ratio: ratio,
        ground_plane: config.ground_plane,
    })
}
