//! Topic names and qualities of service.

use ros2_client::dds::rustdds::Topic;
use ros2_client::dds::{Node, Publisher, Subscription};
use ros2_client::qos::{Durability, History};
use ros2_client::{MessageTypeName, Name, QosProfile};
use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::Ros2Error;
use crate::msg::RosType;

/// What camera drivers publish and what the node subscribes with: best effort, volatile,
/// keep the last `depth` samples. A frame that arrives while one is being processed waits
/// in that bounded queue or is dropped; it never queues without bound.
pub fn sensor_data(depth: usize) -> QosProfile {
    QosProfile::subscription_default()
        .reliability_best_effort()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// What the node publishes its estimates with: reliable, volatile, keep the last `depth`
/// (ROS 2's default profile is depth 10). A best-effort subscriber still matches it.
pub fn reliable(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// The fully qualified name of topic `name` for a node in `namespace` (`/` for none):
/// absolute names stay, relative ones are put under the namespace. `~` and substitutions
/// are not supported.
///
/// # Errors
/// [`Ros2Error::Name`] for a name ROS 2 refuses (empty, a double slash, a character other
/// than letters, digits, `_` and `/`, a token starting with a digit).
pub fn resolve(namespace: &str, name: &str) -> Result<Name, Ros2Error> {
    let bad = |reason: String| Ros2Error::Name {
        name: name.to_owned(),
        reason,
    };
    if name.starts_with('~') || name.contains('{') {
        return Err(bad("`~` and `{}` substitutions are not supported".into()));
    }
    let full = if name.starts_with('/') {
        name.to_owned()
    } else {
        format!("{}/{name}", namespace.trim_end_matches('/'))
    };
    let full = if full.starts_with('/') {
        full
    } else {
        format!("/{full}")
    };
    Name::parse(&full).map_err(|e| bad(format!("{e:?}")))
}

/// The topic `name` (resolved in the node's namespace) of `M`'s type.
fn topic<M: RosType>(node: &mut Node, name: &str, qos: &QosProfile) -> Result<Topic, Ros2Error> {
    let full = resolve(node.namespace(), name)?;
    node.create_topic(&full, MessageTypeName::new(M::PACKAGE, M::NAME), qos)
        .map_err(|e| Ros2Error::Dds(format!("topic {name}: {e:?}")))
}

/// A publisher of `M` on `name` (resolved in the node's namespace).
///
/// # Errors
/// [`Ros2Error::Name`] or [`Ros2Error::Dds`].
pub fn publisher<M: RosType + Serialize>(
    node: &mut Node,
    name: &str,
    qos: &QosProfile,
) -> Result<Publisher<M>, Ros2Error> {
    let topic = topic::<M>(node, name, qos)?;
    node.create_publisher(&topic, Some(qos.clone()))
        .map_err(|e| Ros2Error::Dds(format!("publisher on {name}: {e:?}")))
}

/// A subscription to `M` on `name` (resolved in the node's namespace).
///
/// # Errors
/// [`Ros2Error::Name`] or [`Ros2Error::Dds`].
pub fn subscription<M: RosType + DeserializeOwned + 'static>(
    node: &mut Node,
    name: &str,
    qos: &QosProfile,
) -> Result<Subscription<M>, Ros2Error> {
    let topic = topic::<M>(node, name, qos)?;
    node.create_subscription(&topic, Some(qos.clone()))
        .map_err(|e| Ros2Error::Dds(format!("subscription to {name}: {e:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_resolve_as_ros_resolves_them() {
        let dds = |ns: &str, name: &str| {
            let node = ros2_client::NodeName::new("/", "n").unwrap();
            resolve(ns, name).unwrap().to_dds_name("rt", &node, "")
        };
        assert_eq!(dds("/", "image_raw"), "rt/image_raw");
        assert_eq!(dds("/robot2", "image_raw"), "rt/robot2/image_raw");
        assert_eq!(dds("/robot2", "/tf"), "rt/tf");
        assert_eq!(dds("/", "camera/image_raw"), "rt/camera/image_raw");
        for bad in ["", "a//b", "2cam", "~/x", "a b", "x/"] {
            assert!(resolve("/", bad).is_err(), "{bad}");
        }
    }
}
