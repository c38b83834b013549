//! The pose of a body constrained to a plane whose pose in the camera frame is known: three
//! parameters `(x, y, yaw)` instead of six.
//!
//! A body standing on a known plane (an object on a table seen by a calibrated camera, a
//! vehicle on the floor seen from a camera at a known height and tilt) has only its position
//! in the plane and its heading about the plane's normal free. Fitting those three numbers to
//! the reprojection error uses the prior the 6-DOF solve ignores: the two planar-target pose
//! minima that trade places under noise (the "pose flip") rarely both stand on the plane, and
//! height, roll and pitch no longer absorb corner noise.
//!
//! # Frames
//! [`PlaneFrame`] is the rigid transform taking plane coordinates (`x`, `y` in the plane, `z`
//! along its normal, the plane at `z = 0`) into camera coordinates. A [`PlanarPose`]
//! `(x, y, yaw)` puts the body's origin at `(x, y, 0)` in the plane frame with its axes those
//! of the plane turned by `yaw` about `z`; a model point `m` (body frame) is then at
//! `p = R_plane (Rz(yaw) m + (x, y, 0)) + t_plane` in the camera frame.
//!
//! # Solver
//! Levenberg-Marquardt of `lm.rs` (the loop and the covariance the 6-DOF solve uses) on
//! the three parameters, with the analytic Jacobian of each corner's pixel: with `A` the 2x3
//! Jacobian of the projection at `p` times `R_plane`, and `q = Rz(yaw) m`, the columns are
//! `A e_x`, `A e_y` and `A (e_z x q) = -q_y A e_x + q_x A e_y`. Points are accumulated straight
//! into the 3x3 normal equations (no allocation). The covariance of `(x, y, yaw)` is
//! `sigma^2 (J^T J)^-1` with `sigma^2 = max(sse / (2N - 3), min_pixel_sigma^2)`.

use nalgebra::{Matrix2x3, Matrix3, Point2, Point3, Rotation3, Vector2, Vector3};

use crate::lm::{LeastSquares, Normal};
use unicycle::PlanarPose;

use crate::{Intrinsics, Pose};

/// A plane's frame in the camera frame: the rotation and translation taking plane coordinates
/// (`x`, `y` in the plane, `z` along its normal) into camera coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneFrame {
    /// Plane axes to camera axes.
    pub rotation: Rotation3<f64>,
    /// The plane frame's origin in the camera frame.
    pub translation: Vector3<f64>,
}

impl PlaneFrame {
    /// True when every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.rotation
            .matrix()
            .iter()
            .chain(self.translation.iter())
            .all(|v| v.is_finite())
    }

    /// The rotation and translation taking the body frame of `pose` into the camera frame.
    pub fn body_to_camera(&self, pose: &PlanarPose) -> (Rotation3<f64>, Vector3<f64>) {
        let yaw = Rotation3::from_axis_angle(&Vector3::z_axis(), pose.theta);
        (
            self.rotation * yaw,
            self.rotation * Vector3::new(pose.x, pose.y, 0.0) + self.translation,
        )
    }

    /// The planar pose nearest a 6-DOF body pose (body frame to camera frame): the body's
    /// origin dropped onto the plane, and the heading of its x axis projected onto it.
    pub fn planar_from_pose(&self, pose: &Pose) -> PlanarPose {
        let to_plane = self.rotation.inverse();
        let r = to_plane * Rotation3::new(pose.rotation);
        let t = to_plane * (pose.translation - self.translation);
        let x_axis = r * Vector3::x();
        PlanarPose {
            x: t.x,
            y: t.y,
            theta: x_axis.y.atan2(x_axis.x),
        }
    }
}

/// A refined pose on a plane with its quality figures
/// ([`crate::PoseSolver::refine_on_plane`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarEstimate {
    /// The pose in the plane's frame; `yaw` as the solver reached it (not wrapped).
    pub pose: PlanarPose,
    /// Reprojection RMS in pixels, `sqrt(sum |e_i|^2 / N)` over the N points.
    pub rms: f64,
    /// Covariance of `[x, y, yaw]`: `sigma^2 (J^T J)^-1` with
    /// `sigma^2 = max(sum |e_i|^2 / (2N - 3), min_pixel_sigma^2)`.
    pub covariance: Matrix3<f64>,
    /// Levenberg-Marquardt iterations used.
    pub iterations: usize,
    /// False when LM ran out of iterations (the estimate is the last one reached).
    pub converged: bool,
}

/// Reprojection error of model points (body frame) for a body on `plane`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PlaneReprojection<'a> {
    pub k: &'a Intrinsics,
    pub plane: &'a PlaneFrame,
    pub model: &'a [Point3<f64>],
    pub image: &'a [Point2<f64>],
}

