//! The data-generation graph as ROS 2 nodes: `causal_arm_sim`, `causal_arm_babbler` and
//! `causal_arm_recorder`, each its own process or the three composed in one ([`compose`]),
//! and `causal_arm_reacher`, which stands in for the babbler when `causal-arm reach` drives
//! the arm to targets.
//!
//! Lock-step protocol (so nothing is lost and a seed reproduces `causal-arm generate`):
//! 1. the simulator publishes the state of step k on all state topics, one stamp;
//! 2. the babbler, having every state topic for that stamp, publishes `/babbler/action`
//!    with the same stamp; the simulator waits for it and executes it;
//! 3. the recorder buffers messages per stamp, writes a step once all its topics are in
//!    (in the same order as `generate`), and publishes the stamp of the last complete step
//!    on `/recorder/ack`; the simulator never runs more than `ack_window` steps ahead.
//!
//! All three take the same run parameters (`experiment`, `profile`, `steps`, `episodes`,
//! `seed`, `sigma`) with `--ros-args -p name:=value`.

pub mod answer;
pub mod babbler_node;
pub mod compose;
pub mod feed;
pub mod flow;
pub mod intra;
pub mod launch;
pub mod parts;
pub mod plan;
pub mod reacher_node;
pub mod recorder_node;
pub mod screen;
pub mod sim_node;

pub use plan::{RunSetup, expected_readers};

/// Acknowledgement topic of the recorder (`rosgraph_msgs/msg/Clock`: the stamp of the
/// last step it has written completely).
pub const ACK_TOPIC: &str = causal_arm_protocol::topics::RECORDER_ACK;

/// How long a node gives the readers it matched to match it on their side too (each
/// confirms with its first ACKNACK, which rustdds readers send at once), before it
/// publishes anyway.
pub const SETTLE: std::time::Duration = std::time::Duration::from_millis(500);

/// How long a node waits, before it exits, for its last samples to be acknowledged by
/// every reader: a round trip on one machine, so the bound is reached only when a reader
/// has left.
pub const FINAL_DELIVERY: std::time::Duration = std::time::Duration::from_millis(300);

/// Before a node exits: waits up to [`FINAL_DELIVERY`] until every reader has
/// acknowledged what `publisher` wrote (`what` names it in the log if not).
pub(crate) fn wait_for_final_delivery<M: serde::Serialize>(
    publisher: &ros2_client::Publisher<M>,
    what: &str,
) {
    if !publisher
        .wait_for_all_acked(FINAL_DELIVERY)
        .unwrap_or(false)
    {
        tracing::debug!("{what} was not acknowledged within {FINAL_DELIVERY:?}");
    }
}

pub use causal_arm_node::run::{node_main, stop_flag, take_next};
