//! Rotations by the exponential map (spec 4.3, paper eqs. 23-24), and the rigid pose type.
//!
//! `exp` is Rodrigues' formula `R = I + A [w]x + B [w]x^2` with `A = sin(t)/t`,
//! `B = (1 - cos t)/t^2`, `t = |w|`; below [`SMALL_ANGLE`] both coefficients come from their
//! Taylor series so nothing divides by a tiny angle. `log` takes the angle from
//! `atan2(|vee(R - R^T)|/2, (tr R - 1)/2)`, which is accurate at every angle, and the axis from
//! the antisymmetric part except near pi (cos t < -1/2), where the antisymmetric part vanishes and
//! the axis is read from the symmetric part `(R + R^T)/2 - cos(t) I = (1 - cos t) n n^T`.
//!
//! The solver differentiates `exp(w) p` with respect to `w` through the left Jacobian of SO(3):
//! `d(exp(w) p)/dw = -[exp(w) p]x J_l(w)`, `J_l(w) = I + B [w]x + C [w]x^2`,
//! `C = (t - sin t)/t^3` (see [`exp_point_jacobian`]).

use nalgebra::{
    Isometry3, Matrix3, Point3, Rotation3, SVector, Translation3, UnitQuaternion, Vector3,
};

/// Below this rotation angle (radians) `exp`, `log` and `J_l` use Taylor series. Truncation
/// error at the threshold is below 1e-20.
pub const SMALL_ANGLE: f64 = 1e-3;

/// The skew-symmetric (cross-product) matrix `[w]x`, so `[w]x v = w x v`.
#[inline]
pub fn hat(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

/// Coefficients `(A, B, C) = (sin t / t, (1 - cos t)/t^2, (t - sin t)/t^3)` for `t^2 = theta2`.
#[inline]
fn coefficients(theta2: f64) -> (f64, f64, f64) {
    if theta2 < SMALL_ANGLE * SMALL_ANGLE {
        let t4 = theta2 * theta2;
        (
            1.0 - theta2 / 6.0 + t4 / 120.0,
            0.5 - theta2 / 24.0 + t4 / 720.0,
            1.0 / 6.0 - theta2 / 120.0 + t4 / 5040.0,
        )
    } else {
        let t = theta2.sqrt();
        let (s, c) = t.sin_cos();
        (s / t, (1.0 - c) / theta2, (t - s) / (theta2 * t))
    }
}

/// The rotation matrix `exp([w]x)` of a rotation vector `w` (axis times angle, radians).
#[inline]
pub fn exp(w: &Vector3<f64>) -> Matrix3<f64> {
    let (a, b, _) = coefficients(w.norm_squared());
    let k = hat(w);
    Matrix3::identity() + k * a + k * k * b
}

/// The rotation matrix and the left Jacobian `J_l(w)` together (they share the trigonometry).
#[inline]
pub fn exp_and_left_jacobian(w: &Vector3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let (a, b, c) = coefficients(w.norm_squared());
    let k = hat(w);
    let k2 = k * k;
    (
        Matrix3::identity() + k * a + k2 * b,
        Matrix3::identity() + k * b + k2 * c,
    )
}

/// The left Jacobian of SO(3): `exp(w + d) ~ exp(J_l(w) d) exp(w)` for small `d`.
#[inline]
pub fn left_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    exp_and_left_jacobian(w).1
}

/// The 3x3 Jacobian of `exp(w) p` with respect to `w`: `-[exp(w) p]x J_l(w)`.
#[inline]
pub fn exp_point_jacobian(w: &Vector3<f64>, p: &Vector3<f64>) -> Matrix3<f64> {
    let (r, jl) = exp_and_left_jacobian(w);
    -hat(&(r * p)) * jl
}

/// The rotation vector `w` with `exp(w) = r` and `|w| <= pi`. `r` must be a rotation matrix
/// (orthonormal, det 1); for other matrices the result is that of a nearby rotation.
pub fn log(r: &Matrix3<f64>) -> Vector3<f64> {
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    let s = 0.5 * v.norm(); // sin(theta)
    let c = (0.5 * (r.trace() - 1.0)).clamp(-1.0, 1.0); // cos(theta)
    let theta = s.atan2(c);
    if theta < SMALL_ANGLE {
        // theta / (2 sin theta) = 1/2 (1 + t^2/6 + 7 t^4/360 + ...)
        let t2 = theta * theta;
        return v * (0.5 * (1.0 + t2 / 6.0 + 7.0 * t2 * t2 / 360.0));
    }
    if c > -0.5 {
        return v * (theta / (2.0 * s));
    }
    // Near pi: (R + R^T)/2 - c I = (1 - c) n n^T. Take the column with the largest diagonal.
    let sym = (r + r.transpose()) * 0.5 - Matrix3::identity() * c;
    let d = Vector3::new(sym[(0, 0)], sym[(1, 1)], sym[(2, 2)]);
    let k = d.imax();
    let col = sym.column(k).into_owned();
    let mut n = col / (d[k].max(f64::MIN_POSITIVE)).sqrt();
    let norm = n.norm();
    if norm > 0.0 {
        n /= norm;
    }
    // The antisymmetric part is 2 sin(theta) n: it fixes the sign of the axis.
    if n.dot(&v) < 0.0 {
        n = -n;
    }
    n * theta
}

