//! The input side of the `formation-tracker` command-line tool, as a library so that it can
//! be tested and reused: frame sources and the follower's inputs file.
//!
//! - [`frames`]: frame sources (a folder of images, a y4m file, a y4m stream on stdin) read
//!   into one reused grey buffer.
//! - [`bag`]: ROS 2 bags (rosbag2 MCAP): images, camera calibration and follower inputs,
//!   streamed.
//! - [`mcap_out`], [`foxglove`]: an MCAP writer, and tracking results as Foxglove channels.
//! - [`inputs`]: the follower's own inputs `(v2, w2)` and camera pan per frame, from a CSV.
//! - [`limits`]: the run's memory budget (`--max-memory`) and the bounds every input meets.
//!
//! The subcommands themselves live beside `main.rs` in `cmd/`, one module per subcommand:
//! each parses its arguments, calls the libraries (`formation-tracker`, `formation-sim`)
//! and writes files; `main.rs` reports an error as one line with a non-zero exit code.
#![deny(missing_docs)]
#![deny(clippy::print_stderr)]

pub mod bag;
pub mod foxglove;
pub mod frames;
pub mod inputs;
pub mod limits;
pub mod mcap_out;
pub mod y4m;
