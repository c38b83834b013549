//! Levenberg-Marquardt refinement of the exponential-map pose parameters
//! `[wx, wy, wz, tx, ty, tz]` (spec 4.4, paper eqs. 26-28), and the pose covariance.
//!
//! The loop ([`refine`]) and the covariance are written once for any [`LeastSquares`]
//! problem of `N` parameters with static normal equations: the 6-DOF pose here
//! ([`Reprojection`]) and the pose of a body constrained to a plane
//! (`crate::plane::PlaneReprojection`, three parameters).
//!
//! The residual is the reprojection error in pixels of every correspondence, all faces
//! together. The 2N x 6 Jacobian is never formed: each point adds its 2x6 block straight into
//! `J^T J` (6x6) and `J^T e` (6), so a solve allocates nothing whatever the number of points.
//! The rotation block is accumulated in the local (left-perturbation) frame, where a point's
//! block is `J_proj [-R p]x`, and mapped once to the parameters through the left Jacobian
//! `J_l(w)` (see [`crate::so3`]).
//!
//! Each step solves `(J^T J + lambda I) d = -J^T e` (the spec's damped normal equations) by
//! Cholesky. Lambda starts at `initial_damping * max(diag(J^T J))` [1e-7] and adapts with Nielsen's
//! gain-ratio rule (a smooth form of the Marquardt/Lowe up-down schedule): after an accepted
//! step `lambda *= max(1/3, 1 - (2 rho - 1)^3)`, after a rejected one it grows by a factor that
//! doubles each time. A step that puts a point behind the camera is rejected like any step that
//! increases the cost.
//!
//! Convergence ([`LmConfig`], defaults in brackets): the solve stops and reports success when
//! the damped step's predicted reduction of the squared error is below
//! `relative_cost_tolerance` of it while lambda is small (nearly Gauss-Newton), when
//! the gradient `max |J^T e|` falls below `gradient_tolerance` [1e-10], when the step is smaller
//! than `step_tolerance * (|params| + step_tolerance)` [1e-10], or when an accepted step lowers
//! the sum of squared errors by less than `relative_cost_tolerance` of it [1e-8]. (Near the
//! fronto-parallel view of one face the two planar minima merge and the cost is quartic in the
//! tilt, where LM converges only linearly: the relative-cost test is what ends those solves.) Running out
//! of `max_iterations` [100] returns [`PoseError::NotConverged`] carrying the last estimate.

use crate::ldl::Ldl;
use crate::{Distortion, Intrinsics, Pose, PoseError, so3};
use nalgebra::{Matrix2x3, Matrix3, Matrix6, Point2, Point3, SMatrix, SVector, Vector6};

/// Levenberg-Marquardt settings. `Default` gives the documented defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmConfig {
    /// Iterations (Cholesky solves) allowed before [`PoseError::NotConverged`]. Default 100.
    pub max_iterations: usize,
    /// Stop when `max_i |(J^T e)_i|` is below this (px^2 per parameter unit). Default 1e-10.
    pub gradient_tolerance: f64,
    /// Stop when `|step| <= step_tolerance * (|params| + step_tolerance)`. Default 1e-10.
    pub step_tolerance: f64,
    /// Stop when an accepted step lowers the squared error by less than this fraction (or the
    /// linear model predicts less, in the near-Gauss-Newton regime). Default 1e-8: the pose is
    /// then within ~1e-4 of its standard deviation of the exact minimum.
    pub relative_cost_tolerance: f64,
    /// Initial lambda as a fraction of the largest diagonal entry of `J^T J`. Default 1e-7:
    /// both initialisers land close to the minimum, so the first steps are nearly Gauss-Newton;
    /// the gain ratio raises lambda at once when a start is poor.
    pub initial_damping: f64,
}

impl Default for LmConfig {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            gradient_tolerance: 1e-10,
            step_tolerance: 1e-10,
            relative_cost_tolerance: 1e-8,
            initial_damping: 1e-7,
        }
    }
}

