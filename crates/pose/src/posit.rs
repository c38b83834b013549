//! POSIT (DeMenthon and Davis, "Model-based object pose in 25 lines of code", 1995): the
//! initialiser the paper uses for four or more non-coplanar points (spec 4.4).
//!
//! With `M0` the first model point, `a_i = M_i - M0` and normalised image points `(x_i, y_i)`,
//! each iteration solves the scaled-orthographic system
//! `I = A^-1 sum a_i (x_i (1 + eps_i) - x_0)`, `J = A^-1 sum a_i (y_i (1 + eps_i) - y_0)`
//! with `A = sum a_i a_i^T`, takes the rows `i = I/|I|`, `j = J/|J|`, `k = i x j`, the depth
//! `Z0 = 2 / (|I| + |J|)`, and updates the perspective corrections `eps_i = (a_i . k) / Z0`.
//! The corrections depend only on the previous `k` and `Z0`, so nothing is stored per point and
//! nothing allocates. The rotation is projected onto SO(3) at the end (its rows are orthogonal
//! only at convergence).

use crate::{Intrinsics, Pose, PoseError};
use nalgebra::{Matrix3, Point2, Point3, Vector3};

/// Iterations POSIT runs before giving up.
pub const POSIT_MAX_ITERATIONS: usize = 100;
/// POSIT stops when the change of `k` plus the relative change of `Z0` is below this. POSIT
/// converges linearly and only initialises LM, so this need not be tight.
pub const POSIT_TOLERANCE: f64 = 1e-9;

/// Pose by POSIT from four or more non-coplanar model points and their pixels (already
/// undistorted). The first point is the reference point. Returns
/// [`PoseError::NotConverged`] with the last estimate when the iteration does not settle, and
/// [`PoseError::Degenerate`] when the points are coplanar.
pub fn posit(
    k: &Intrinsics,
    model: &[Point3<f64>],
    image: &[Point2<f64>],
) -> Result<Pose, PoseError> {
    check_correspondences(model, image)?;
    let m0 = model[0].coords;
    let n0 = k.pixel_to_normalized(&image[0]);
    let mut a = Matrix3::<f64>::zeros();
    let mut scale = 0.0f64;
    for p in &model[1..] {
        let d = p.coords - m0;
        a += d * d.transpose();
        scale = scale.max(d.norm_squared());
    }
    // Condition check relative to the model's size: coplanar points make A singular.
    let a_inv = a
        .try_inverse()
        .filter(|inv| inv.iter().all(|v| v.is_finite()) && a.determinant() > 1e-12 * scale.powi(3))
        .ok_or(PoseError::Degenerate {
            reason: "POSIT needs non-coplanar model points",
        })?;

    let mut kvec = Vector3::zeros();
    let mut z0_inv = 0.0; // 1 / Z0, so eps_i = (a_i . k) / Z0 = (a_i . k) * z0_inv; starts at eps = 0
    let mut rows = (Vector3::x(), Vector3::y());
    let mut z0 = 1.0;
    let mut converged = false;
    let mut iterations = 0;
    for iter in 1..=POSIT_MAX_ITERATIONS {
        iterations = iter;
        let mut bx = Vector3::zeros();
        let mut by = Vector3::zeros();
        for (p, m) in model[1..].iter().zip(&image[1..]) {
            let d = p.coords - m0;
            let n = k.pixel_to_normalized(m);
            let eps = 1.0 + d.dot(&kvec) * z0_inv;
            bx += d * (n.x * eps - n0.x);
            by += d * (n.y * eps - n0.y);
        }
        let iv = a_inv * bx;
        let jv = a_inv * by;
        let (ni, nj) = (iv.norm(), jv.norm());
        if !(ni > 0.0 && nj > 0.0 && ni.is_finite() && nj.is_finite()) {
            return Err(PoseError::Degenerate {
                reason: "POSIT found no scaled-orthographic solution",
            });
        }
        let i_row = iv / ni;
        let j_row = jv / nj;
        let k_new = i_row.cross(&j_row).normalize();
        let s = 0.5 * (ni + nj);
        let z0_new = 1.0 / s;
        let change = (k_new - kvec).norm() + (z0_new - z0).abs() / z0_new;
        kvec = k_new;
        z0 = z0_new;
        z0_inv = s;
        rows = (i_row, j_row);
        if change < POSIT_TOLERANCE {
            converged = true;
            break;
        }
    }
    let raw = Matrix3::from_rows(&[rows.0.transpose(), rows.1.transpose(), kvec.transpose()]);
    let r = nearest_rotation(&raw);
    let t = Vector3::new(n0.x * z0, n0.y * z0, z0) - r * m0;
    let pose = Pose::from_matrix(&r, t);
    if !pose.is_finite() {
        return Err(PoseError::Degenerate {
            reason: "POSIT produced a non-finite pose",
        });
    }
    if converged {
        Ok(pose)
    } else {
        Err(PoseError::NotConverged {
            iterations,
            estimate: pose,
        })
    }
}

/// The rotation closest (Frobenius) to `m`: `U diag(1, 1, det(U V^T)) V^T`.
/// The checks every solver makes first: as many pixels as model points, and at least four.
pub(crate) fn check_correspondences(
    model: &[Point3<f64>],
    image: &[Point2<f64>],
) -> Result<(), PoseError> {
    if model.len() != image.len() {
        return Err(PoseError::LengthMismatch {
            model: model.len(),
            image: image.len(),
        });
    }
    if model.len() < 4 {
        return Err(PoseError::TooFewPoints {
            needed: 4,
            got: model.len(),
        });
    }
    Ok(())
}

pub(crate) fn nearest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => {
            let d = (u * vt).determinant().signum();
            u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt
        }
        _ => Matrix3::identity(),
    }
}
