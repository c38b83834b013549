//! Unicycle robots and the polar leader-follower formation model with a camera offset.
//!
//! This crate is the robot model of the project (spec sections 2.2-2.5) and nothing else: it
//! knows about poses, wheel inputs and formation geometry, but nothing about cameras' pixels,
//! markers or filters. Three layers, and the camera's place on the follower:
//!
//! - [`PlanarPose`] and [`Inputs`]: one unicycle `x' = v cos(theta), y' = v sin(theta),
//!   theta' = w`, integrated either in closed form ([`PlanarPose::integrate_exact`], an arc written
//!   with a `sinc` so that a straight line is the same formula's limit and nothing divides by
//!   a tiny `w`) or by RK4 ([`PlanarPose::integrate_rk4`]). Truth simulations use the exact form.
//! - [`Formation`]: the formation variables `(l12, alpha12, beta12)` between a leader and a
//!   follower whose camera is `d` metres ahead of its axle (spec 2.3), and both inverses
//!   (leader pose from follower pose and formation, and vice versa).
//! - [`PolarModel`]: the state `[x1, y1, theta1, l12, alpha12, beta12]` with leader inputs
//!   `w = [v1, w1]` as unknown parameters and follower inputs `u = [v2, w2]` as known inputs
//!   (spec 2.4); its discrete map [`PolarModel::f`] (RK4, angles wrapped after the step) and
//!   measurement [`PolarModel::h`] are exactly what a dual unscented Kalman filter needs.
//!   nalgebra's static vectors keep the dimensions in the types and keep the step free of
//!   allocation.
//!
//! - [`predict_leader`]: the leader's motion as a follower hypothesises it from its own
//!   inputs ([`LeaderMotion`]: accelerating, holding the formation, holding the bearing), and
//!   the leader velocities behind the last two ([`formation_holding_velocity`],
//!   [`bearing_holding_turn_rate`], [`controlled_formation_velocity`]): the model set a
//!   multiple-model filter mixes.
//!
//! - [`camera`]: where the camera sits on the follower ([`camera::CameraMount`]) and the
//!   measurement transform of spec 2.5 from a leader's pose in the camera frame to its
//!   formation variables ([`camera::formation_from_camera_pose`]).
//!
//! [`SeparationBearingController`] closes the loop for simulations: Das et al.'s `l-psi`
//! controller (IEEE T-RA 2002) holding a separation and a bearing in the leader's frame.
//!
//! # Why errors and not NaN
//! The polar model divides by `l12`. Rather than let a bad sigma point or a collision produce
//! NaN that silently poisons a filter, every entry point validates its input and returns a
//! [`UnicycleError`]: `l12 <= MIN_SEPARATION` (also checked at every RK4 stage), non-finite
//! numbers, a non-positive `dt` or a negative offset. Angles are wrapped to `(-pi, pi]` on
//! output, never required to be wrapped on input.
//!
//! # Example
//! ```
//! use nalgebra::Vector2;
//! use unicycle::{PolarModel, PlanarPose};
//!
//! let model = PolarModel::new(0.5)?;
//! let leader = PlanarPose::new(1.5, 0.25, 0.0);
//! let follower = PlanarPose::new(0.0, 0.0, 0.0);
//! let x = model.state_from_poses(&leader, &follower)?;
//! let next = model.f(&x, &Vector2::new(0.8, 0.0), &Vector2::new(0.8, 0.0), 1.0 / 30.0)?;
//! // Both robots drive straight at the same speed: the formation does not change.
//! assert!((PolarModel::h(&next) - PolarModel::h(&x)).norm() < 1e-12);
//! # Ok::<(), unicycle::UnicycleError>(())
//! ```
#![deny(missing_docs)]

/// This crate's version (`CARGO_PKG_VERSION`), for tools that report what they were built from.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

mod actuation;
mod angle;
pub mod camera;
mod controller;
mod error;
mod leader;
mod polar;
mod robot;

pub use actuation::Actuation;
pub use angle::wrap_angle;
pub use controller::{ControllerConfig, SeparationBearingController};
pub use error::UnicycleError;
pub use leader::{
    LeaderJump, LeaderMotion, LeaderMotionTuning, LeaderNoise, LeaderState,
    MIN_PREDICTED_SEPARATION, bearing_holding_turn_rate, controlled_formation_velocity,
    formation_holding_velocity, predict_leader,
};
pub use polar::{
    Formation, FormationMeasurement, MEASUREMENT_ANGLES, MIN_SEPARATION, PolarModel, PolarState,
    STATE_ANGLES,
};
pub use robot::{Inputs, PlanarPose};
