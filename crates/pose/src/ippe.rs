//! IPPE, Infinitesimal Plane-based Pose Estimation (Collins and Bartoli, IJCV 2014): both pose
//! candidates of a planar target from the homography (spec 4.4, beyond the paper).
//!
//! A plane seen under perspective has, near the fronto-parallel view and under noise, two
//! reprojection minima related by a reflection about the line of sight; returning only one is
//! how the pose "flips" OpenCV/AprilTag users report arise. IPPE reads the first-order
//! (infinitesimal) behaviour of the homography `H` (plane, centred at its centroid, to
//! normalised image) at the centroid: its image `v = (H02, H12)` and its 2x2 Jacobian `J`. With
//! `R_v` a rotation taking the optical axis to `(v, 1)`, `B = [I | -v] R_v[:, :2]` and
//! `A = B^-1 J`, the largest singular value `gamma` of `A` is the inverse depth and
//! `R~ = A / gamma` is the top-left 2x2 block of the rotation; its third row has two signs,
//! which give the two candidates `R = R_v [c1 c2 c1 x c2]`. Each translation is then the
//! linear least-squares translation for that rotation.
//!
//! The homography is the normalised DLT with `H22 = 1` (well defined because the centroid is in
//! front of the camera), solved from 8x8 normal equations accumulated point by point: no
//! allocation for any number of points.

use crate::PoseError;
use nalgebra::{Matrix2, Matrix3, Point2, SMatrix, SVector, Vector2, Vector3};

/// Homography (3x3, `H22 = 1`) mapping plane points to image points, by normalised DLT.
/// `pts(i)` gives the `i`-th (plane point, image point) pair, `i < n`.
pub(crate) fn homography(
    n: usize,
    pts: impl Fn(usize) -> (Point2<f64>, Point2<f64>),
) -> Result<Matrix3<f64>, PoseError> {
    let (tp, tp_fwd, _) = normalizer(n, |i| pts(i).0);
    let (ti, _, ti_inv) = normalizer(n, |i| pts(i).1);
    let mut ata = SMatrix::<f64, 8, 8>::zeros();
    let mut atb = SVector::<f64, 8>::zeros();
    for i in 0..n {
        let (p, m) = pts(i);
        let (x, y) = (tp.0 * (p.x - tp.1.x), tp.0 * (p.y - tp.1.y));
        let (u, v) = (ti.0 * (m.x - ti.1.x), ti.0 * (m.y - ti.1.y));
        let r1 = SVector::<f64, 8>::from([x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y]);
        let r2 = SVector::<f64, 8>::from([0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y]);
        ata += r1 * r1.transpose() + r2 * r2.transpose();
        atb += r1 * u + r2 * v;
    }
    let h = ata
        .cholesky()
        .map(|c| c.solve(&atb))
        .ok_or(PoseError::Degenerate {
            reason: "homography is not determined (three or more points collinear?)",
        })?;
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0);
    let full = ti_inv * hn * tp_fwd;
    let s = full[(2, 2)];
    if s == 0.0 || !full.iter().all(|v| v.is_finite()) {
        return Err(PoseError::Degenerate {
            reason: "homography is singular",
        });
    }
    Ok(full / s)
}

/// The affine (weak-perspective) approximation of the homography: `H = [[A, c], [0, 0, 1]]`
/// with `c` the mean image point and `A` the least-squares 2x2 map from the (centred) plane
/// points. A fallback when the projective homography of nearly degenerate points is unusable.
pub(crate) fn affine_homography(
    n: usize,
    pts: impl Fn(usize) -> (Point2<f64>, Point2<f64>),
) -> Result<Matrix3<f64>, PoseError> {
    let nf = n.max(1) as f64;
    let (pc, ic) = (0..n).fold((Vector2::zeros(), Vector2::zeros()), |(a, b), i| {
        let (p, m) = pts(i);
        (a + p.coords, b + m.coords)
    });
    let (pc, ic) = (pc / nf, ic / nf);
    let mut ptp = Matrix2::<f64>::zeros();
    let mut ptm = Matrix2::<f64>::zeros();
    for i in 0..n {
        let (p, m) = pts(i);
        let (dp, dm) = (p.coords - pc, m.coords - ic);
        ptp += dp * dp.transpose();
        ptm += dp * dm.transpose();
    }
    let a = (ptp.try_inverse().ok_or(PoseError::Degenerate {
        reason: "affine map not determined",
    })? * ptm)
        .transpose();
    // m = A (p - pc) + ic = A p + (ic - A pc)
    let c = ic - a * pc;
    Ok(Matrix3::new(
        a[(0, 0)],
        a[(0, 1)],
        c.x,
        a[(1, 0)],
        a[(1, 1)],
        c.y,
        0.0,
        0.0,
        1.0,
    ))
}

