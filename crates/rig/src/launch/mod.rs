//! The launcher as a library: which nodes a run starts with which arguments
//! ([`LaunchPlan::from_graph`], from the graph file), started as processes
//! ([`LaunchPlan::spawn`]) or composed in this one ([`LaunchPlan::compose`]), and supervised
//! until the run-ending node (the recorder) exits ([`run`]). `causal-arm launch`,
//! `--shards` and `reach` are front ends over it.

pub mod supervise;

use std::path::Path;
use std::rc::Rc;
use std::sync::atomic::Ordering;

use anyhow::{Context as _, bail};
use causal_arm_datagen::GenerateOptions;
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_node::{RosArgs, RosNode, qos};
use causal_arm_protocol::graph::GraphSpec;
use causal_arm_protocol::ns_from_time;

use crate::ACK_TOPIC;
use crate::compose::ComposedNode;
use crate::screen::{Screen, Screened};
pub use supervise::{Process, STOP_TIMEOUT, Started, follow, stop_all, wait_all, wait_for_exit};

/// One node to start: its graph-file name (also its binary's) and its arguments.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeCommand {
    /// Node (and binary) name.
    pub name: String,
    /// Its command-line arguments (`--ros-args -p …`).
    pub args: Vec<String>,
}

/// The nodes of one run, in the graph file's start order ([`LaunchPlan::ends_run`] says
/// which of them ends it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LaunchPlan {
    /// The nodes to start.
    pub nodes: Vec<NodeCommand>,
}

impl LaunchPlan {
    /// Every node of `graph`, each given the run's parameters of `options` and its own
    /// (the recorder its output), joining with `enclave` if the launcher has one.
    pub fn from_graph(graph: &GraphSpec, options: &GenerateOptions, enclave: Option<&str>) -> Self {
        let run = options.run_params().to_ros_args();
        let (size, duration) = options.split.to_ros2_units();
        use causal_arm_node::params::recorder;
        let node_values = [
            (recorder::output::NAME, options.out.display().to_string()),
            (recorder::overwrite::NAME, options.overwrite.to_string()),
            (recorder::max_bag_size::NAME, size.to_string()),
            (recorder::max_bag_duration::NAME, duration.to_string()),
            (
                recorder::chunk_compression::NAME,
                options.compression.to_string(),
            ),
        ];
        let nodes = (graph.nodes.iter())
            .map(|node| {
                let own = node.params.iter().filter_map(|p| {
                    let value = node_values.iter().find(|(name, _)| *name == p.name)?;
                    Some(format!("{}:={}", p.name, value.1))
                });
                let mut args = vec!["--ros-args".to_owned()];
                for param in run.iter().cloned().chain(own) {
                    args.extend(["-p".to_owned(), param]);
                }
                if let Some(enclave) = enclave {
                    args.extend(["--enclave".to_owned(), enclave.to_owned()]);
                }
                NodeCommand {
                    name: node.name.clone(),
                    args,
                }
            })
            .collect();
        Self { nodes }
    }

    /// Puts the graph file's stand-in `name` (the reacher) in the place of the node it
    /// replaces (the babbler), with that node's arguments and `params` (`name:=value`).
    pub fn stand_in(
        &mut self,
        graph: &GraphSpec,
        name: &str,
        params: &[String],
    ) -> anyhow::Result<()> {
        let stand_in = (graph.stand_ins.iter())
            .find(|n| n.name == name)
            .with_context(|| format!("the graph file declares no {name} stand-in"))?;
        let replaced = stand_in.replaces.clone().unwrap_or_default();
        let node = (self.nodes.iter_mut())
            .find(|n| n.name == replaced)
            .with_context(|| {
                format!("{name} stands in for {replaced}, which is not among the nodes")
            })?;
        node.name = stand_in.name.clone();
        node.args
            .extend(params.iter().flat_map(|p| ["-p".to_owned(), p.clone()]));
        Ok(())
    }

