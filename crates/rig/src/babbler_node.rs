//! `causal_arm_babbler`: answers every simulator state with a babbling action.

use causal_arm_datagen::{Babbler, fast_forward, validate};
use causal_arm_kinematics::ArmModel;
use causal_arm_node::RosArgs;
use causal_arm_node::RosNode;

use crate::answer::answer_states;
use crate::intra::IntraPort;
use crate::{RunSetup, stop_flag};
use causal_arm_node::params::{BabblerParams, RunParams};

/// Runs the babbler node until it answered every step of the run or SIGINT/SIGTERM.
pub fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    run_composed(ros_args, None)
}

/// As [`run`], composed with other nodes of the graph in this process (`port`).
pub fn run_composed(ros_args: &RosArgs, port: Option<IntraPort<'_>>) -> anyhow::Result<()> {
    let mut node = RosNode::new(BabblerParams::NODE, &BabblerParams::specs()?, ros_args)?;
    let run = RunSetup::from_params(&RunParams::from_params(node.params())?, "")?;
    let own = BabblerParams::from_params(node.params())?;
    validate(&run.options)?;
    let stop = stop_flag();
    // Resuming at a later step: the babbler as it was then (re-run with its simulator).
    let start = run.options.start_step;
    let mut babbler = match start {
        0 => Babbler::new(&run.options, &ArmModel::embedded())?,
        _ => fast_forward(&run.options, start)?.1,
    };
    answer_states(
        "babbler",
        (&mut node, port),
        &run,
        &(&own).into(),
        start,
        &stop,
        |state, place| {
            if place.in_episode == 0 && place.step > 0 {
                babbler.reset();
            }
            Ok(babbler.next_drawn(state))
        },
    )?;
    Ok(())
}
