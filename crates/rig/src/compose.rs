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
    /// How it ended, once joined: kept, so it is the same at every ask, as a process's
    /// exit status is.
    outcome: Option<Result<(), String>>,
}

impl ComposedNode {
    pub(crate) fn new(name: String, handle: JoinHandle<anyhow::Result<()>>) -> Self {
        Self {
            name,
            handle: Some(handle),
            outcome: None,
        }
    }

    /// The node's outcome once it has ended (`None` while it runs); a panic is an error.
    pub fn outcome(&mut self) -> Option<&Result<(), String>> {
        if self.handle.as_ref().is_some_and(JoinHandle::is_finished) {
            self.join();
        }
        self.outcome.as_ref()
    }

    /// Waits for the node to end and gives its outcome.
    pub fn join(&mut self) -> &Result<(), String> {
        if let Some(handle) = self.handle.take() {
            self.outcome = Some(match handle.join() {
                Ok(result) => result.map_err(|e| format!("{e:#}")),
                Err(_) => Err(format!("{} panicked", self.name)),
            });
        }
        self.outcome
            .get_or_insert_with(|| Err("never started".to_owned()))
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
        running.push(ComposedNode::new(name, handle));
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_that_ended_keeps_its_outcome_at_every_ask() {
        let ok = std::thread::spawn(|| Ok(()));
        let failed = std::thread::spawn(|| Err(anyhow!("no bag")));
        let mut nodes = [
            ComposedNode::new("ok".into(), ok),
            ComposedNode::new("failed".into(), failed),
        ];
        for node in &mut nodes {
            node.join();
        }
        for _ in 0..3 {
            assert_eq!(nodes[0].outcome(), Some(&Ok(())));
            assert_eq!(nodes[1].outcome(), Some(&Err("no bag".to_owned())));
        }
    }

    #[test]
    fn a_panic_is_an_error_naming_the_node() {
        let handle = std::thread::spawn(|| -> anyhow::Result<()> { panic!("boom") });
        let mut node = ComposedNode::new("sim".into(), handle);
        assert_eq!(node.join(), &Err("sim panicked".to_owned()));
    }
}
