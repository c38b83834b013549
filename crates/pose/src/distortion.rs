//! Lens distortion of corner points, in the three models ROS and OpenCV calibrations use
//! (spec 4.1, beyond the paper). Only the detected corner points are undistorted, never the
//! whole image.
//!
//! On undistorted normalised coordinates `(x, y)` (pinhole, `z = 1`), `r^2 = x^2 + y^2`:
//!
//! - **`plumb_bob`** (OpenCV's default, `k1, k2, p1, p2[, k3]`) and **`rational_polynomial`**
//!   (`k1, k2, p1, p2, k3, k4, k5, k6`, OpenCV's `CALIB_RATIONAL_MODEL`):
//!
//!   ```text
//!   radial = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
//!   x_d = x radial + 2 p1 x y + p2 (r^2 + 2 x^2)
//!   y_d = y radial + p1 (r^2 + 2 y^2) + 2 p2 x y
//!   ```
//!   (`plumb_bob` is the case `k4 = k5 = k6 = 0`).
//! - **`equidistant`** (fisheye, OpenCV's `cv::fisheye`, `k1, k2, k3, k4`): with
//!   `theta = atan(r)` the angle of the ray from the optical axis,
//!
//!   ```text
//!   theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//!   (x_d, y_d) = (theta_d / r) (x, y)
//!   ```
//!
//! The distorted normalised point goes through the camera matrix as usual (`u = fx x_d + s
//! y_d + cx`, which is OpenCV's `fx (x_d + alpha y_d) + cx` for the fisheye model).
//!
//! Undistortion inverts these by Newton's method: on the 2x2 system for the two polynomial
//! models (OpenCV uses a fixed-point iteration, which converges more slowly and can cycle for
//! strong distortion), on `theta` alone for the fisheye model. It starts from the distorted
//! point, stops when the residual is below [`UNDISTORT_TOLERANCE`] (then takes one more step
//! if that lowers the residual further) and reports a typed error after
//! [`UNDISTORT_MAX_ITERATIONS`] iterations or on a singular Jacobian (points outside the
//! region where the model is invertible). A fisheye point whose ray lies 90 degrees or more
//! off the axis has no pinhole image and is refused ([`PoseError::BeyondPinholeView`]).

use crate::{Intrinsics, PoseError};
use nalgebra::{Matrix2, Point2, Vector2};
use std::fmt;
use std::str::FromStr;

/// Residual (normalised image units, ~1e-12 of the focal length) below which undistortion
/// stops.
pub const UNDISTORT_TOLERANCE: f64 = 1e-12;
/// Newton iterations allowed per point before undistortion reports non-convergence.
pub const UNDISTORT_MAX_ITERATIONS: usize = 20;

/// Which distortion model, by the names ROS uses in `sensor_msgs/CameraInfo.distortion_model`
/// (`sensor_msgs/distortion_models.h`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DistortionModel {
    /// `plumb_bob`: radial-tangential, `k1, k2, p1, p2, k3`.
    PlumbBob,
    /// `rational_polynomial`: `k1, k2, p1, p2, k3, k4, k5, k6`.
    RationalPolynomial,
    /// `equidistant`: OpenCV's fisheye model, `k1, k2, k3, k4`.
    Equidistant,
}

impl DistortionModel {
    /// Every model, in the order of the enum.
    pub const ALL: [DistortionModel; 3] = [
        DistortionModel::PlumbBob,
        DistortionModel::RationalPolynomial,
        DistortionModel::Equidistant,
    ];

    /// The ROS name: `plumb_bob`, `rational_polynomial` or `equidistant`.
    pub fn name(self) -> &'static str {
        match self {
            DistortionModel::PlumbBob => "plumb_bob",
            DistortionModel::RationalPolynomial => "rational_polynomial",
            DistortionModel::Equidistant => "equidistant",
        }
    }

    /// The coefficient names in the order of the coefficient vector (ROS `D`, OpenCV
    /// `distCoeffs`).
    pub fn coefficient_names(self) -> &'static [&'static str] {
        match self {
            DistortionModel::PlumbBob => &["k1", "k2", "p1", "p2", "k3"],
            DistortionModel::RationalPolynomial => {
                &["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"]
            }
            DistortionModel::Equidistant => &["k1", "k2", "k3", "k4"],
        }
    }

    /// The model of a name: the ROS names, and `fisheye` for `equidistant` (OpenCV's name).
    /// Case-sensitive, as ROS is.
    pub fn from_name(name: &str) -> Result<Self, PoseError> {
        match name {
            "plumb_bob" => Ok(DistortionModel::PlumbBob),
            "rational_polynomial" => Ok(DistortionModel::RationalPolynomial),
            "equidistant" | "fisheye" => Ok(DistortionModel::Equidistant),
            _ => Err(PoseError::UnknownDistortionModel {
                name: name.to_string(),
            }),
        }
    }
}

