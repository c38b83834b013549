//! Formation variables (spec 2.3) and the polar leader-follower model (spec 2.4).

use nalgebra::{SVector, Vector2, Vector3};

use crate::angle::wrap_angle;
use crate::error::{UnicycleError, check_dt, check_finite};
use crate::robot::{Inputs, PlanarPose};

/// Smallest separation `l12` (metres) the model accepts. Below it the bearings are undefined
/// and the polar equations divide by (almost) zero, so every entry point returns
/// [`UnicycleError::SeparationTooSmall`] instead.
pub const MIN_SEPARATION: f64 = 1e-6;

/// Polar state `[x1, y1, theta1, l12, alpha12, beta12]` (spec 2.4).
pub type PolarState = SVector<f64, 6>;

/// Measurement `h(x) = [l12, alpha12, beta12]`.
pub type FormationMeasurement = Vector3<f64>;

/// Indices of the state components that are angles (wrapped to `(-pi, pi]`).
pub const STATE_ANGLES: [usize; 3] = [2, 4, 5];

/// Indices of the measurement components that are angles.
pub const MEASUREMENT_ANGLES: [usize; 2] = [1, 2];

/// Formation variables between a leader (robot 1) and a follower's camera (robot 2). With
/// the `serde` feature it reads and writes as `{l12, alpha12, beta12}`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Formation {
    /// Distance from the follower's camera to the leader's reference point, metres.
    pub l12: f64,
    /// Bearing of the camera-to-leader line in the leader's frame (`zeta12 - theta1`), rad.
    pub alpha12: f64,
    /// Bearing of the camera-to-leader line in the follower's frame (`zeta12 - theta2`), rad.
    pub beta12: f64,
}

fn check_offset(d: f64) -> Result<(), UnicycleError> {
    if d.is_finite() && d >= 0.0 {
        Ok(())
    } else {
        Err(UnicycleError::InvalidOffset { d })
    }
}

fn check_separation(l12: f64) -> Result<(), UnicycleError> {
    if l12 > MIN_SEPARATION {
        Ok(())
    } else {
        Err(UnicycleError::SeparationTooSmall {
            l12,
            min: MIN_SEPARATION,
        })
    }
}

impl Formation {
    /// Formation variables from two world poses and the camera offset `d` (spec 2.3).
    /// Angles are wrapped to `(-pi, pi]`.
    ///
    /// # Errors
    /// Non-finite poses, a bad `d`, or a leader within [`MIN_SEPARATION`] of the camera.
    pub fn from_poses(
        leader: &PlanarPose,
        follower: &PlanarPose,
        d: f64,
    ) -> Result<Self, UnicycleError> {
        leader.check("leader pose")?;
        follower.check("follower pose")?;
        check_offset(d)?;
        let (xc, yc) = follower.point_ahead(d);
        let (dx, dy) = (leader.x - xc, leader.y - yc);
        let l12 = dx.hypot(dy);
        check_separation(l12)?;
        let zeta = dy.atan2(dx);
        Ok(Self {
            l12,
            alpha12: wrap_angle(zeta - leader.theta),
            beta12: wrap_angle(zeta - follower.theta),
        })
    }

    /// The inverse of [`Formation::from_poses`] for the leader: where the leader is, given
    /// the follower's pose, these formation variables and `d`. The heading is wrapped.
    ///
    /// # Errors
    /// Non-finite values, a bad `d`, or `l12 <= MIN_SEPARATION`.
    pub fn leader_pose(&self, follower: &PlanarPose, d: f64) -> Result<PlanarPose, UnicycleError> {
        self.check()?;
        follower.check("follower pose")?;
        check_offset(d)?;
        let (xc, yc) = follower.point_ahead(d);
        let zeta = follower.theta + self.beta12;
        Ok(PlanarPose {
            x: xc + self.l12 * zeta.cos(),
            y: yc + self.l12 * zeta.sin(),
            theta: wrap_angle(zeta - self.alpha12),
        })
    }

    /// The other inverse: where the follower is, given the leader's pose, these formation
    /// variables and `d`. The heading is wrapped.
    ///
    /// # Errors
    /// As [`Formation::leader_pose`].
    pub fn follower_pose(&self, leader: &PlanarPose, d: f64) -> Result<PlanarPose, UnicycleError> {
        self.check()?;
        leader.check("leader pose")?;
        check_offset(d)?;
        let zeta = leader.theta + self.alpha12;
        let theta2 = zeta - self.beta12;
        let xc = leader.x - self.l12 * zeta.cos();
        let yc = leader.y - self.l12 * zeta.sin();
        Ok(PlanarPose {
            x: xc - d * theta2.cos(),
            y: yc - d * theta2.sin(),
            theta: wrap_angle(theta2),
        })
    }

    /// As a measurement vector `[l12, alpha12, beta12]`.
    pub fn to_vector(&self) -> FormationMeasurement {
        Vector3::new(self.l12, self.alpha12, self.beta12)
    }

    /// From a measurement vector `[l12, alpha12, beta12]` (not validated; see the
    /// consumers, which validate).
    pub fn from_vector(y: &FormationMeasurement) -> Self {
        Self {
            l12: y[0],
            alpha12: y[1],
            beta12: y[2],
        }
    }

    fn check(&self) -> Result<(), UnicycleError> {
        check_finite("formation", &[self.l12, self.alpha12, self.beta12])?;
        check_separation(self.l12)
    }
}

