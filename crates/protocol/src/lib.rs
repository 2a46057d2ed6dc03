//! The vocabulary the project's crates share: what the graph's topics and frames are called
//! and how stamps are written, what the simulator and the babbler exchange each step and
//! how that becomes ROS messages; which experiments there are, what a bag records about its
//! run and how a run's seed is split; where the table and the cube are.
//!
//! The graph itself (nodes, parameters, topics) is data too: [`graph`] reads
//! `launch_scripts/graph.toml`, which every front end shares.
//!
//! Libraries (dataset, trainer, explainer, truth) read bags and speak of experiments; they
//! need these names and shapes, not the simulator or the babbler that produce them. Keeping
//! them here, with no DDS and no physics behind them, lets every crate agree on them without
//! building rapier3d or ros2-client.

pub mod checks;
pub mod choice;
pub mod design;
pub mod experiment;
pub mod graph;
pub mod identity;
pub mod join;
pub mod markers;
pub mod messages;
pub mod scene;
pub mod step;
pub mod topics;

pub use checks::{WellFormed, command_of};
pub use choice::{Choice, one_of, parse_choice};
pub use design::{Design, Draw, Drawn, ToolRegion, design_of};
pub use experiment::{Experiment, Profile, RunPlan, babbler_seed, bag_keys, shard_seed, sim_seed};
pub use graph::{GraphSpec, NodeDecl, ParamDecl, ParamDefault, graph};
pub use identity::{Gid, Origin, Quarantine, QuarantineCounts, Trusted, WriterDirectory};
pub use join::{JoinCounts, Refusal, StepJoiner, StepParts, fill};
pub use markers::{markers_key, scene_markers};
pub use messages::{
    FrameTransform, LatchedMessages, StateFromMessagesError, StepMessages, action_message,
    state_from_messages, static_tf_message, step_messages,
};
pub use scene::Scene;
pub use step::{ARM_DOF, Command, SimState};
pub use topics::{frames, ns_from_time, time_from_ns};