impl fmt::Display for DistortionModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for DistortionModel {
    type Err = PoseError;
    fn from_str(s: &str) -> Result<Self, PoseError> {
        Self::from_name(s)
    }
}

/// A lens distortion model with its coefficients (OpenCV's definitions, see the module docs).
///
/// Build it checked with [`Distortion::plumb_bob`], [`Distortion::rational_polynomial`],
/// [`Distortion::equidistant`], [`Distortion::from_model`] (a model name and a coefficient
/// vector, as in ROS `CameraInfo`) or [`Distortion::from_opencv`] (an OpenCV `distCoeffs`
/// vector). A value built directly from the variants is checked by [`Distortion::validate`];
/// a non-finite coefficient never yields NaN silently: undistortion reports it.
/// `Default` is no distortion (`plumb_bob` with zero coefficients).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distortion {
    /// Radial-tangential (`plumb_bob`).
    PlumbBob {
        /// Radial, r^2.
        k1: f64,
        /// Radial, r^4.
        k2: f64,
        /// Tangential.
        p1: f64,
        /// Tangential.
        p2: f64,
        /// Radial, r^6.
        k3: f64,
    },
    /// Rational radial and tangential (`rational_polynomial`).
    RationalPolynomial {
        /// Numerator, r^2.
        k1: f64,
        /// Numerator, r^4.
        k2: f64,
        /// Tangential.
        p1: f64,
        /// Tangential.
        p2: f64,
        /// Numerator, r^6.
        k3: f64,
        /// Denominator, r^2.
        k4: f64,
        /// Denominator, r^4.
        k5: f64,
        /// Denominator, r^6.
        k6: f64,
    },
    /// Fisheye (`equidistant`, OpenCV's `cv::fisheye`).
    Equidistant {
        /// theta^3 term.
        k1: f64,
        /// theta^5 term.
        k2: f64,
        /// theta^7 term.
        k3: f64,
        /// theta^9 term.
        k4: f64,
    },
}

impl Default for Distortion {
    fn default() -> Self {
        Self::NONE
    }
}

/// Why a radial profile cannot belong to a lens (see [`Distortion::check_monotonic`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum ProfileFault {
    /// The distorted radius stops growing at this undistorted radius (or angle, fisheye).
    FoldsBack(f64),
    /// The distorted radius never reaches the image corner.
    NeverReaches,
}

impl Distortion {
    /// No distortion.
    pub const NONE: Distortion = Distortion::PlumbBob {
        k1: 0.0,
        k2: 0.0,
        p1: 0.0,
        p2: 0.0,
        k3: 0.0,
    };

