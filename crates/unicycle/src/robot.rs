//! One unicycle robot (spec 2.2): pose, inputs, exact and RK4 integration.

use crate::angle::wrap_angle;
use crate::error::{UnicycleError, check_dt, check_finite};

/// Planar pose of a unicycle: position `(x, y)` in metres and heading `theta` in radians
/// (counter-clockwise from the world x axis).
///
/// With the `serde` feature it reads and writes as `{x, y, theta}` (unknown fields refused).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(deny_unknown_fields)
)]
pub struct PlanarPose {
    /// World x of the robot's reference point, metres.
    pub x: f64,
    /// World y of the robot's reference point, metres.
    pub y: f64,
    /// Heading, radians, counter-clockwise positive.
    pub theta: f64,
}

/// Inputs of a unicycle: forward speed `v` (m/s) and turn rate `w` (rad/s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Inputs {
    /// Forward (linear) speed, m/s.
    pub v: f64,
    /// Angular speed, rad/s, counter-clockwise positive.
    pub w: f64,
}

impl Inputs {
    /// Builds inputs from a linear and an angular speed.
    pub const fn new(v: f64, w: f64) -> Self {
        Self { v, w }
    }

    pub(crate) fn check(&self, what: &'static str) -> Result<(), UnicycleError> {
        check_finite(what, &[self.v, self.w])
    }
}

/// Below this `|w dt|` the sinc in [`PlanarPose::integrate_exact`] is evaluated by its Taylor
/// series, so a straight line (w = 0) and a very gentle arc share one formula.
const SINC_TAYLOR_BELOW: f64 = 1e-4;

/// `sin(x) / x`, accurate near 0.
fn sinc(x: f64) -> f64 {
    if x.abs() < SINC_TAYLOR_BELOW {
        // 1 - x^2/6 + x^4/120: the next term is below 1e-22 here.
        let x2 = x * x;
        1.0 - x2 / 6.0 + x2 * x2 / 120.0
    } else {
        x.sin() / x
    }
}

impl PlanarPose {
    /// Builds a pose; `theta` is kept as given (not wrapped).
    pub const fn new(x: f64, y: f64, theta: f64) -> Self {
        Self { x, y, theta }
    }

    /// `[x, y, theta]`.
    pub fn to_vector(&self) -> nalgebra::Vector3<f64> {
        nalgebra::Vector3::new(self.x, self.y, self.theta)
    }

    /// The pose of `[x, y, theta]`.
    pub fn from_vector(v: &nalgebra::Vector3<f64>) -> Self {
        Self {
            x: v.x,
            y: v.y,
            theta: v.z,
        }
    }

    /// True when all three are finite.
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.theta.is_finite()
    }

    /// The point `d` metres ahead of the reference point along the heading: where the
    /// follower's camera sits (spec 2.2, `x_2c`, `y_2c`).
    pub fn point_ahead(&self, d: f64) -> (f64, f64) {
        (self.x + d * self.theta.cos(), self.y + d * self.theta.sin())
    }

    pub(crate) fn check(&self, what: &'static str) -> Result<(), UnicycleError> {
        check_finite(what, &[self.x, self.y, self.theta])
    }

    /// Time derivative `(x', y', theta')` of the unicycle (spec 2.2).
    pub fn derivative(&self, u: Inputs) -> (f64, f64, f64) {
        (u.v * self.theta.cos(), u.v * self.theta.sin(), u.w)
    }

    /// Integrates the unicycle exactly over `dt` with inputs held constant.
    ///
    /// The closed form is an arc of radius `v / w`; it is written as
    /// `dx = v dt sinc(w dt / 2) cos(theta + w dt / 2)` (same for `dy` with `sin`), which
    /// becomes the straight line `v dt (cos theta, sin theta)` as `w -> 0` without dividing
    /// by a tiny `w`. The returned heading is wrapped to `(-pi, pi]`.
    ///
    /// # Errors
    /// [`UnicycleError::NonFinite`] for a non-finite pose or input,
    /// [`UnicycleError::InvalidTimeStep`] for `dt` not finite and positive.
    pub fn integrate_exact(&self, u: Inputs, dt: f64) -> Result<PlanarPose, UnicycleError> {
        self.check("pose")?;
        u.check("inputs")?;
        check_dt(dt)?;
        let half = 0.5 * u.w * dt;
        let chord = u.v * dt * sinc(half);
        let mid = self.theta + half;
        Ok(PlanarPose {
            x: self.x + chord * mid.cos(),
            y: self.y + chord * mid.sin(),
            theta: wrap_angle(self.theta + u.w * dt),
        })
    }

    /// Integrates the unicycle over `dt` with one classical Runge-Kutta (RK4) step, inputs
    /// held constant. Agrees with [`PlanarPose::integrate_exact`] to `O(dt^5)`; it exists so the
    /// Cartesian and polar models can be integrated by the same scheme when that matters.
    ///
    /// # Errors
    /// As [`PlanarPose::integrate_exact`].
    pub fn integrate_rk4(&self, u: Inputs, dt: f64) -> Result<PlanarPose, UnicycleError> {
        self.check("pose")?;
        u.check("inputs")?;
        check_dt(dt)?;
        let at = |p: &PlanarPose, k: (f64, f64, f64), s: f64| PlanarPose {
            x: p.x + s * k.0,
            y: p.y + s * k.1,
            theta: p.theta + s * k.2,
        };
        let k1 = self.derivative(u);
        let k2 = at(self, k1, 0.5 * dt).derivative(u);
        let k3 = at(self, k2, 0.5 * dt).derivative(u);
        let k4 = at(self, k3, dt).derivative(u);
        let s = dt / 6.0;
        Ok(PlanarPose {
            x: self.x + s * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0),
            y: self.y + s * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1),
            theta: wrap_angle(self.theta + u.w * dt),
        })
    }
}
