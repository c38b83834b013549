//! `formation-tracker ros2` (the node) and `formation-tracker ros2-sim` (a robot pair, or a
//! recording, published as a camera driver and odometry would): ROS 2 in pure Rust
//! (docs/ros2.md).

pub mod node;
pub mod sim;

use formation_ros2::msg;
use ros2_client::dds::Subscription;

/// The follower-inputs topic's type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum InputsType {
    /// `nav_msgs/msg/Odometry` (its `twist.twist`).
    Odometry,
    /// `geometry_msgs/msg/TwistStamped`.
    TwistStamped,
    /// `geometry_msgs/msg/Twist` (no stamp: the latest received is used).
    Twist,
    /// No inputs topic: the follower is taken to stand still.
    None,
}

/// Takes every sample waiting on `sub`, in arrival order, as `wrap` makes it, with its
/// publisher sequence number; a sample that fails to decode is returned as its error text.
fn drain<M: serde::de::DeserializeOwned + 'static, T>(
    sub: &Subscription<M>,
    wrap: impl Fn(M) -> T,
    out: &mut Vec<Result<(T, i64), String>>,
) {
    // Bounded: the reader's history depth bounds what can be waiting, and this cap guards
    // against a publisher faster than the loop.
    for _ in 0..1024 {
        match sub.take() {
            Ok(Some((m, info))) => out.push(Ok((wrap(m), info.sequence_number()))),
            Ok(None) => break,
            Err(e) => out.push(Err(format!("{e:?}"))),
        }
    }
}

/// A header stamp in nanoseconds, or why it is unusable.
fn stamp_ns(h: &msg::Header, kind: &str) -> Result<u64, String> {
    h.stamp.to_ns().ok_or_else(|| {
        format!(
            "{kind}: header.stamp = {}.{:09}: not a time after the epoch",
            h.stamp.sec, h.stamp.nanosec
        )
    })
}
