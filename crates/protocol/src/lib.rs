//! The vocabulary the project's crates share: what the graph's topics and frames are called
//! and how stamps are written.
//!
//! Libraries (dataset, trainer, explainer, truth) read bags and speak of experiments; they
//! need these names, not the simulator or the babbler that produce them. Keeping the names
//! here, with no DDS and no physics behind them, lets every crate agree on them without
//! building rapier3d or ros2-client.

pub mod topics;

pub use topics::{frames, ns_from_time, time_from_ns};
