//! ROS 2 for formation-tracker, in pure Rust (no ROS installation, no C): the message types
//! the node reads and writes, the DDS domain and interfaces from the environment, the
//! topics with their quality of service, and the conversions between messages and what the
//! pipeline takes and gives.
//!
//! # Design
//!
//! The transport is [`ros2_client`] on RustDDS, which speaks RTPS to any DDS of a ROS 2
//! system (Fast DDS, CycloneDDS). Messages are plain serde structs ([`msg`]) in the field
//! order of their `.msg` files, under their standard type names, so that `ros2 topic echo`
//! and Foxglove read them with nothing of ours installed.
//!
//! - [`env`](mod@env): `ROS_DOMAIN_ID` and `ROS_AUTOMATIC_DISCOVERY_RANGE` (`LOCALHOST` keeps every
//!   packet on the loopback interface), read as a ROS 2 installation reads them.
//! - [`topics`]: names resolved as ROS resolves them, and the two QoS profiles: sensor data
//!   (best effort, keep last) for what a camera driver publishes, reliable for estimates.
//! - [`convert`]: images, calibrations and odometry into the pipeline's types through the
//!   same functions as `track` on a recorded bag (a frame gives the same pixels live and
//!   recorded); the tracker's estimates into poses, twists, transforms and the formation
//!   message.
//!
//! The node itself (`formation-tracker ros2`) and the simulated robot pair
//! (`formation-tracker ros2-sim`) are commands of the command-line tool, which composes
//! this crate with the tracker; `docs/ros2.md` lists the topics, frames and layouts.
//!
//! ```
//! use formation_ros2::{RosEnv, msg};
//! // The environment of a node that must not leave the machine.
//! let env = RosEnv::from_vars(|name| match name {
//!     "ROS_DOMAIN_ID" => Some("7".into()),
//!     "ROS_AUTOMATIC_DISCOVERY_RANGE" => Some("LOCALHOST".into()),
//!     _ => None,
//! })
//! .unwrap();
//! assert_eq!(env.domain_id, 7);
//! assert_eq!(msg::Time::from_ns(1_500_000_000), msg::Time { sec: 1, nanosec: 500_000_000 });
//! ```
#![deny(missing_docs)]

pub mod convert;
pub mod env;
pub mod msg;
pub mod topics;

pub use env::{DiscoveryRange, RosEnv};

/// What can go wrong between the node and ROS 2.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// An environment variable has a value we cannot use.
    #[error("{variable}={value:?}: expected {expected}")]
    Environment {
        /// The variable.
        variable: &'static str,
        /// Its value.
        value: String,
        /// What it may be.
        expected: &'static str,
    },
    /// The DDS participant, node, topic, reader or writer could not be made, or a read or
    /// write failed.
    #[error("DDS: {0}")]
    Dds(String),
    /// A topic name that ROS 2 does not accept.
    #[error("topic name {name:?}: {reason}")]
    Name {
        /// The name as given.
        name: String,
        /// Why it is refused.
        reason: String,
    },
    /// A received message that cannot be used.
    #[error("{kind}: {reason}")]
    Message {
        /// The message type.
        kind: &'static str,
        /// What is wrong, naming the field and value.
        reason: String,
    },
    /// An estimate that cannot be published as a pose.
    #[error("estimate: {0}")]
    Estimate(String),
}
