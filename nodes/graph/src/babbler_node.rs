//! `causal_arm_babbler`: answers every simulator state with a babbling action.

use std::rc::Rc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::bail;
use causal_arm_datagen::{Babbler, fast_forward, validate};
use causal_arm_kinematics::ArmModel;
use causal_arm_msgs::msg::Action;
use causal_arm_node::{RosArgs, RosNode, qos};
use causal_arm_protocol::{StepJoiner, action_message, state_from_messages, topics};

use crate::feed::{drain_or_wait, refusal_summary};
use crate::parts::{StateParts, state_feeds};
use crate::screen::Screen;
use crate::{RunParams, node_param_specs, stop_flag};

/// Runs the babbler node until it answered every step of the run or SIGINT/SIGTERM.
pub fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    let specs = node_param_specs("causal_arm_babbler")?;
    let mut node = RosNode::new("causal_arm_babbler", &specs, ros_args)?;
    let run = RunParams::from_params(node.params(), "")?;
    validate(&run.options)?;
    let timeout = Duration::from_secs_f64(node.params().double("timeout"));
    let stop = stop_flag();
    let recorded = qos::recorded();
    let screen = Rc::new(Screen::new(&mut node)?);
    let feeds = state_feeds::<StateParts>(&mut node, &screen, &recorded)?;
    let actions = node.publisher::<Action>(topics::ACTION, recorded)?;
    // Resuming at a later step: the babbler as it was then (re-run with its simulator).
    let start = run.options.start_step;
    let mut babbler = match start {
        0 => Babbler::new(&run.options, &ArmModel::embedded())?,
        _ => fast_forward(&run.options, start)?.1,
    };

    // The simulator and, when the run is recorded, the recorder: an action written before
    // the recorder's reader matched would never reach the bag.
    let with_recorder = node.params().bool("wait_for_recorder");
    let needed = crate::expected_readers(topics::ACTION, with_recorder)?.max(1);
    let settle = Duration::from_millis(500);
    if !node.wait_for_subscribers(&actions, needed, timeout, settle, &stop) {
        if stop.load(Ordering::SeqCst) {
            return Ok(());
        }
        bail!(
            "{needed} subscriber(s) of {} (the simulator{}) did not appear within {timeout:?}",
            topics::ACTION,
            if with_recorder {
                " and the recorder"
            } else {
                ""
            }
        );
    }

    let per_episode = run.options.plan.steps_per_episode;
    let total = run.options.plan.total_steps();
    let mut joiner = StepJoiner::<StateParts>::new();
    let mut answered = start;
    let mut last_activity = Instant::now();
    while answered < total && !stop.load(Ordering::SeqCst) {
        if drain_or_wait(&feeds, &mut joiner, Duration::from_millis(100)) {
            last_activity = Instant::now();
        } else if last_activity.elapsed() > timeout {
            bail!("no state from the simulator for {timeout:?} after {answered} of {total} steps");
        }
        // The simulator waits for each answer before the next state, so an incomplete
        // step older than a complete one is a stray: release it (lenient popping).
        while let Some((_, parts)) = joiner.pop_complete(false) {
            let k = answered % per_episode;
            let episode = (answered / per_episode) as u32;
            if k == 0 && answered > 0 {
                babbler.reset();
            }
            let state = state_from_messages(
                parts.joint_states.as_ref().expect("complete"),
                parts.ef_pose.as_ref().expect("complete"),
                parts.object_pose.as_ref().expect("complete"),
                parts.object_color.as_ref().expect("complete"),
                parts.magnet.as_ref().expect("complete"),
                answered,
                episode,
            )?;
            let command = babbler.next(&state);
            actions
                .publish(action_message(&state, &command, k))
                .map_err(|e| anyhow::anyhow!("publishing on {}: {e:?}", topics::ACTION))?;
            answered += 1;
        }
    }

    // Let reliable delivery of the last action complete.
    std::thread::sleep(Duration::from_millis(200));
    tracing::info!(
        "babbler answered {answered} of {total} steps; {}",
        refusal_summary(&feeds, &joiner)
    );
    Ok(())
}