/// A rigid transform from the model (rig) frame to the camera frame:
/// `x_camera = exp([rotation]x) x_model + translation`.
///
/// This is the solver's parameter vector `[wx, wy, wz, tx, ty, tz]` (spec 4.3) in a named
/// form; convert with [`Pose::to_params`], [`Pose::from_params`], [`Pose::to_isometry`] and
/// [`Pose::from_isometry`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation vector (axis times angle, radians).
    pub rotation: Vector3<f64>,
    /// Translation (same unit as the model points, usually metres).
    pub translation: Vector3<f64>,
}

impl Default for Pose {
    fn default() -> Self {
        Self::identity()
    }
}

impl Pose {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: Vector3::zeros(),
            translation: Vector3::zeros(),
        }
    }

    /// A pose from a rotation vector and a translation.
    pub fn new(rotation: Vector3<f64>, translation: Vector3<f64>) -> Self {
        Self {
            rotation,
            translation,
        }
    }

    /// A pose from a rotation matrix (assumed orthonormal) and a translation.
    pub fn from_matrix(rotation: &Matrix3<f64>, translation: Vector3<f64>) -> Self {
        Self {
            rotation: log(rotation),
            translation,
        }
    }

    /// The rotation matrix `exp([rotation]x)`.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        exp(&self.rotation)
    }

    /// The parameter vector `[wx, wy, wz, tx, ty, tz]`.
    pub fn to_params(&self) -> SVector<f64, 6> {
        SVector::<f64, 6>::new(
            self.rotation.x,
            self.rotation.y,
            self.rotation.z,
            self.translation.x,
            self.translation.y,
            self.translation.z,
        )
    }

    /// The pose of a parameter vector `[wx, wy, wz, tx, ty, tz]`.
    pub fn from_params(p: &SVector<f64, 6>) -> Self {
        Self {
            rotation: Vector3::new(p[0], p[1], p[2]),
            translation: Vector3::new(p[3], p[4], p[5]),
        }
    }

    /// As an nalgebra isometry (same transform).
    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.translation),
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
                self.rotation_matrix(),
            )),
        )
    }

    /// From an nalgebra isometry.
    pub fn from_isometry(iso: &Isometry3<f64>) -> Self {
        Self {
            rotation: iso.rotation.scaled_axis(),
            translation: iso.translation.vector,
        }
    }

    /// Maps a model point into the camera frame.
    pub fn transform_point(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.rotation_matrix() * p.coords + self.translation)
    }

    /// The inverse transform (camera frame to model frame).
    pub fn inverse(&self) -> Self {
        let r = self.rotation_matrix();
        Self {
            rotation: -self.rotation,
            translation: -(r.transpose() * self.translation),
        }
    }

    /// The angle in radians of the rotation between this pose's and `other`'s orientation.
    pub fn rotation_angle_to(&self, other: &Pose) -> f64 {
        let d = self.rotation_matrix().transpose() * other.rotation_matrix();
        log(&d).norm()
    }

    /// True when all six parameters are finite.
    pub fn is_finite(&self) -> bool {
        self.rotation
            .iter()
            .chain(self.translation.iter())
            .all(|v| v.is_finite())
    }

    /// The same rotation with the rotation vector wrapped to angle `<= pi` (the solver keeps
    /// its parameters there so the map stays well conditioned).
    pub fn normalized(&self) -> Self {
        let t = self.rotation.norm();
        if t > std::f64::consts::PI {
            Self {
                rotation: log(&exp(&self.rotation)),
                translation: self.translation,
            }
        } else {
            *self
        }
    }
}

impl From<Pose> for Isometry3<f64> {
    fn from(p: Pose) -> Self {
        p.to_isometry()
    }
}

impl From<Isometry3<f64>> for Pose {
    fn from(iso: Isometry3<f64>) -> Self {
        Pose::from_isometry(&iso)
    }
}
