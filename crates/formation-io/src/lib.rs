//! Readers and writers for formation-tracker: everything that turns a user's files and
//! recordings into frames, calibrations and inputs, and tracking results into files that
//! other tools read. It holds no algorithm: frames go to `formation-tracker`'s pipeline,
//! and what comes out of it is written here as it is.
//!
//! - [`frames`]: frame sources (a folder of images, a y4m file, a y4m stream on stdin) read
//!   into one reused grey buffer; [`y4m`] the YUV4MPEG2 reader behind them.
//! - [`bag`]: ROS 2 bags (rosbag2 folders and MCAP files): images, camera calibration and
//!   follower inputs, streamed, with the CDR messages ([`bag::cdr`]) and pixel formats
//!   ([`bag::pixels`]).
//! - [`mcap_out`], [`foxglove`]: an MCAP writer, and tracking results as Foxglove channels.
//! - [`inputs`]: the follower's own inputs `(v2, w2)` and camera pan per frame, from a CSV.
//! - [`controller`]: the follower's own controller (gains and set-points) from a YAML/JSON file.
//! - [`rigfile`]: rig files (YAML/JSON) that override the reference rig, with errors that
//!   name the bad field; [`textfile`] the bounded text reader behind them and the scene and
//!   scenario files of `formation-sim`.
//! - [`limits`]: the run's memory budget (`--max-memory`) and the bounds every input meets.
//!
//! Every read is bounded (by [`limits`] or [`textfile::MAX_TEXT_BYTES`]); bad input is a
//! typed error naming the file, field and value, never a panic.
#![deny(missing_docs)]
#![deny(clippy::print_stderr)]

/// This crate's version (`CARGO_PKG_VERSION`), for tools that report what they were built from.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

pub mod bag;
pub mod controller;
pub mod foxglove;
pub mod frames;
pub mod inputs;
pub mod limits;
pub mod mcap_out;
pub mod rigfile;
pub mod textfile;
pub mod y4m;