    /// Radial-tangential coefficients in OpenCV's order; all must be finite.
    pub fn plumb_bob(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Result<Self, PoseError> {
        let d = Self::PlumbBob { k1, k2, p1, p2, k3 };
        d.validate()?;
        Ok(d)
    }

    /// Rational-polynomial coefficients in OpenCV's order `[k1, k2, p1, p2, k3, k4, k5, k6]`;
    /// all must be finite.
    pub fn rational_polynomial(c: [f64; 8]) -> Result<Self, PoseError> {
        let [k1, k2, p1, p2, k3, k4, k5, k6] = c;
        let d = Self::RationalPolynomial {
            k1,
            k2,
            p1,
            p2,
            k3,
            k4,
            k5,
            k6,
        };
        d.validate()?;
        Ok(d)
    }

    /// Fisheye coefficients `k1..k4` (OpenCV's `cv::fisheye` `D`); all must be finite.
    pub fn equidistant(k1: f64, k2: f64, k3: f64, k4: f64) -> Result<Self, PoseError> {
        let d = Self::Equidistant { k1, k2, k3, k4 };
        d.validate()?;
        Ok(d)
    }

    /// A model and its coefficient vector, as ROS `CameraInfo` gives them
    /// (`distortion_model`, `D`): `plumb_bob` takes 4 or 5 values (`k3 = 0` when absent),
    /// `rational_polynomial` 8 (or 12 or 14 with OpenCV's thin-prism and tilt terms all zero),
    /// `equidistant` 4. An empty vector means no distortion for the two polynomial models (ROS
    /// publishes rectified images so); a fisheye lens always needs its 4 coefficients.
    pub fn from_model(model: DistortionModel, c: &[f64]) -> Result<Self, PoseError> {
        let count = |accepted| PoseError::DistortionCount {
            model: model.name(),
            count: c.len(),
            accepted,
        };
        match model {
            DistortionModel::PlumbBob => match c.len() {
                0 => Ok(Self::NONE),
                4 | 5 => Self::plumb_bob(c[0], c[1], c[2], c[3], c.get(4).copied().unwrap_or(0.0)),
                _ => Err(count("4 or 5 (k1, k2, p1, p2[, k3])")),
            },
            DistortionModel::RationalPolynomial => match c.len() {
                0 => Ok(Self::NONE),
                8 | 12 | 14 => {
                    reject_extra_terms(c)?;
                    let mut a = [0.0; 8];
                    a.copy_from_slice(&c[..8]);
                    Self::rational_polynomial(a)
                }
                _ => Err(count(
                    "8 (k1, k2, p1, p2, k3, k4, k5, k6; 12 or 14 with the thin-prism and tilt terms zero)",
                )),
            },
            DistortionModel::Equidistant => match c {
                [k1, k2, k3, k4] => Self::equidistant(*k1, *k2, *k3, *k4),
                _ => Err(count("4 (k1, k2, k3, k4)")),
            },
        }
    }

    /// [`Distortion::from_model`] with the model by name (see [`DistortionModel::from_name`]).
    pub fn from_name(model: &str, c: &[f64]) -> Result<Self, PoseError> {
        Self::from_model(DistortionModel::from_name(model)?, c)
    }

    /// An OpenCV `distCoeffs` vector of `cv::calibrateCamera`: 4 or 5 values are
    /// `plumb_bob`, 8 `rational_polynomial`, 12 or 14 `rational_polynomial` when the
    /// thin-prism (`s1..s4`) and tilt (`tauX, tauY`) terms are zero. A fisheye (`cv::fisheye`)
    /// vector also has 4 values, so it cannot be told from its length: use
    /// [`Distortion::from_model`] with [`DistortionModel::Equidistant`].
    pub fn from_opencv(c: &[f64]) -> Result<Self, PoseError> {
        match c.len() {
            4 | 5 => Self::from_model(DistortionModel::PlumbBob, c),
            8 | 12 | 14 => Self::from_model(DistortionModel::RationalPolynomial, c),
            n => Err(PoseError::DistortionCount {
                model: "OpenCV",
                count: n,
                accepted: "4 or 5 (plumb_bob: k1, k2, p1, p2[, k3]), 8 (rational_polynomial: k1, k2, p1, p2, k3, k4, k5, k6), or 12 or 14 with the thin-prism and tilt terms zero; a fisheye (equidistant) calibration has 4 and must name its model",
            }),
        }
    }

    /// The model.
    pub fn model(&self) -> DistortionModel {
        match self {
            Distortion::PlumbBob { .. } => DistortionModel::PlumbBob,
            Distortion::RationalPolynomial { .. } => DistortionModel::RationalPolynomial,
            Distortion::Equidistant { .. } => DistortionModel::Equidistant,
        }
    }

    /// The coefficients in the order of [`DistortionModel::coefficient_names`] (ROS `D`).
    pub fn coefficients(&self) -> Vec<f64> {
        let (a, n) = self.coefficient_array();
        a[..n].to_vec()
    }

    /// The coefficients in a fixed array (no allocation) and how many there are.
    fn coefficient_array(&self) -> ([f64; 8], usize) {
        match *self {
            Distortion::PlumbBob { k1, k2, p1, p2, k3 } => ([k1, k2, p1, p2, k3, 0.0, 0.0, 0.0], 5),
            Distortion::RationalPolynomial {
                k1,
                k2,
                p1,
                p2,
                k3,
                k4,
                k5,
                k6,
            } => ([k1, k2, p1, p2, k3, k4, k5, k6], 8),
            Distortion::Equidistant { k1, k2, k3, k4 } => ([k1, k2, k3, k4, 0.0, 0.0, 0.0, 0.0], 4),
        }
    }

    /// `Ok` when every coefficient is finite, else [`PoseError::InvalidDistortion`] naming it.
    pub fn validate(&self) -> Result<(), PoseError> {
        let names = self.model().coefficient_names();
        let (values, _) = self.coefficient_array();
        for (name, value) in names.iter().zip(values) {
            if !value.is_finite() {
                return Err(PoseError::InvalidDistortion { name, value });
            }
        }
        Ok(())
    }

    /// True when the model maps every point to itself (a polynomial model with all
    /// coefficients zero). A fisheye model never is: with zero coefficients it is the ideal
    /// f-theta lens, `r_d = atan(r)`.
    pub fn is_identity(&self) -> bool {
        match self {
            Distortion::Equidistant { .. } => false,
            _ => self.coefficient_array().0.iter().all(|c| *c == 0.0),
        }
    }

    /// Polynomial models: `(k1, k2, p1, p2, k3, k4, k5, k6)` with zeros for plumb bob.
    #[inline]
    fn polynomial(&self) -> Option<[f64; 8]> {
        match *self {
            Distortion::PlumbBob { k1, k2, p1, p2, k3 } => {
                Some([k1, k2, p1, p2, k3, 0.0, 0.0, 0.0])
            }
            Distortion::RationalPolynomial {
                k1,
                k2,
                p1,
                p2,
                k3,
                k4,
                k5,
                k6,
            } => Some([k1, k2, p1, p2, k3, k4, k5, k6]),
            Distortion::Equidistant { .. } => None,
        }
    }

    /// Distorts a normalised point.
    #[inline]
    pub fn distort(&self, n: &Point2<f64>) -> Point2<f64> {
        match self.polynomial() {
            Some(c) => polynomial_distort(&c, n).0,
            None => {
                let r = n.x.hypot(n.y);
                if r < 1e-8 {
                    return *n;
                }
                let (theta_d, _) = self.fisheye_theta_d(r.atan());
                Point2::new(n.x * theta_d / r, n.y * theta_d / r)
            }
        }
    }

    /// The distorted point and the 2x2 Jacobian of [`Distortion::distort`] at `n`.
    #[inline]
    pub(crate) fn distort_with_jacobian(&self, n: &Point2<f64>) -> (Point2<f64>, Matrix2<f64>) {
        if let Some(c) = self.polynomial() {
            return polynomial_distort(&c, n);
        }
        let r = n.x.hypot(n.y);
        if r < 1e-8 {
            return (*n, Matrix2::identity());
        }
        // d = s(r) n with s = theta_d(atan r) / r: J = s I + (ds/dr / r) n n^T.
        let theta = r.atan();
        let (theta_d, dtheta_d) = self.fisheye_theta_d(theta);
        let s = theta_d / r;
        let ds = (dtheta_d / (1.0 + r * r) * r - theta_d) / (r * r);
        let v = Vector2::new(n.x, n.y);
        let j = Matrix2::identity() * s + v * v.transpose() * (ds / r);
        (Point2::new(n.x * s, n.y * s), j)
    }

    /// Fisheye `theta_d(theta)` and its derivative.
    #[inline]
    fn fisheye_theta_d(&self, theta: f64) -> (f64, f64) {
        let Distortion::Equidistant { k1, k2, k3, k4 } = *self else {
            return (theta, 1.0);
        };
        let t2 = theta * theta;
        let poly = 1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)));
        let dpoly = 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
        (theta * poly, dpoly)
    }

    /// Undistorts a normalised point (see the module docs).
    pub fn undistort(&self, d: &Point2<f64>) -> Result<Point2<f64>, PoseError> {
        if !(d.x.is_finite() && d.y.is_finite()) {
            return Err(PoseError::NonFinite {
                which: "image",
                index: 0,
            });
        }
        self.validate()?;
        match self.polynomial() {
            Some(c) => undistort_polynomial(&c, d),
            None => self.undistort_fisheye(d),
        }
    }

    fn undistort_fisheye(&self, d: &Point2<f64>) -> Result<Point2<f64>, PoseError> {
        let rd = d.x.hypot(d.y);
        if rd < 1e-8 {
            return Ok(*d);
        }
        let residual_at = |theta: f64| self.fisheye_theta_d(theta).0 - rd;
        let mut theta = rd.min(std::f64::consts::PI);
        let mut residual = f64::INFINITY;
        let mut converged = false;
        for _ in 0..UNDISTORT_MAX_ITERATIONS {
            let (f, df) = self.fisheye_theta_d(theta);
            let e = f - rd;
            residual = e.abs();
            let step = e / df;
            if residual <= UNDISTORT_TOLERANCE {
                // One polishing step, kept only if it lowers the residual.
                let next = theta - step;
                if next.is_finite() && residual_at(next).abs() < residual {
                    theta = next;
                }
                converged = true;
                break;
            }
            if !step.is_finite() {
                break;
            }
            theta -= step;
        }
        if !converged {
            // The loop may end exactly on a converged iterate.
            let last = residual_at(theta).abs();
            if last.is_nan() || last > UNDISTORT_TOLERANCE {
                return Err(PoseError::UndistortionNotConverged {
                    x: d.x,
                    y: d.y,
                    iterations: UNDISTORT_MAX_ITERATIONS,
                    residual: if last.is_finite() { last } else { residual },
                });
            }
        }
        if !(0.0..std::f64::consts::FRAC_PI_2).contains(&theta) {
            return Err(PoseError::BeyondPinholeView {
                x: d.x,
                y: d.y,
                angle: theta,
            });
        }
        let s = theta.tan() / rd;
        Ok(Point2::new(d.x * s, d.y * s))
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

    /// The radial profile without the tangential terms: for the polynomial models the
    /// distorted radius `r_d` and `d r_d / d r` at the undistorted radius `t = r`; for the
    /// fisheye model `theta_d` and `d theta_d / d theta` at the angle `t = theta`.
    fn radial_profile(&self, t: f64) -> (f64, f64) {
        match self.polynomial() {
            Some(c) => {
                let (radial, dradial) = radial_factor(&c, t * t);
                (t * radial, radial + 2.0 * t * t * dradial)
            }
            None => self.fisheye_theta_d(t),
        }
    }

    /// Whether the radial profile grows monotonically (so the model is invertible) from the
    /// axis out to a distorted normalised radius `corner` (an image's farthest corner):
    /// marches the profile in steps of `corner / 1000`, up to 100 times the corner radius
    /// (polynomial models) or an angle of pi (fisheye). Returns the undistorted radius
    /// (fisheye: the angle) at which the profile reaches the corner, to within a step.
    pub(crate) fn check_monotonic(&self, corner: f64) -> Result<f64, ProfileFault> {
        let step = corner / 1000.0;
        let limit = match self.model() {
            DistortionModel::Equidistant => std::f64::consts::PI,
            _ => 100.0 * corner,
        };
        let mut t = 0.0;
        while t <= limit {
            let (value, slope) = self.radial_profile(t);
            if value >= corner {
                return Ok(t);
            }
            if slope.is_nan() || slope <= 0.0 {
                return Err(ProfileFault::FoldsBack(t));
            }
            t += step;
        }
        Err(ProfileFault::NeverReaches)
    }
}

