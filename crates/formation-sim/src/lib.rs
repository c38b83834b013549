//! Simulation, evaluation and reproduction for `formation-tracker`: everything that needs
//! ground truth, a synthetic camera or a plot, kept out of the library a robot links.
//!
//! - [`scene`]: scenes of leaders seen by a follower's camera, rendered by `synthcam` with
//!   the markers as exact cell-grid textures, and their ground truth; scene files.
//! - [`paper`]: the paper's configurations (Figs. 7-11) and seeded random scenes.
//! - [`evaluate`]: scoring the whole pipeline on a synthetic scene (render, detect, robots)
//!   against its exact ground truth: faces read, wrong codes, pose errors; Markdown tables.
//! - [`annotate`]: annotated frames: markers read, labelled with robot and face, and each
//!   robot's estimated rig reprojected over the image (the paper's Figs. 10-11).
//! - [`scenario`]: the reference scenario of the dual-UKF experiment: a Cartesian truth
//!   simulation and seeded noisy measurements.
//! - [`reproduce`]: the dual-UKF reproduction (paper Figs. 12-13) with its figures of merit.
//! - [`demo`]: the end-to-end demo: the reference scenario with the synthetic camera in the
//!   loop, an occlusion, open or closed loop, a chain of robots.
//! - [`plot`]: figures as SVG and PNG with plotters' pure-Rust backends and an embedded font.
//!
//! Library modules never print or exit; the `formation-tracker` binary
//! (`formation-tracker-cli`) writes what they return.
#![deny(missing_docs)]

/// This crate's version (`CARGO_PKG_VERSION`), for tools that report what they were built from.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

pub mod annotate;
pub mod demo;
pub mod evaluate;
pub mod pair;
pub mod paper;
pub mod plot;
pub mod reproduce;
pub mod scenario;
pub mod scenario_file;
pub mod scene;
