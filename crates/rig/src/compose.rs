//! Nodes of the graph composed into one process, as an rclcpp component container runs
//! its components: each node keeps its own name, parameters, participant and topics on
//! DDS, and runs on its own thread; what one of them publishes for another is handed over
//! in process ([`crate::intra`]) instead of crossing DDS, which saves the lock-step's
//! thread hand-offs and datagrams on every step. The nodes share a process, so they also
//! share its fate: a node that fails or panics stops the others (the recorder then
//! finalizes its bag with the complete steps, as on Ctrl-C).

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;

use anyhow::{anyhow, bail};
use causal_arm_node::RosArgs;
use causal_arm_protocol::graph::graph;

use crate::intra::{IntraBus, IntraPort};
use crate::{babbler_node, recorder_node, sim_node, stop_flag};

/// A node of the graph that can run composed: its name and its entry point.
type Entry = fn(&RosArgs, Option<IntraPort<'_>>) -> anyhow::Result<()>;

/// The graph's nodes that can be composed.
const COMPOSABLE: [(&str, Entry); 3] = [
    ("causal_arm_sim", sim_node::run_composed),
    ("causal_arm_babbler", babbler_node::run_composed),
    ("causal_arm_recorder", recorder_node::run_composed),
];

/// One composed node, running on its own thread.
pub struct ComposedNode {
    /// The graph file's name of the node.
    pub name: String,
    handle: Option<JoinHandle<anyhow::Result<()>>>,
}

impl ComposedNode {
    /// The node's result once it has ended (`None` while it runs); a panic is an error.
    pub fn try_finish(&mut self) -> Option<anyhow::Result<()>> {
        if !self.handle.as_ref()?.is_finished() {
            return None;
        }
        self.finish()
    }

    /// Waits for the node to end and gives its result (`None` if already given).
    pub fn finish(&mut self) -> Option<anyhow::Result<()>> {
        let handle = self.handle.take()?;
        Some(
            handle
                .join()
                .unwrap_or_else(|_| Err(anyhow!("{} panicked", self.name))),
        )
    }
}

/// Starts each of `nodes` (the graph file's node name and its ROS arguments) on its own
/// thread, linked in process to the others. A node that fails or panics sets the stop
/// flag, so the others wind down as on SIGINT.
pub fn spawn(nodes: Vec<(String, RosArgs)>) -> anyhow::Result<Vec<ComposedNode>> {
    let names: Vec<&str> = nodes.iter().map(|(name, _)| name.as_str()).collect();
    let mut entries = Vec::new();
    for name in &names {
        match COMPOSABLE.iter().find(|(n, _)| n == name) {
            Some((_, entry)) => entries.push(*entry),
            None => bail!(
                "{name} cannot run composed; the composable nodes are {}",
                COMPOSABLE.map(|(n, _)| n).join(", ")
            ),
        }
    }
    let bus = Arc::new(IntraBus::for_nodes(graph()?, &names)?);
    let mut running = Vec::new();
    for ((name, args), entry) in nodes.into_iter().zip(entries) {
        let bus = Arc::clone(&bus);
        let thread_name = name.clone();
        let handle = std::thread::Builder::new()
            .name(name.clone())
            .spawn(move || run_node(&bus, &thread_name, &args, entry))?;
        running.push(ComposedNode {
            name,
            handle: Some(handle),
        });
    }
    Ok(running)
}

/// Runs one node; its failure (an error or a panic) stops the whole container.
fn run_node(bus: &IntraBus, name: &str, args: &RosArgs, entry: Entry) -> anyhow::Result<()> {
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        entry(args, Some(bus.port(name)))
    }))
    .unwrap_or_else(|_| Err(anyhow!("{name} panicked")));
    if outcome.is_err() {
        stop_flag().store(true, Ordering::SeqCst);
    }
    outcome
}
