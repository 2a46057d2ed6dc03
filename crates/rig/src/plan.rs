//! The run parameters every node of the graph takes, mapped onto the shared
//! [`GenerateOptions`] so the graph and `causal-arm generate` agree.

use causal_arm_datagen::GenerateOptions;
use causal_arm_node::params::RunParams;
use causal_arm_protocol::graph::graph;

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

/// The run a node of the graph takes part in: its run parameters made into the options
/// `generate` would use.
#[derive(Debug, Clone)]
pub struct RunSetup {
    /// The options `generate` would use.
    pub options: GenerateOptions,
}

impl RunSetup {
    /// From the run's parameters; `out` is only used by the recorder.
    pub fn from_params(run: &RunParams, out: &str) -> anyhow::Result<Self> {
        Ok(Self {
            options: GenerateOptions::from_run_params(run, out)?,
        })
    }

    /// Sim-time duration of one step, ns (to turn stamps into step counts).
    pub fn step_ns(&self) -> f64 {
        self.options.sim.dt * self.options.sim.substeps as f64 * 1e9
    }
}