impl LeastSquares<3> for PlaneReprojection<'_> {
    type Params = PlanarPose;

    #[inline]
    fn to_vector(p: &PlanarPose) -> Vector3<f64> {
        p.to_vector()
    }

    #[inline]
    fn from_vector(v: &Vector3<f64>) -> PlanarPose {
        PlanarPose::from_vector(v)
    }

    fn normal_equations(&self, p: &PlanarPose) -> Result<Normal<3>, (usize, f64)> {
        let r = self.plane.rotation.matrix();
        let origin = Vector3::new(p.x, p.y, 0.0);
        let (s, c) = p.theta.sin_cos();
        let mut jtj = Matrix3::<f64>::zeros();
        let mut jte = Vector3::<f64>::zeros();
        let mut sse = 0.0;
        for (i, (m, px)) in self.model.iter().zip(self.image).enumerate() {
            // The point turned by the yaw, in plane axes.
            let q = Vector3::new(c * m.x - s * m.y, s * m.x + c * m.y, m.z);
            let pc = Point3::from(r * (q + origin) + self.plane.translation);
            if pc.z.is_nan() || pc.z <= crate::MIN_DEPTH {
                return Err((i, pc.z));
            }
            let proj = self
                .k
                .normalized_to_pixel(&Point2::new(pc.x / pc.z, pc.y / pc.z));
            let e = Vector2::new(proj.x - px.x, proj.y - px.y);
            sse += e.norm_squared();
            let a = self.k.projection_jacobian(&pc) * r;
            let (ax, ay) = (a.column(0), a.column(1));
            let j = Matrix2x3::from_columns(&[ax.into(), ay.into(), ay * q.x - ax * q.y]);
            jtj += j.transpose() * j;
            jte += j.transpose() * e;
        }
        Ok(Normal { jtj, jte, sse })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A plane 0.3 below a camera tilted down by `tilt` and panned by `pan` (camera axes: x
    /// right, y down, z forward; plane axes: x forward, y left, z up).
    fn plane(tilt: f64, pan: f64) -> PlaneFrame {
        let level = Matrix3::new(0.0, -1.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0);
        let cam_to_plane = Rotation3::from_axis_angle(&Vector3::z_axis(), pan)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), tilt)
            * Rotation3::from_matrix_unchecked(level.transpose());
        let rotation = cam_to_plane.inverse();
        PlaneFrame {
            rotation,
            translation: -(rotation * Vector3::new(0.2, 0.0, 0.3)),
        }
    }

    fn box_corners() -> Vec<Point3<f64>> {
        let mut v = Vec::new();
        for &(x, y, z) in &[
            (0.1, -0.07, 0.05),
            (0.1, 0.07, 0.05),
            (0.1, 0.07, 0.17),
            (0.1, -0.07, 0.17),
            (0.05, 0.12, 0.05),
            (-0.05, 0.12, 0.05),
            (-0.05, 0.12, 0.17),
            (0.05, 0.12, 0.17),
        ] {
            v.push(Point3::new(x, y, z));
        }
        v
    }

    fn k() -> Intrinsics {
        Intrinsics::new(560.0, 550.0, std::f64::consts::FRAC_PI_2, 320.0, 240.0)
            .expect("valid intrinsics")
    }

    fn residuals(problem: &PlaneReprojection<'_>, p: &PlanarPose) -> Vec<f64> {
        let (r, t) = problem.plane.body_to_camera(p);
        problem
            .model
            .iter()
            .zip(problem.image)
            .flat_map(|(m, px)| {
                let q = problem
                    .k
                    .project(&Point3::from(r * m.coords + t))
                    .expect("in front");
                [q.x - px.x, q.y - px.y]
            })
            .collect()
    }

    #[test]
    fn refine_on_plane_recovers_the_pose_and_checks_its_input() {
        let k = k();
        let plane = plane(0.1, -0.2);
        let model = box_corners();
        let truth = PlanarPose {
            x: 1.7,
            y: 0.3,
            theta: 2.5,
        };
        let (r, t) = plane.body_to_camera(&truth);
        let image: Vec<Point2<f64>> = model
            .iter()
            .map(|m| {
                k.project(&Point3::from(r * m.coords + t))
                    .expect("in front")
            })
            .collect();
        let solver = crate::PoseSolver::new(k);
        let start = PlanarPose {
            x: 1.6,
            y: 0.35,
            theta: 2.3,
        };
        let est = solver
            .refine_on_plane(&plane, &model, &image, &start)
            .expect("converges");
        assert!(est.converged);
        assert!(
            (est.pose.to_vector() - truth.to_vector()).amax() < 1e-9,
            "{est:?}"
        );
        assert!(est.rms < 1e-9);
        // Exact data: the covariance is the noise floor's, (0.1 px)^2 (J^T J)^-1.
        let problem = PlaneReprojection {
            k: &k,
            plane: &plane,
            model: &model,
            image: &image,
        };
        let jtj = problem.normal_equations(&est.pose).expect("in front").jtj;
        let want = jtj.try_inverse().expect("invertible") * 0.01;
        assert!((est.covariance - want).amax() < 1e-9 * want.amax());
        // A start that puts the body behind the camera, and non-finite input, are errors.
        let behind = PlanarPose { x: -3.0, ..start };
        assert!(matches!(
            solver.refine_on_plane(&plane, &model, &image, &behind),
            Err(crate::PoseError::PointBehindCamera { .. })
        ));
        let nan = PlanarPose {
            theta: f64::NAN,
            ..start
        };
        assert!(matches!(
            solver.refine_on_plane(&plane, &model, &image, &nan),
            Err(crate::PoseError::NonFinite { .. })
        ));
        assert!(matches!(
            solver.refine_on_plane(&plane, &model[..3], &image[..3], &start),
            Err(crate::PoseError::TooFewPoints { .. })
        ));
    }

    proptest! {
        /// The analytic normal equations equal those of the central-difference Jacobian of
        /// the residuals written with `body_to_camera` (an independent formula).
        #[test]
        fn analytic_jacobian_matches_central_differences(
            x in 0.8..3.0f64, y in -1.0..1.0f64, yaw in -3.1..3.1f64,
            tilt in -0.3..0.3f64, pan in -0.4..0.4f64, noise in 0.0..2.0f64,
        ) {
            let plane = plane(tilt, pan);
            let k = k();
            let model = box_corners();
            let p = PlanarPose { x, y, theta: yaw };
            let (r, t) = plane.body_to_camera(&p);
            let mut image = Vec::new();
            for (i, m) in model.iter().enumerate() {
                let pc = Point3::from(r * m.coords + t);
                prop_assume!(pc.z > 0.1);
                let q = k.project(&pc).expect("in front");
                let f = i as f64;
                image.push(Point2::new(q.x + noise * f.sin(), q.y - noise * f.cos()));
            }
            let problem = PlaneReprojection { k: &k, plane: &plane, model: &model, image: &image };
            let n = problem.normal_equations(&p).expect("in front");
            let e = residuals(&problem, &p);
            let mut jac = vec![Vector3::<f64>::zeros(); e.len()];
            for j in 0..3 {
                let h = 1e-6;
                let mut v = p.to_vector();
                v[j] += h;
                let ep = residuals(&problem, &PlanarPose::from_vector(&v));
                v[j] -= 2.0 * h;
                let em = residuals(&problem, &PlanarPose::from_vector(&v));
                for (row, (a, b)) in jac.iter_mut().zip(ep.iter().zip(&em)) {
                    row[j] = (a - b) / (2.0 * h);
                }
            }
            let mut jtj = Matrix3::zeros();
            let mut jte = Vector3::zeros();
            for (row, ei) in jac.iter().zip(&e) {
                jtj += row * row.transpose();
                jte += row * *ei;
            }
            let sse: f64 = e.iter().map(|v| v * v).sum();
            prop_assert!((n.jtj - jtj).amax() <= 1e-6 * jtj.amax(), "{} vs {}", n.jtj, jtj);
            prop_assert!((n.jte - jte).amax() <= 1e-6 * jtj.amax().sqrt() * (1.0 + sse.sqrt()));
            prop_assert!((n.sse - sse).abs() <= 1e-9 * (1.0 + sse));
        }

        /// `planar_from_pose` inverts `body_to_camera`.
        #[test]
        fn planar_from_pose_inverts_body_to_camera(
            x in -3.0..3.0f64, y in -3.0..3.0f64, yaw in -3.1..3.1f64,
            tilt in -0.5..0.5f64, pan in -1.0..1.0f64,
        ) {
            let plane = plane(tilt, pan);
            let p = PlanarPose { x, y, theta: yaw };
            let (r, t) = plane.body_to_camera(&p);
            let back = plane.planar_from_pose(&Pose::new(r.scaled_axis(), t));
            prop_assert!((back.x - x).abs() < 1e-9 && (back.y - y).abs() < 1e-9);
            let d = (back.theta - yaw).sin().abs() + (1.0 - (back.theta - yaw).cos());
            prop_assert!(d < 1e-9, "yaw {} vs {}", back.theta, yaw);
        }
    }
}
