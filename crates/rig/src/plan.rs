//! The run parameters every node of the graph takes, mapped onto the shared
//! [`GenerateOptions`] so the graph and `causal-arm generate` agree.

use causal_arm_datagen::{GenerateOptions, Shard};
use causal_arm_node::{ParamSpec, Params};
use causal_arm_protocol::graph::graph;
use causal_arm_protocol::{Experiment, Profile, RunPlan};

/// How many readers of `topic` the graph file declares, leaving out the recorder (the
/// node publishing its acknowledgements) when the run is not recorded: a node publishing
/// on a volatile topic waits for them, since a sample written before a reader matched
/// never reaches it (with DDS Security each match also waits for a key exchange).
pub fn expected_readers(topic: &str, with_recorder: bool) -> anyhow::Result<usize> {
    let ack = causal_arm_protocol::topics::RECORDER_ACK;
    Ok(graph()?
        .subscribers_of(topic)
        .filter(|n| with_recorder || !n.publishes.iter().any(|t| t == ack))
        .count())
}

/// The ROS parameter declarations of `node`: the run's parameters and the node's own, as
/// `launch_scripts/graph.toml` declares them.
pub fn node_param_specs(node: &str) -> anyhow::Result<Vec<ParamSpec>> {
    let graph = graph()?;
    let decl = graph
        .node(node)
        .ok_or_else(|| anyhow::anyhow!("the graph file declares no node {node}"))?;
    Ok(graph
        .run_params
        .iter()
        .chain(&decl.params)
        .map(ParamSpec::from)
        .collect())
}

/// Validated run parameters.
#[derive(Debug, Clone)]
pub struct RunParams {
    /// The options `generate` would use.
    pub options: GenerateOptions,
}

impl RunParams {
    /// From resolved parameters; `out` is only used by the recorder.
    pub fn from_params(params: &Params, out: &str) -> anyhow::Result<Self> {
        let experiment: Experiment = params
            .string("experiment")
            .parse()
            .map_err(anyhow::Error::msg)?;
        let profile: Profile = params
            .string("profile")
            .parse()
            .map_err(anyhow::Error::msg)?;
        let mut plan = RunPlan::for_profile(experiment, profile);
        let steps = params.integer("steps");
        let episodes = params.integer("episodes");
        if steps > 0 {
            plan.steps_per_episode = steps as u64;
        }
        if episodes > 0 {
            plan.episodes = episodes as u64;
        }
        let mut options =
            GenerateOptions::new(experiment, plan, params.integer("seed") as u64, out);
        options.exp1.sigma = params.double("sigma");
        options.sim.velocity_scale = params.double("velocity_scale");
        options.sim.arm = params.string("arm").parse().map_err(anyhow::Error::msg)?;
        options.exp2.move_while_switching = params.bool("move_while_switching");
        options.start_step = params.integer("start_step") as u64;
        let (index, count) = (params.integer("shard_index"), params.integer("shard_count"));
        if count > 1 {
            if index >= count {
                anyhow::bail!("shard_index {index} is not a shard of a set of {count}");
            }
            options.shard = Some(Shard {
                index: index as u64,
                count: count as u64,
                set_seed: params.integer("shard_set_seed") as u64,
            });
        }
        if options.start_step >= options.plan.total_steps() {
            anyhow::bail!(
                "start_step {} is not a step of the run (it has {} steps)",
                options.start_step,
                options.plan.total_steps()
            );
        }
        Ok(Self { options })
    }

    /// The run's parameters as `-p name:=value` arguments that make every node run
    /// `options` (the inverse of [`RunParams::from_params`]).
    pub fn ros_params(options: &GenerateOptions) -> Vec<String> {
        vec![
            format!("experiment:={}", options.experiment),
            format!("seed:={}", options.seed),
            format!("sigma:={:?}", options.exp1.sigma),
            format!("velocity_scale:={:?}", options.sim.velocity_scale),
            format!("arm:={}", options.sim.arm),
            format!(
                "move_while_switching:={}",
                options.exp2.move_while_switching
            ),
            format!("steps:={}", options.plan.steps_per_episode),
            format!("episodes:={}", options.plan.episodes),
            format!("start_step:={}", options.start_step),
            format!("shard_index:={}", options.shard.map_or(0, |s| s.index)),
            format!("shard_count:={}", options.shard.map_or(1, |s| s.count)),
            format!(
                "shard_set_seed:={}",
                options.shard.map_or(0, |s| s.set_seed)
            ),
        ]
    }

    /// Sim-time duration of one step, ns (to turn stamps into step counts).
    pub fn step_ns(&self) -> f64 {
        self.options.sim.dt * self.options.sim.substeps as f64 * 1e9
    }
}
