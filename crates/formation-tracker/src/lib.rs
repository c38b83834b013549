//! Vision-based tracking of mobile robots in formation: the thin composition a follower
//! robot links against.
//!
//! This crate ties the library crates to *our* robots and nothing else: `fiducial` finds
//! and reads markers, `pose` measures their 6-DOF pose, `unicycle` models the robots and
//! `dukf` filters. It renders nothing, plots nothing, parses no command line and reads no
//! video: scenes, reproductions and the demo are in `formation-sim`, the command-line tool
//! in `formation-tracker-cli`.
//!
//! - [`rig`]: the leader's marker rig: the reference octagon of five marker faces
//!   (spec 3.3), the 3D corners of each marker in the leader's body frame, and the mapping
//!   between `(robot, face)` and dictionary entries ([`rig::RigModel`]); rig files
//!   (YAML/JSON) are read by `formation-io`.
//! - [`mount`]: the camera mount on the follower and the measurement transform of spec 2.5,
//!   from a leader's pose in the camera frame to `(l12, alpha12, beta12)` and their
//!   covariance.
//! - [`robots`]: robot poses from the markers of a frame: grouped by robot, one joint pose
//!   per robot (`pose`), inconsistent faces rejected, optionally refined on the ground plane,
//!   turned into `(l12, alpha12, beta12)` with covariance.
//! - [`filter`]: the crate `formation-filter` re-exported: [`filter::FormationFilter`], the
//!   IMM or the paper's dual UKF (`dukf`) over the polar leader-follower model (`unicycle`),
//!   one per tracked leader, with its [`filter::FilterTuning`] and offline smoother.
//! - [`tracker`]: [`tracker::Tracker`], one [`filter::FormationFilter`] per leader robot
//!   over time: per-frame pose measurements in, formation variables and leader velocities
//!   out, with coasting, loss and re-acquisition, planar-ambiguity resolution and gating.
//! - [`guided`]: tracking-guided detection: each leader's predicted image region
//!   (its rig reprojected at the predicted pose, with a margin from the prediction's
//!   covariance), and when to scan the full frame ([`guided::GuidedConfig`]).
//! - [`pipeline`]: one camera frame (a grey image) through detection, robot poses and the
//!   tracker, with the time of each stage.
//!
//! Library modules never print, exit or unwrap on user data; every failure is a typed error.
#![deny(missing_docs)]

/// This crate's version (`CARGO_PKG_VERSION`), for tools that report what they were built from.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// The formation filter, one per tracked leader: the crate `formation-filter`, re-exported
/// under the name the tracker's API uses.
pub use formation_filter as filter;
pub mod guided;
pub mod mount;
pub mod pipeline;
pub mod rig;
pub mod robots;
pub mod tracker;