/// Coefficients 8 and beyond of an OpenCV vector (thin prism `s1..s4`, tilt `tauX, tauY`)
/// must be zero.
fn reject_extra_terms(c: &[f64]) -> Result<(), PoseError> {
    match c.iter().enumerate().skip(8).find(|(_, v)| **v != 0.0) {
        Some((index, value)) => Err(PoseError::UnsupportedDistortion {
            index,
            value: *value,
        }),
        None => Ok(()),
    }
}

/// `radial(r2)` of the polynomial models and `d radial / d r2`.
#[inline]
fn radial_factor(c: &[f64; 8], r2: f64) -> (f64, f64) {
    let [k1, k2, _, _, k3, k4, k5, k6] = *c;
    let num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    let dnum = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
    let den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6));
    let dden = k4 + r2 * (2.0 * k5 + 3.0 * r2 * k6);
    (num / den, (dnum * den - num * dden) / (den * den))
}

/// The distorted point of the polynomial models and its 2x2 Jacobian.
#[inline]
fn polynomial_distort(c: &[f64; 8], n: &Point2<f64>) -> (Point2<f64>, Matrix2<f64>) {
    let (p1, p2) = (c[2], c[3]);
    let (x, y) = (n.x, n.y);
    let r2 = x * x + y * y;
    let (radial, dradial) = radial_factor(c, r2);
    let d = Point2::new(
        x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
        y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
    );
    let off = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
    let j = Matrix2::new(
        radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x,
        off,
        off,
        radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x,
    );
    (d, j)
}

/// Newton on the 2x2 system of the polynomial models.
fn undistort_polynomial(c: &[f64; 8], d: &Point2<f64>) -> Result<Point2<f64>, PoseError> {
    let residual_at = |n: &Point2<f64>| {
        let (f, j) = polynomial_distort(c, n);
        (Vector2::new(f.x - d.x, f.y - d.y), j)
    };
    let mut n = *d;
    let mut residual = f64::INFINITY;
    for _ in 0..UNDISTORT_MAX_ITERATIONS {
        let (e, j) = residual_at(&n);
        residual = e.norm();
        if residual <= UNDISTORT_TOLERANCE {
            // One polishing step, kept only if it lowers the residual.
            if let Some(jinv) = j.try_inverse() {
                let next = n - jinv * e;
                if residual_at(&next).0.norm() < residual {
                    n = next;
                }
            }
            return Ok(n);
        }
        let Some(jinv) = j.try_inverse() else { break };
        n -= jinv * e;
        if !(n.x.is_finite() && n.y.is_finite()) {
            break;
        }
    }
    // One last check: the loop may end exactly on a converged iterate.
    let last = residual_at(&n).0.norm();
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
