//! What the node crate's DDS tests share: nodes on loopback in a test's own domain.
// Each test binary compiles this module and uses only part of it.
#![allow(dead_code)]

use causal_arm_node::{DiscoveryRange, RosArgs, RosEnv, RosNode};
use ros2_client::ServiceMapping;

/// The environment of an unsecured node on loopback in `domain`.
pub fn loopback_env(domain: u16) -> RosEnv {
    RosEnv {
        domain_id: domain,
        discovery_range: DiscoveryRange::Localhost,
        service_mapping: ServiceMapping::Enhanced,
        security: Default::default(),
    }
}

/// An unsecured node called `name` on loopback in `domain`.
pub fn loopback_node(domain: u16, name: &str) -> RosNode {
    RosNode::with_env(loopback_env(domain), name, &[], &RosArgs::default()).expect("node")
}