/// Normal equations of the reprojection error at one parameter vector of `N` entries.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Normal<const N: usize> {
    /// `J^T J`.
    pub jtj: SMatrix<f64, N, N>,
    /// `J^T e`.
    pub jte: SVector<f64, N>,
    /// Sum of squared residuals (px^2).
    pub sse: f64,
}

/// A reprojection least-squares problem of `N` parameters that [`refine`] can solve.
pub(crate) trait LeastSquares<const N: usize> {
    /// The parameters in their own type.
    type Params: Copy + PartialEq;
    /// The parameter vector LM steps in.
    fn to_vector(p: &Self::Params) -> SVector<f64, N>;
    /// The parameters of a vector.
    fn from_vector(v: &SVector<f64, N>) -> Self::Params;
    /// The canonical form of equivalent parameters (e.g. a rotation vector wrapped to angle
    /// `<= pi`); the identity unless overridden.
    fn normalized(p: &Self::Params) -> Self::Params {
        *p
    }
    /// Residuals and normal equations at `p`. `Err(index, z)` names the first point on or
    /// behind the camera plane.
    fn normal_equations(&self, p: &Self::Params) -> Result<Normal<N>, (usize, f64)>;
}

/// The 6-DOF pose problem: model points (rig frame) and their pixels.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Reprojection<'a> {
    pub k: &'a Intrinsics,
    pub model: &'a [Point3<f64>],
    pub image: &'a [Point2<f64>],
}

impl LeastSquares<6> for Reprojection<'_> {
    type Params = Pose;

    #[inline]
    fn to_vector(p: &Pose) -> Vector6<f64> {
        p.to_params()
    }

    #[inline]
    fn from_vector(v: &Vector6<f64>) -> Pose {
        Pose::from_params(v)
    }

    #[inline]
    fn normalized(p: &Pose) -> Pose {
        p.normalized()
    }

    #[inline]
    fn normal_equations(&self, p: &Pose) -> Result<Normal<6>, (usize, f64)> {
        normal_equations(self.k, self.model, self.image, p)
    }
}

/// The 6-DOF pose problem with the residual in distorted (detected) pixels: model points
/// project through the pinhole, then the lens model, then `K`, and are compared with the
/// pixels as detected. This is the objective of OpenCV's `solvePnP` refinement and the
/// maximum-likelihood one when the detector's noise is in its own pixels.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DistortedReprojection<'a> {
    pub k: &'a Intrinsics,
    pub distortion: &'a Distortion,
    pub model: &'a [Point3<f64>],
    pub image: &'a [Point2<f64>],
}

impl LeastSquares<6> for DistortedReprojection<'_> {
    type Params = Pose;

    #[inline]
    fn to_vector(p: &Pose) -> Vector6<f64> {
        p.to_params()
    }

    #[inline]
    fn from_vector(v: &Vector6<f64>) -> Pose {
        Pose::from_params(v)
    }

    #[inline]
    fn normalized(p: &Pose) -> Pose {
        p.normalized()
    }

    fn normal_equations(&self, p: &Pose) -> Result<Normal<6>, (usize, f64)> {
        let m = self.k.matrix();
        let k2 = nalgebra::Matrix2::new(m[(0, 0)], m[(0, 1)], 0.0, m[(1, 1)]);
        let (k, d) = (self.k, self.distortion);
        normal_equations_with(self.model, self.image, p, |pc| {
            let iz = 1.0 / pc.z;
            let n = Point2::new(pc.x * iz, pc.y * iz);
            let (dn, jd) = d.distort_with_jacobian(&n);
            let jn = Matrix2x3::new(iz, 0.0, -n.x * iz, 0.0, iz, -n.y * iz);
            (k.normalized_to_pixel(&dn), k2 * jd * jn)
        })
    }
}

