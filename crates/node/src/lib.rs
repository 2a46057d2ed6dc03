//! Node plumbing shared by every causal-arm node.
//!
//! Every node needs the same handful of things done the way ROS 2 users expect:
//! a DDS context that honours `ROS_DOMAIN_ID`, `ROS_AUTOMATIC_DISCOVERY_RANGE` and
//! `ROS_LOCALHOST_ONLY` ([`env`]), named QoS profiles ([`qos`]), typed parameters from
//! `--ros-args -p name:=value` ([`params`]), logging through `tracing` that also reaches
//! `/rosout` ([`logging`]), sim time, and one tokio runtime for signals, timers and
//! ros2-client's spinner ([`runtime`]). [`RosNode`] bundles them so node crates stay thin.

pub mod env;
pub mod logging;
pub mod node;
pub mod params;
pub mod qos;
pub mod replies;
pub mod run;
pub mod runtime;

pub use env::{DiscoveryRange, EnvError, RosEnv};
pub use node::{NodeError, RosNode};
pub use params::{ParamError, ParamKind, ParamSpec, ParamValue, Params, RosArgs};