/// Isotropic (Hartley) normalisation `q = s (p - c)`: returns `(s, c)`, the forward matrix
/// and its inverse.
fn normalizer(
    n: usize,
    pt: impl Fn(usize) -> Point2<f64>,
) -> ((f64, Vector2<f64>), Matrix3<f64>, Matrix3<f64>) {
    let nf = n.max(1) as f64;
    let c = (0..n).fold(Vector2::zeros(), |acc, i| acc + pt(i).coords) / nf;
    let rms = ((0..n)
        .map(|i| (pt(i).coords - c).norm_squared())
        .sum::<f64>()
        / nf)
        .sqrt();
    let s = if rms > 0.0 {
        std::f64::consts::SQRT_2 / rms
    } else {
        1.0
    };
    // Forward: q = s (p - c). Inverse: p = q / s + c.
    let fwd = Matrix3::new(s, 0.0, -s * c.x, 0.0, s, -s * c.y, 0.0, 0.0, 1.0);
    let inv = Matrix3::new(1.0 / s, 0.0, c.x, 0.0, 1.0 / s, c.y, 0.0, 0.0, 1.0);
    ((s, c), fwd, inv)
}

/// The IPPE rotation candidates (camera-from-plane), from `H` of a plane centred at its
/// centroid to normalised image coordinates (`H22 = 1`). Returns `(R1, R2, gamma)`.
pub(crate) fn rotations(h: &Matrix3<f64>) -> Result<(Matrix3<f64>, Matrix3<f64>), PoseError> {
    let (p, q) = (h[(0, 2)], h[(1, 2)]);
    let j = Matrix2::new(
        h[(0, 0)] - h[(2, 0)] * p,
        h[(0, 1)] - h[(2, 1)] * p,
        h[(1, 0)] - h[(2, 0)] * q,
        h[(1, 1)] - h[(2, 1)] * q,
    );
    // R_v: the minimal rotation taking e3 to v_hat = (p, q, 1)/|.| (c = v_hat.z > 0).
    let vh = Vector3::new(p, q, 1.0).normalize();
    let kx = Vector3::new(-vh.y, vh.x, 0.0); // e3 x v_hat
    let kh = crate::so3::hat(&kx);
    let rv = Matrix3::identity() + kh + kh * kh / (1.0 + vh.z);
    let b = Matrix2::new(
        rv[(0, 0)] - p * rv[(2, 0)],
        rv[(0, 1)] - p * rv[(2, 1)],
        rv[(1, 0)] - q * rv[(2, 0)],
        rv[(1, 1)] - q * rv[(2, 1)],
    );
    let a = b.try_inverse().ok_or(PoseError::Degenerate {
        reason: "IPPE: singular B",
    })? * j;
    // Largest singular value of A from A A^T.
    let (s00, s01, s11) = (
        a[(0, 0)] * a[(0, 0)] + a[(0, 1)] * a[(0, 1)],
        a[(0, 0)] * a[(1, 0)] + a[(0, 1)] * a[(1, 1)],
        a[(1, 0)] * a[(1, 0)] + a[(1, 1)] * a[(1, 1)],
    );
    let gamma2 = 0.5 * (s00 + s11 + ((s00 - s11).powi(2) + 4.0 * s01 * s01).sqrt());
    let gamma = gamma2.sqrt();
    if !gamma.is_finite() || gamma <= f64::EPSILON {
        return Err(PoseError::Degenerate {
            reason: "IPPE: the homography has no scale (plane seen edge-on?)",
        });
    }
    let rt = a / gamma;
    let b0 = (1.0 - rt[(0, 0)].powi(2) - rt[(1, 0)].powi(2))
        .max(0.0)
        .sqrt();
    let mut b1 = (1.0 - rt[(0, 1)].powi(2) - rt[(1, 1)].powi(2))
        .max(0.0)
        .sqrt();
    if -(rt[(0, 0)] * rt[(0, 1)] + rt[(1, 0)] * rt[(1, 1)]) < 0.0 {
        b1 = -b1;
    }
    let build = |sign: f64| {
        let c1 = Vector3::new(rt[(0, 0)], rt[(1, 0)], sign * b0);
        let c2 = Vector3::new(rt[(0, 1)], rt[(1, 1)], sign * b1);
        let c3 = c1.cross(&c2);
        rv * Matrix3::from_columns(&[c1, c2, c3])
    };
    Ok((build(1.0), build(-1.0)))
}

/// Least-squares translation for a known rotation `r` (camera-from-plane) of plane points
/// `(x, y, 0)` seen at normalised image points.
/// `pts(i)` gives the `i`-th (plane point, normalised image point) pair, `i < n`.
pub(crate) fn translation(
    r: &Matrix3<f64>,
    n: usize,
    pts: impl Fn(usize) -> (Point2<f64>, Point2<f64>),
) -> Result<Vector3<f64>, PoseError> {
    let mut ata = Matrix3::<f64>::zeros();
    let mut atb = Vector3::<f64>::zeros();
    for i in 0..n {
        let (p, m) = pts(i);
        let rx = r.column(0) * p.x + r.column(1) * p.y;
        let a1 = Vector3::new(1.0, 0.0, -m.x);
        let a2 = Vector3::new(0.0, 1.0, -m.y);
        ata += a1 * a1.transpose() + a2 * a2.transpose();
        atb += a1 * (m.x * rx.z - rx.x) + a2 * (m.y * rx.z - rx.y);
    }
    ata.cholesky()
        .map(|c| c.solve(&atb))
        .ok_or(PoseError::Degenerate {
            reason: "IPPE: translation not determined",
        })
}