/// Reprojection residuals and normal equations at `pose`. `Err(index, z)` names the first
/// point on or behind the camera plane.
pub(crate) fn normal_equations(
    k: &Intrinsics,
    model: &[Point3<f64>],
    image: &[Point2<f64>],
    pose: &Pose,
) -> Result<Normal<6>, (usize, f64)> {
    normal_equations_with(model, image, pose, |pc| {
        (
            k.normalized_to_pixel(&Point2::new(pc.x / pc.z, pc.y / pc.z)),
            k.projection_jacobian(pc),
        )
    })
}

/// [`normal_equations`] for any projection: `project(pc)` gives the pixel of a camera-frame
/// point in front of the camera and its 2x3 Jacobian.
#[inline]
fn normal_equations_with(
    model: &[Point3<f64>],
    image: &[Point2<f64>],
    pose: &Pose,
    project: impl Fn(&Point3<f64>) -> (Point2<f64>, Matrix2x3<f64>),
) -> Result<Normal<6>, (usize, f64)> {
    let (r, jl) = so3::exp_and_left_jacobian(&pose.rotation);
    // Local-frame accumulation: blocks [rot | trans] with rot = J_proj [-Rp]x.
    let mut rr = Matrix3::<f64>::zeros();
    let mut rt = Matrix3::<f64>::zeros();
    let mut tt = Matrix3::<f64>::zeros();
    let mut gr = nalgebra::Vector3::<f64>::zeros();
    let mut gt = nalgebra::Vector3::<f64>::zeros();
    let mut sse = 0.0;
    for (i, (p, m)) in model.iter().zip(image).enumerate() {
        let rp = r * p.coords;
        let pc = Point3::from(rp + pose.translation);
        if pc.z.is_nan() || pc.z <= crate::MIN_DEPTH {
            return Err((i, pc.z));
        }
        let (proj, jp) = project(&pc);
        let e = nalgebra::Vector2::new(proj.x - m.x, proj.y - m.y);
        sse += e.norm_squared();
        // Row a of J_proj times -[Rp]x is (Rp x a)^T.
        let (a0, a1) = (jp.row(0).transpose(), jp.row(1).transpose());
        let jr: Matrix2x3<f64> =
            Matrix2x3::from_rows(&[rp.cross(&a0).transpose(), rp.cross(&a1).transpose()]);
        rr += jr.transpose() * jr;
        rt += jr.transpose() * jp;
        tt += jp.transpose() * jp;
        gr += jr.transpose() * e;
        gt += jp.transpose() * e;
    }
    // Map the rotation block to the parameters: J_w = J_local J_l.
    let jlt = jl.transpose();
    let rr = jlt * rr * jl;
    let rt = jlt * rt;
    let gr = jlt * gr;
    let mut jtj = Matrix6::zeros();
    jtj.fixed_view_mut::<3, 3>(0, 0).copy_from(&rr);
    jtj.fixed_view_mut::<3, 3>(0, 3).copy_from(&rt);
    jtj.fixed_view_mut::<3, 3>(3, 0).copy_from(&rt.transpose());
    jtj.fixed_view_mut::<3, 3>(3, 3).copy_from(&tt);
    let mut jte = Vector6::zeros();
    jte.fixed_view_mut::<3, 1>(0, 0).copy_from(&gr);
    jte.fixed_view_mut::<3, 1>(3, 0).copy_from(&gt);
    Ok(Normal { jtj, jte, sse })
}

/// The outcome of a refinement: converged, or out of iterations (the estimate is still
/// usable).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Refined<P, const N: usize> {
    pub pose: P,
    pub normal: Normal<N>,
    pub iterations: usize,
}

/// Failure of a refinement that still has an estimate.
pub(crate) type Unconverged<P, const N: usize> = Refined<P, N>;

