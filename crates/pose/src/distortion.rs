//! Lens distortion: OpenCV's radial-tangential ("plumb bob") model with `k1, k2, p1, p2, k3`
//! (spec 4.1, beyond the paper). Only the detected corner points are undistorted, never the
//! whole image.
//!
//! On normalised coordinates `(x, y)`, `r^2 = x^2 + y^2`:
//!
//! ```text
//! x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
//! y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y
//! ```
//!
//! Undistortion inverts this by Newton's method on the 2x2 system (OpenCV uses a fixed-point
//! iteration, which converges more slowly and can cycle for strong distortion). It starts from
//! the distorted point, stops when the residual is below [`UNDISTORT_TOLERANCE`] and reports a
//! typed error after [`UNDISTORT_MAX_ITERATIONS`] iterations or on a singular Jacobian (points
//! outside the region where the model is invertible).

use crate::{Intrinsics, PoseError};
use nalgebra::{Matrix2, Point2, Vector2};

/// Residual (normalised image units, ~1e-12 of the focal length) below which undistortion
/// stops.
pub const UNDISTORT_TOLERANCE: f64 = 1e-12;
/// Newton iterations allowed per point before undistortion reports non-convergence.
pub const UNDISTORT_MAX_ITERATIONS: usize = 20;

/// Radial-tangential distortion coefficients in OpenCV's order `(k1, k2, p1, p2, k3)`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Distortion {
    /// Radial, r^2.
    pub k1: f64,
    /// Radial, r^4.
    pub k2: f64,
    /// Tangential.
    pub p1: f64,
    /// Tangential.
    pub p2: f64,
    /// Radial, r^6.
    pub k3: f64,
}

impl Distortion {
    /// Coefficients in OpenCV's order; all must be finite.
    pub fn new(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Result<Self, PoseError> {
        let d = Self { k1, k2, p1, p2, k3 };
        d.validate()?;
        Ok(d)
    }

    /// From OpenCV's coefficient vector: 4 (`k3 = 0`) or 5 values, or more with the extra
    /// rational/thin-prism terms all zero (anything else is not this model).
    pub fn from_slice(c: &[f64]) -> Result<Self, PoseError> {
        let get = |i: usize| c.get(i).copied().unwrap_or(0.0);
        if c.len() < 4 {
            return Err(PoseError::DistortionCount { count: c.len() });
        }
        if let Some((i, extra)) = c.iter().enumerate().skip(5).find(|(_, v)| **v != 0.0) {
            return Err(PoseError::UnsupportedDistortion {
                index: i,
                value: *extra,
            });
        }
        Self::new(get(0), get(1), get(2), get(3), get(4))
    }

    fn validate(&self) -> Result<(), PoseError> {
        for (name, value) in [
            ("k1", self.k1),
            ("k2", self.k2),
            ("p1", self.p1),
            ("p2", self.p2),
            ("k3", self.k3),
        ] {
            if !value.is_finite() {
                return Err(PoseError::InvalidDistortion { name, value });
            }
        }
        Ok(())
    }

    /// True when every coefficient is zero.
    pub fn is_zero(&self) -> bool {
        *self == Self::default()
    }

    /// Distorts a normalised point.
    #[inline]
    pub fn distort(&self, n: &Point2<f64>) -> Point2<f64> {
        let (x, y) = (n.x, n.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        Point2::new(
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// The distorted point and the 2x2 Jacobian of [`Distortion::distort`].
    #[inline]
    fn distort_with_jacobian(&self, n: &Point2<f64>) -> (Point2<f64>, Matrix2<f64>) {
        let (x, y) = (n.x, n.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // d radial / d r2
        let dradial = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3);
        let d = self.distort(n);
        let j = Matrix2::new(
            radial + 2.0 * x * x * dradial + 2.0 * self.p1 * y + 6.0 * self.p2 * x,
            2.0 * x * y * dradial + 2.0 * self.p1 * x + 2.0 * self.p2 * y,
            2.0 * x * y * dradial + 2.0 * self.p1 * x + 2.0 * self.p2 * y,
            radial + 2.0 * y * y * dradial + 6.0 * self.p1 * y + 2.0 * self.p2 * x,
        );
        (d, j)
    }

    /// Undistorts a normalised point by Newton's method (see the module docs).
    pub fn undistort(&self, d: &Point2<f64>) -> Result<Point2<f64>, PoseError> {
        if !(d.x.is_finite() && d.y.is_finite()) {
            return Err(PoseError::NonFinite {
                which: "image",
                index: 0,
            });
        }
        let mut n = *d;
        let mut residual = f64::INFINITY;
        for _ in 0..UNDISTORT_MAX_ITERATIONS {
            let (f, j) = self.distort_with_jacobian(&n);
            let e = Vector2::new(f.x - d.x, f.y - d.y);
            residual = e.norm();
            if residual <= UNDISTORT_TOLERANCE {
                return Ok(n);
            }
            let Some(jinv) = j.try_inverse() else { break };
            let step = jinv * e;
            n -= step;
            if !(n.x.is_finite() && n.y.is_finite()) {
                break;
            }
        }
        // One last check: the loop may end exactly on a converged iterate.
        let f = self.distort(&n);
        let last = ((f.x - d.x).powi(2) + (f.y - d.y).powi(2)).sqrt();
        if last <= UNDISTORT_TOLERANCE {
            return Ok(n);
        }
        Err(PoseError::UndistortionNotConverged {
            x: d.x,
            y: d.y,
            iterations: UNDISTORT_MAX_ITERATIONS,
            residual: if last.is_finite() { last } else { residual },
        })
    }

    /// Distorts a pixel: pixel to normalised, distort, back to pixels.
    pub fn distort_pixel(&self, k: &Intrinsics, m: &Point2<f64>) -> Point2<f64> {
        k.normalized_to_pixel(&self.distort(&k.pixel_to_normalized(m)))
    }

    /// Undistorts a pixel (a detected corner) into the ideal pinhole pixel.
    pub fn undistort_pixel(
        &self,
        k: &Intrinsics,
        m: &Point2<f64>,
    ) -> Result<Point2<f64>, PoseError> {
        Ok(k.normalized_to_pixel(&self.undistort(&k.pixel_to_normalized(m))?))
    }
}
