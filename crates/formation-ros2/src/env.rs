//! Which DDS domain and which interfaces: `ROS_DOMAIN_ID` and
//! `ROS_AUTOMATIC_DISCOVERY_RANGE`, as a ROS 2 installation reads them.

use std::net::{IpAddr, Ipv4Addr};

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::dds::{Context, Node};
use ros2_client::{NodeName, NodeOptions};

use crate::Ros2Error;

/// Largest domain id whose ports are valid on every platform (ROS 2's documented range is
/// 0 to 232 on Linux).
pub const MAX_DOMAIN_ID: u16 = 232;

/// How far discovery reaches (`ROS_AUTOMATIC_DISCOVERY_RANGE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiscoveryRange {
    /// Every interface (ROS 2's `SUBNET`, the default; also `SYSTEM_DEFAULT`).
    Subnet,
    /// The loopback interface only: no packet leaves the machine (`LOCALHOST`, or the older
    /// `ROS_LOCALHOST_ONLY=1`).
    Localhost,
}

/// The DDS settings of a node, from the environment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RosEnv {
    /// `ROS_DOMAIN_ID`, 0 by default.
    pub domain_id: u16,
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE`, `SUBNET` by default.
    pub range: DiscoveryRange,
}

impl RosEnv {
    /// Reads the process environment.
    ///
    /// # Errors
    /// [`Ros2Error::Environment`] naming the variable and its value.
    pub fn from_env() -> Result<Self, Ros2Error> {
        Self::from_vars(|name| std::env::var(name).ok())
    }

    /// Reads the variables through `get` (a test can pass its own).
    ///
    /// # Errors
    /// A domain id that is not a whole number from 0 to [`MAX_DOMAIN_ID`], or a discovery
    /// range other than `SUBNET`, `SYSTEM_DEFAULT` and `LOCALHOST` (`OFF` would discover
    /// nothing, so it is refused rather than silently ignored).
    pub fn from_vars(get: impl Fn(&str) -> Option<String>) -> Result<Self, Ros2Error> {
        let bad =
            |variable: &'static str, value: &str, expected: &'static str| Ros2Error::Environment {
                variable,
                value: value.to_owned(),
                expected,
            };
        let domain_id = match get("ROS_DOMAIN_ID").filter(|v| !v.trim().is_empty()) {
            None => 0,
            Some(v) => v
                .trim()
                .parse::<u16>()
                .ok()
                .filter(|d| *d <= MAX_DOMAIN_ID)
                .ok_or_else(|| bad("ROS_DOMAIN_ID", &v, "a whole number from 0 to 232"))?,
        };
        let legacy_localhost = get("ROS_LOCALHOST_ONLY").is_some_and(|v| v.trim() == "1");
        let range = match get("ROS_AUTOMATIC_DISCOVERY_RANGE")
            .map(|v| v.trim().to_owned())
            .filter(|v| !v.is_empty())
        {
            None if legacy_localhost => DiscoveryRange::Localhost,
            None => DiscoveryRange::Subnet,
            Some(v) => match v.as_str() {
                "SUBNET" | "SYSTEM_DEFAULT" => DiscoveryRange::Subnet,
                "LOCALHOST" => DiscoveryRange::Localhost,
                _ => {
                    return Err(bad(
                        "ROS_AUTOMATIC_DISCOVERY_RANGE",
                        &v,
                        "SUBNET, SYSTEM_DEFAULT or LOCALHOST",
                    ));
                }
            },
        };
        Ok(Self { domain_id, range })
    }

    /// A DDS participant in this domain, on the loopback interface only with
    /// [`DiscoveryRange::Localhost`], and a ROS 2 node named `name` in `namespace` (`/` for
    /// none) in it.
    ///
    /// # Errors
    /// [`Ros2Error::Dds`] when the participant or the node cannot be made (e.g. no usable
    /// network interface, or a bad node name).
    pub fn node(&self, namespace: &str, name: &str) -> Result<Node, Ros2Error> {
        let dds = |what: &str, e: &dyn std::fmt::Display| Ros2Error::Dds(format!("{what}: {e}"));
        let mut builder = DomainParticipantBuilder::new(self.domain_id)
            // Camera frames arrive in bursts of fragments: a bigger receive buffer loses
            // fewer of them (the kernel caps it at net.core.rmem_max).
            .socket_receive_buffer_size(8 << 20);
        if self.range == DiscoveryRange::Localhost {
            builder = builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        }
        let participant = builder
            .build()
            .map_err(|e| dds("cannot join the DDS domain", &e))?;
        let context = Context::from_domain_participant(participant)
            .map_err(|e| dds("cannot start the ROS 2 context", &e))?;
        let name = NodeName::new(namespace, name)
            .map_err(|e| dds(&format!("node name {namespace:?} {name:?}"), &e))?;
        let mut node = context
            .new_node(name, NodeOptions::new().enable_rosout(false))
            .map_err(|e| dds("cannot create the node", &e))?;
        // The node's background task keeps its view of matched readers and writers (and the
        // ROS graph) current; it ends when the node is dropped.
        let spinner = node
            .spinner()
            .map_err(|e| dds("cannot start the node's background task", &e))?;
        std::thread::Builder::new()
            .name("ros2-spinner".into())
            .spawn(move || futures::executor::block_on(spinner.spin()))
            .map_err(|e| dds("cannot start the node's background thread", &e))?;
        Ok(node)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(vars: &[(&str, &str)]) -> Result<RosEnv, Ros2Error> {
        let vars: Vec<(String, String)> = vars
            .iter()
            .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
            .collect();
        RosEnv::from_vars(|name| vars.iter().find(|(k, _)| k == name).map(|(_, v)| v.clone()))
    }

    #[test]
    fn defaults_are_domain_0_on_every_interface() {
        let e = env(&[]).unwrap();
        assert_eq!(e.domain_id, 0);
        assert_eq!(e.range, DiscoveryRange::Subnet);
    }

    #[test]
    fn the_variables_are_read() {
        let e = env(&[
            ("ROS_DOMAIN_ID", "42"),
            ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST"),
        ])
        .unwrap();
        assert_eq!((e.domain_id, e.range), (42, DiscoveryRange::Localhost));
        let e = env(&[("ROS_LOCALHOST_ONLY", "1")]).unwrap();
        assert_eq!(e.range, DiscoveryRange::Localhost);
        // The newer variable wins over the older one.
        let e = env(&[
            ("ROS_LOCALHOST_ONLY", "1"),
            ("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET"),
        ])
        .unwrap();
        assert_eq!(e.range, DiscoveryRange::Subnet);
    }

    #[test]
    fn bad_values_name_the_variable_and_the_value() {
        for (var, value) in [
            ("ROS_DOMAIN_ID", "233"),
            ("ROS_DOMAIN_ID", "-1"),
            ("ROS_DOMAIN_ID", "seven"),
            ("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF"),
            ("ROS_AUTOMATIC_DISCOVERY_RANGE", "localhost"),
        ] {
            let err = env(&[(var, value)]).unwrap_err().to_string();
            assert!(err.contains(var) && err.contains(value), "{err}");
        }
    }
}