/// Levenberg-Marquardt from `initial`. Errors: a point behind the camera at the start, a
/// non-finite cost; `Ok(Err(_))` when iterations ran out (the estimate is still usable).
#[allow(clippy::type_complexity)] // the two outcomes of an estimate are one `Result` each
pub(crate) fn refine<P: LeastSquares<N>, const N: usize>(
    problem: &P,
    initial: &P::Params,
    cfg: &LmConfig,
) -> Result<Result<Refined<P::Params, N>, Unconverged<P::Params, N>>, PoseError> {
    let mut pose = P::normalized(initial);
    let mut cur = problem
        .normal_equations(&pose)
        .map_err(|(index, z)| PoseError::PointBehindCamera { index, z })?;
    if !cur.sse.is_finite() {
        return Err(PoseError::Degenerate {
            reason: "reprojection error is not finite at the initial pose",
        });
    }
    let max_diag = (0..N).map(|i| cur.jtj[(i, i)]).fold(0.0, f64::max);
    let mut lambda = cfg.initial_damping * max_diag.max(f64::MIN_POSITIVE);
    let mut nu = 2.0;
    for iter in 1..=cfg.max_iterations {
        if cur.jte.amax() <= cfg.gradient_tolerance {
            return Ok(Ok(Refined {
                pose,
                normal: cur,
                iterations: iter - 1,
            }));
        }
        let mut a = cur.jtj;
        for i in 0..N {
            a[(i, i)] += lambda;
        }
        let Some(chol) = Ldl::new(&a) else {
            lambda *= nu;
            nu *= 2.0;
            continue;
        };
        let step = chol.solve(&(-cur.jte));
        let x = P::to_vector(&pose);
        if step.norm() <= cfg.step_tolerance * (x.norm() + cfg.step_tolerance) {
            return Ok(Ok(Refined {
                pose,
                normal: cur,
                iterations: iter,
            }));
        }
        let candidate = P::from_vector(&(x + step));
        // Predicted reduction of sse by the linear model: -2 d^T g - d^T J^T J d = d^T (lambda d - g).
        let predicted = step.dot(&(step * lambda - cur.jte));
        // Nearly Gauss-Newton and the model promises less than the cost tolerance: the current
        // pose is the minimum within tolerance, no need to evaluate the step.
        let max_diag = (0..N).map(|i| cur.jtj[(i, i)]).fold(0.0, f64::max);
        if lambda <= 1e-3 * max_diag
            && (0.0..=cfg.relative_cost_tolerance * cur.sse).contains(&predicted)
        {
            return Ok(Ok(Refined {
                pose,
                normal: cur,
                iterations: iter,
            }));
        }
        let rho = match problem.normal_equations(&candidate) {
            Ok(n) if n.sse.is_finite() && predicted > 0.0 => {
                let rho = (cur.sse - n.sse) / predicted;
                if rho > 0.0 {
                    let old = cur.sse;
                    pose = P::normalized(&candidate);
                    cur = if pose == candidate {
                        n
                    } else {
                        problem
                            .normal_equations(&pose)
                            .map_err(|(index, z)| PoseError::PointBehindCamera { index, z })?
                    };
                    if old - cur.sse <= cfg.relative_cost_tolerance * old {
                        return Ok(Ok(Refined {
                            pose,
                            normal: cur,
                            iterations: iter,
                        }));
                    }
                }
                rho
            }
            _ => -1.0,
        };
        if rho > 0.0 {
            let f = 2.0 * rho - 1.0;
            lambda *= (1.0 - f * f * f).max(1.0 / 3.0);
            nu = 2.0;
        } else {
            lambda *= nu;
            nu *= 2.0;
        }
        if !lambda.is_finite() {
            // No step size lowers the cost any more: the pose is a minimum to machine precision.
            return Ok(Ok(Refined {
                pose,
                normal: cur,
                iterations: iter,
            }));
        }
    }
    Ok(Err(Unconverged {
        pose,
        normal: cur,
        iterations: cfg.max_iterations,
    }))
}