    /// Where the graph file's run-ending node (the recorder) is among the nodes.
    pub fn ends_run(&self, graph: &GraphSpec) -> anyhow::Result<usize> {
        let ends_run = (graph.nodes.iter())
            .find(|n| n.ends_run)
            .ok_or_else(|| anyhow::anyhow!("the graph has no node that ends the run"))?;
        (self.nodes.iter())
            .position(|n| n.name == ends_run.name)
            .with_context(|| format!("{} is not among the nodes to start", ends_run.name))
    }

    /// Starts each node as a process of its binary in `bin_dir`, in order.
    pub fn spawn(&self, bin_dir: &Path) -> anyhow::Result<Vec<Process>> {
        (self.nodes.iter())
            .map(|node| Process::spawn(&node.name, &node_binary(bin_dir, &node.name)?, &node.args))
            .collect()
    }

    /// Starts the nodes composed in this process, on threads (see [`crate::compose`]).
    pub fn compose(&self) -> anyhow::Result<Vec<ComposedNode>> {
        let mut nodes = Vec::new();
        for node in &self.nodes {
            let argv: Vec<String> = std::iter::once(node.name.clone())
                .chain(node.args.iter().cloned())
                .collect();
            let (node_args, _) = RosArgs::split(&argv)?;
            nodes.push((node.name.clone(), node_args));
        }
        crate::compose::spawn(nodes)
    }
}

/// The binary of node `name` in `bin_dir`, or an error saying how to build it.
pub fn node_binary(bin_dir: &Path, name: &str) -> anyhow::Result<std::path::PathBuf> {
    let path = bin_dir.join(name);
    if !path.exists() {
        bail!(
            "{} not found; build the nodes with `cargo build --workspace --bins`",
            path.display()
        );
    }
    Ok(path)
}

impl Started for ComposedNode {
    fn name(&self) -> &str {
        &self.name
    }

    fn exited(&mut self) -> anyhow::Result<Option<Result<(), String>>> {
        Ok(self.outcome().cloned())
    }

    /// Composed nodes share the process's stop flag, as they share its signals.
    fn interrupt(&self) {
        causal_arm_node::runtime::stop_flag().store(true, Ordering::SeqCst);
    }

    /// A thread cannot be killed: it is asked to stop and joined.
    fn kill(&mut self) -> anyhow::Result<()> {
        self.interrupt();
        if let Err(e) = self.join().clone() {
            tracing::warn!("{}: {e}", self.name);
        }
        Ok(())
    }
}

/// Runs the started `nodes` until the one at `ends_run` exits, calling `progress(steps)`
/// with the steps the recorder has acknowledged, then stops the others: whatever ended
/// the run, no node outlives it. Fails naming the recorder when it failed.
pub fn run<N: Started>(
    options: &GenerateOptions,
    ros_args: &RosArgs,
    mut nodes: Vec<N>,
    ends_run: usize,
    progress: &mut dyn FnMut(u64),
) -> anyhow::Result<()> {
    let stop = causal_arm_node::runtime::stop_flag();
    let mut recorder = nodes.remove(ends_run);
    let outcome = follow_acks(
        options,
        ros_args,
        &mut recorder,
        &mut nodes,
        &stop,
        progress,
    );
    stop_all(&mut nodes, STOP_TIMEOUT)?;
    if let Err(failure) = outcome? {
        bail!("{} failed ({failure})", recorder.name());
    }
    Ok(())
}

