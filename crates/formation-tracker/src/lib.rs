//! Vision-based tracking of mobile robots in formation: rig model, measurement transform,
//! tracker and CLI.
//!
//! This crate is the thin composition layer over the library crates: `fiducial` finds and
//! reads markers, `pose` measures their 6-DOF pose, `unicycle` models the robots and
//! `dukf` filters. What belongs here is what ties them to *our* robots:
//!
//! - [`rig`]: the leader's octagon of five marker faces (spec 3.3), the 3D corners of each
//!   marker in the leader's body frame, and the mapping between `(robot, face)` and
//!   dictionary entries. It knows markers only through `fiducial`'s dictionary indices.
//! - [`mount`]: the camera mount on the follower and the measurement transform of spec 2.5,
//!   from a leader's pose in the camera frame to `(l12, alpha12, beta12)` and their
//!   covariance.
//! - [`rigfile`]: rig files (YAML/JSON) overriding the reference rig: faces, geometry and
//!   the dictionary entry of each `(robot, face)`, with errors that name the bad field.
//! - [`scene`]: scenes of leaders seen by a follower's camera, rendered by `synthcam` with
//!   the markers as exact cell-grid textures, and their ground truth.
//! - [`paper`]: the paper's configurations (Figs. 7-11) and seeded random scenes.
//! - [`robots`]: robot poses from the markers of a frame: grouped by robot, one joint pose
//!   per robot (`pose`), inconsistent faces rejected, optionally refined on the ground plane,
//!   turned into `(l12, alpha12, beta12)` with covariance.
//! - [`evaluate`]: scoring the whole pipeline on a synthetic scene (render, detect, robots)
//!   against its exact ground truth: faces read, wrong codes, pose errors; Markdown tables.
//! - [`annotate`]: annotated frames: markers read, labelled with robot and face, and each
//!   robot's estimated rig reprojected over the image (the paper's Figs. 10-11).
//! - [`filter`]: [`filter::FormationFilter`], the dual UKF (`dukf`) over the polar
//!   leader-follower model (`unicycle`), reused per tracked leader; and the dual-UKF
//!   reproduction run (paper Figs. 12-13) with its figures of merit.
//! - [`scenario`]: the reference scenario of that experiment: a Cartesian truth simulation
//!   and seeded noisy measurements.
//! - [`tracker`]: [`tracker::Tracker`], one [`filter::FormationFilter`] per leader robot
//!   over time: per-frame pose measurements in, formation variables and leader velocities
//!   out, with coasting, loss and re-acquisition, planar-ambiguity resolution and gating.
//! - [`frames`]: frame sources (a folder of images, a y4m file, a y4m stream on stdin) read
//!   into one reused grey buffer.
//! - [`inputs`]: the follower's own inputs `(v2, w2)` and camera pan per frame, from a CSV.
//! - [`pipeline`]: one camera frame through detection, robot poses and the tracker, with
//!   the time of each stage; the `track` command and the demo both use it.
//! - [`demo`]: the end-to-end demo: the reference scenario with the synthetic camera in the
//!   loop, an occlusion, open or closed loop, a chain of robots.
//! - [`plot`]: figures as SVG and PNG with plotters' pure-Rust backends and an embedded font.
//!
//! Library modules never print or exit. The `formation-tracker` binary's subcommands live
//! beside `main.rs` in `cmd/`; they are thin wrappers that parse arguments, call these
//! modules and write files.
#![deny(missing_docs)]

pub mod annotate;
pub mod demo;
pub mod evaluate;
pub mod filter;
pub mod frames;
pub mod inputs;
pub mod mount;
pub mod paper;
pub mod pipeline;
pub mod plot;
pub mod rig;
pub mod rigfile;
pub mod robots;
pub mod scenario;
pub mod scene;
mod textfile;
pub mod tracker;