/// The parameter covariance `sigma^2 (J^T J)^-1` with
/// `sigma^2 = max(sse / (2 n_points - N), sigma_min^2)`.
pub(crate) fn covariance<const N: usize>(
    normal: &Normal<N>,
    n_points: usize,
    min_pixel_sigma: f64,
) -> Result<SMatrix<f64, N, N>, PoseError> {
    let dof = (2 * n_points).saturating_sub(N).max(1) as f64;
    let var = (normal.sse / dof).max(min_pixel_sigma * min_pixel_sigma);
    let inv = Ldl::new(&normal.jtj)
        .ok_or(PoseError::Degenerate {
            reason: "J^T J is singular at the optimum: the points do not fix the pose",
        })?
        .inverse();
    Ok(inv * var)
}

/// The 2N x 6 Jacobian is not formed by the solver; this helper exists for tests that compare
/// the accumulated normal equations with an explicit one.
#[cfg(test)]
pub(crate) fn point_jacobian(
    k: &Intrinsics,
    pose: &Pose,
    p: &Point3<f64>,
) -> nalgebra::SMatrix<f64, 2, 6> {
    k.project_with_pose_jacobian(pose, p)
        .map(|(_, j)| j)
        .unwrap_or_else(|_| nalgebra::SMatrix::zeros())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// The accumulated normal equations equal those of the explicit 2N x 6 Jacobian.
    #[test]
    fn accumulated_normal_equations_match_explicit_jacobian() {
        let k = Intrinsics::new(560.0, 550.0, 1.5, 320.0, 240.0).expect("valid intrinsics");
        let pose = Pose::new(Vector3::new(0.3, -1.2, 0.4), Vector3::new(0.05, -0.1, 1.3));
        let model: Vec<Point3<f64>> = (0..7)
            .map(|i| {
                let f = f64::from(i);
                Point3::new(
                    0.1 * f.sin(),
                    0.07 * (1.3 * f).cos(),
                    0.05 * (0.7 * f).sin(),
                )
            })
            .collect();
        let image: Vec<Point2<f64>> = model
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let m = k.project(&pose.transform_point(p)).expect("in front");
                Point2::new(m.x + 0.3 * (i as f64).cos(), m.y - 0.2 * (i as f64).sin())
            })
            .collect();
        let n = normal_equations(&k, &model, &image, &pose).expect("in front");
        let mut jtj = Matrix6::zeros();
        let mut jte = Vector6::zeros();
        let mut sse = 0.0;
        for (p, m) in model.iter().zip(&image) {
            let j = point_jacobian(&k, &pose, p);
            let proj = k.project(&pose.transform_point(p)).expect("in front");
            let e = nalgebra::Vector2::new(proj.x - m.x, proj.y - m.y);
            jtj += j.transpose() * j;
            jte += j.transpose() * e;
            sse += e.norm_squared();
        }
        assert!((n.jtj - jtj).amax() < 1e-9 * jtj.amax());
        assert!((n.jte - jte).amax() < 1e-9 * jte.amax());
        assert!((n.sse - sse).abs() < 1e-12);
    }

    #[test]
    fn covariance_uses_the_noise_floor_on_exact_data() {
        let normal = Normal {
            jtj: Matrix6::identity() * 4.0,
            jte: Vector6::zeros(),
            sse: 0.0,
        };
        let c = covariance(&normal, 4, 0.5).expect("positive definite");
        assert!((c - Matrix6::identity() * (0.25 / 4.0)).amax() < 1e-15);
        let noisy = Normal { sse: 8.0, ..normal };
        // sse / (2N - 6) = 8 / 2 = 4 > 0.25.
        let c = covariance(&noisy, 4, 0.5).expect("positive definite");
        assert!((c - Matrix6::identity()).amax() < 1e-15);
        let singular = Normal {
            jtj: Matrix6::zeros(),
            ..normal
        };
        assert!(matches!(
            covariance(&singular, 4, 0.5),
            Err(PoseError::Degenerate { .. })
        ));
    }
}