/// [`follow`], with the progress read from the recorder's acknowledgements (only from its
/// writers: any participant may write on the topic).
fn follow_acks<N: Started>(
    options: &GenerateOptions,
    ros_args: &RosArgs,
    recorder: &mut N,
    others: &mut [N],
    stop: &std::sync::atomic::AtomicBool,
    progress: &mut dyn FnMut(u64),
) -> anyhow::Result<Result<(), String>> {
    let mut node = RosNode::new("causal_arm_launch", &[], ros_args)?;
    let screen = Rc::new(Screen::of_graph_file(&mut node)?);
    let mut acks =
        Screened::<Clock, u64>::new(&mut node, ACK_TOPIC, qos::default_reliable(), &screen)?;
    let step_ns = options.sim.dt * options.sim.substeps as f64 * 1e9;
    follow(recorder, others, stop, &mut || {
        let stamp = |ack: Clock| ns_from_time(&ack.clock);
        let unreadable = |e| tracing::debug!("ignoring an unreadable acknowledgement: {e}");
        for stamp in acks.take_admitted(stamp, unreadable).1 {
            progress((stamp as f64 / step_ns).round() as u64 + 1);
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_protocol::graph::graph;

    #[test]
    fn every_node_of_the_graph_gets_the_run_and_the_recorder_its_output() {
        let mut options = GenerateOptions::new(
            causal_arm_protocol::Experiment::Exp2,
            causal_arm_protocol::RunPlan {
                episodes: 3,
                steps_per_episode: 500,
            },
            7,
            "bags/x",
        );
        options.exp1.sigma = 0.2;
        let plan = LaunchPlan::from_graph(graph().unwrap(), &options, Some("/causal_arm"));
        let names: Vec<&str> = plan.nodes.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "causal_arm_recorder",
                "causal_arm_babbler",
                "causal_arm_sim"
            ]
        );
        assert_eq!(plan.ends_run(graph().unwrap()).unwrap(), 0);
        for node in &plan.nodes {
            let line = node.args.join(" ");
            for p in ["experiment:=exp2", "seed:=7", "sigma:=0.2", "episodes:=3"] {
                assert!(line.contains(p), "{}: {line}", node.name);
            }
            assert_eq!(
                line.contains("output:=bags/x"),
                node.name == "causal_arm_recorder",
                "{line}"
            );
            assert!(line.ends_with("--enclave /causal_arm"), "{line}");
        }
    }

    #[test]
    fn a_stand_in_takes_the_place_and_arguments_of_the_node_it_replaces() {
        let options = GenerateOptions::new(
            causal_arm_protocol::Experiment::Exp1,
            causal_arm_protocol::RunPlan {
                episodes: 1,
                steps_per_episode: 100,
            },
            3,
            "bags/y",
        );
        let mut plan = LaunchPlan::from_graph(graph().unwrap(), &options, None);
        let babbler = plan.nodes[1].args.clone();
        plan.stand_in(
            graph().unwrap(),
            "causal_arm_reacher",
            &["report:=r.json".into()],
        )
        .unwrap();
        assert_eq!(plan.nodes[1].name, "causal_arm_reacher");
        assert_eq!(plan.nodes[1].args[..babbler.len()], babbler[..]);
        assert!(
            plan.nodes[1]
                .args
                .ends_with(&["-p".into(), "report:=r.json".into()])
        );
        let err = plan
            .stand_in(graph().unwrap(), "causal_arm_ghost", &[])
            .unwrap_err();
        assert!(
            err.to_string().contains("no causal_arm_ghost stand-in"),
            "{err}"
        );
    }

    /// The regression of every composed run: a node that had ended before the recorder
    /// was seen as running again once its outcome had been read, and waited for 10 s.
    #[test]
    fn composed_nodes_that_ended_are_not_waited_for_again() {
        let mut nodes: Vec<ComposedNode> = (0..2)
            .map(|i| ComposedNode::new(format!("node {i}"), std::thread::spawn(|| Ok(()))))
            .collect();
        for node in &mut nodes {
            while node.exited().unwrap().is_none() {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
        let started = std::time::Instant::now();
        stop_all(&mut nodes, std::time::Duration::from_secs(10)).unwrap();
        assert!(
            started.elapsed() < std::time::Duration::from_secs(1),
            "waited {:?} for nodes that had ended",
            started.elapsed()
        );
        assert_eq!(nodes[0].exited().unwrap(), Some(Ok(())));
    }

    #[test]
    fn a_node_binary_that_is_not_built_is_an_error_saying_how() {
        let err = node_binary(Path::new("/nonexistent"), "causal_arm_sim").unwrap_err();
        assert!(
            err.to_string().contains("cargo build --workspace --bins"),
            "{err}"
        );
    }
}