/// The polar leader-follower model of spec 2.4 for a follower whose camera sits `d` metres
/// ahead of its reference point.
///
/// State `x = [x1, y1, theta1, l12, alpha12, beta12]`, follower inputs `u = [v2, w2]`
/// (known), leader inputs `w = [v1, w1]` (the parameters a dual filter estimates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolarModel {
    d: f64,
}

impl PolarModel {
    /// A model with camera offset `d` (metres, finite, `>= 0`).
    ///
    /// # Errors
    /// [`UnicycleError::InvalidOffset`] otherwise.
    pub fn new(d: f64) -> Result<Self, UnicycleError> {
        check_offset(d)?;
        Ok(Self { d })
    }

    /// The camera offset `d`, metres.
    pub fn d(&self) -> f64 {
        self.d
    }

    /// Continuous-time derivative `x'` (spec 2.4).
    ///
    /// # Errors
    /// Non-finite state or inputs; `l12 <= MIN_SEPARATION` (the model's only singularity).
    pub fn derivative(
        &self,
        x: &PolarState,
        u: &Vector2<f64>,
        w: &Vector2<f64>,
    ) -> Result<PolarState, UnicycleError> {
        check_finite("state", x.as_slice())?;
        check_finite("follower inputs", u.as_slice())?;
        check_finite("leader inputs", w.as_slice())?;
        self.derivative_unchecked(x, u, w)
    }

    /// The derivative after the finite-ness checks; still refuses a tiny `l12`.
    fn derivative_unchecked(
        &self,
        x: &PolarState,
        u: &Vector2<f64>,
        w: &Vector2<f64>,
    ) -> Result<PolarState, UnicycleError> {
        let (theta1, l, alpha, beta) = (x[2], x[3], x[4], x[5]);
        check_separation(l)?;
        let (v1, w1) = (w[0], w[1]);
        let (v2, w2) = (u[0], u[1]);
        let d = self.d;
        let (sa, ca) = alpha.sin_cos();
        let (sb, cb) = beta.sin_cos();
        let common = (-v1 * sa + v2 * sb) / l;
        Ok(PolarState::new(
            v1 * theta1.cos(),
            v1 * theta1.sin(),
            w1,
            v1 * ca - v2 * cb - d * w2 * sb,
            common - w1 - d * w2 * cb / l,
            common - w2 * (1.0 + d * cb / l),
        ))
    }

    /// Discrete model `f(x, u, w, dt)`: one classical RK4 step of the polar equations with
    /// inputs held over `dt`, then `theta1, alpha12, beta12` wrapped to `(-pi, pi]`.
    ///
    /// # Errors
    /// Non-finite state or inputs, a bad `dt`, or `l12 <= MIN_SEPARATION` at the start or at
    /// any RK4 stage (the step would otherwise cross the singularity and return garbage).
    pub fn f(
        &self,
        x: &PolarState,
        u: &Vector2<f64>,
        w: &Vector2<f64>,
        dt: f64,
    ) -> Result<PolarState, UnicycleError> {
        check_finite("state", x.as_slice())?;
        check_finite("follower inputs", u.as_slice())?;
        check_finite("leader inputs", w.as_slice())?;
        check_dt(dt)?;
        let k1 = self.derivative_unchecked(x, u, w)?;
        let k2 = self.derivative_unchecked(&(x + k1 * (0.5 * dt)), u, w)?;
        let k3 = self.derivative_unchecked(&(x + k2 * (0.5 * dt)), u, w)?;
        let k4 = self.derivative_unchecked(&(x + k3 * dt), u, w)?;
        let mut next = x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dt / 6.0);
        for i in STATE_ANGLES {
            next[i] = wrap_angle(next[i]);
        }
        check_finite("next state", next.as_slice())?;
        check_separation(next[3])?;
        Ok(next)
    }

    /// Measurement function `h(x) = [l12, alpha12, beta12]`.
    pub fn h(x: &PolarState) -> FormationMeasurement {
        Vector3::new(x[3], x[4], x[5])
    }

    /// The polar state for a leader and a follower given as world poses (spec 2.3).
    ///
    /// # Errors
    /// As [`Formation::from_poses`].
    pub fn state_from_poses(
        &self,
        leader: &PlanarPose,
        follower: &PlanarPose,
    ) -> Result<PolarState, UnicycleError> {
        let f = Formation::from_poses(leader, follower, self.d)?;
        Ok(PolarState::new(
            leader.x,
            leader.y,
            wrap_angle(leader.theta),
            f.l12,
            f.alpha12,
            f.beta12,
        ))
    }

    /// The leader's world pose held in a polar state.
    pub fn leader_pose(x: &PolarState) -> PlanarPose {
        PlanarPose::new(x[0], x[1], x[2])
    }

    /// The follower's world pose implied by a polar state.
    ///
    /// # Errors
    /// Non-finite state or `l12 <= MIN_SEPARATION`.
    pub fn follower_pose(&self, x: &PolarState) -> Result<PlanarPose, UnicycleError> {
        check_finite("state", x.as_slice())?;
        let f = Formation {
            l12: x[3],
            alpha12: x[4],
            beta12: x[5],
        };
        f.follower_pose(&Self::leader_pose(x), self.d)
    }
}

impl From<Inputs> for Vector2<f64> {
    fn from(u: Inputs) -> Self {
        Vector2::new(u.v, u.w)
    }
}

impl From<Vector2<f64>> for Inputs {
    fn from(u: Vector2<f64>) -> Self {
        Inputs::new(u[0], u[1])
    }
}
