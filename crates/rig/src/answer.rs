//! The loop of a node that answers the simulator: join each step's state topics, turn
//! them into a [`SimState`], and publish one action per state on `/babbler/action`. The
//! babbler and the reacher differ only in how they choose the command.

use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::bail;
use causal_arm_msgs::msg::Action;
use causal_arm_node::{RosNode, qos};
use causal_arm_protocol::{
    Drawn, SimState, StepJoiner, action_message, state_from_messages, topics,
};

use crate::RunSetup;
use crate::feed::{drain_or_wait, refusal_summary};
use crate::intra::{IntraPort, Outlet};
use crate::parts::{FeedSource, StateParts, state_feeds};
use crate::screen::Screen;
use causal_arm_node::params::{BabblerParams, ReacherParams};

/// How a node answering the simulator waits for and trusts its peers: the parameters the
/// babbler and the reacher both declare.
#[derive(Debug, Clone)]
pub struct Peers {
    /// Give up when nothing arrives for this long.
    pub timeout: Duration,
    /// Wait for the recorder to read the actions too.
    pub wait_for_recorder: bool,
    /// The `trusted_publishers` setting.
    pub trusted_publishers: String,
}

macro_rules! peers_of {
    ($params:ty) => {
        impl From<&$params> for Peers {
            fn from(own: &$params) -> Self {
                Self {
                    timeout: Duration::from_secs_f64(own.timeout),
                    wait_for_recorder: own.wait_for_recorder,
                    trusted_publishers: own.trusted_publishers.clone(),
                }
            }
        }
    };
}
peers_of!(BabblerParams);
peers_of!(ReacherParams);

/// Where a state falls in the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepPlace {
    /// Step of the run (0-based).
    pub step: u64,
    /// Episode of the run (0-based).
    pub episode: u32,
    /// Step within the episode (0: the state right after the episode's reset).
    pub in_episode: u64,
}

/// Answers every state of `run` from step `start` on with `choose`'s command (and how it
/// was drawn), until the
/// run's last step or `stop`; returns how many steps were answered in all. `node` takes
/// its `wait_for_recorder` and `timeout` parameters from its graph-file declaration;
/// `who` names it in the closing log line ("babbler answered 500 of 500 steps; …").
/// Composed with the simulator (`port`), it takes the states and hands its actions over in
/// process (see [`crate::intra`]).
pub fn answer_states(
    who: &str,
    (node, port): (&mut RosNode, Option<IntraPort<'_>>),
    run: &RunSetup,
    peers: &Peers,
    start: u64,
    stop: &AtomicBool,
    mut choose: impl FnMut(&SimState, StepPlace) -> anyhow::Result<Drawn>,
) -> anyhow::Result<u64> {
    let timeout = peers.timeout;
    let recorded = qos::recorded();
    let screen = Rc::new(Screen::new(node, &peers.trusted_publishers)?);
    let mut source = FeedSource {
        node,
        screen: &screen,
        port,
    };
    let feeds = state_feeds::<StateParts>(&mut source, &recorded)?;
    let actions = Outlet::<Action>::open(node, port, topics::ACTION, recorded)?;

    // The simulator and, when the run is recorded, the recorder: an action written before
    // the recorder's reader matched would never reach the bag. Those composed with this
    // node take it in process.
    let with_recorder = peers.wait_for_recorder;
    let declared = crate::expected_readers(topics::ACTION, with_recorder)?.max(1);
    let needed = declared.saturating_sub(actions.local_subscribers());
    if needed > 0 && !node.wait_for_subscribers(actions.dds(), needed, timeout, crate::SETTLE, stop)
    {
        if stop.load(Ordering::SeqCst) {
            return Ok(start);
        }
        let recorder = if with_recorder {
            " and the recorder"
        } else {
            ""
        };
        bail!(
            "{needed} subscriber(s) of {} (the simulator{recorder}) did not appear within {timeout:?}",
            topics::ACTION,
        );
    }
    // Nodes that were running before the run (an rclpy `ros2 node list`) know this one, and
    // its actions, from the first step.
    node.wait_for_discovery_settled(crate::SETTLE);

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
            let place = StepPlace {
                step: answered,
                episode: (answered / per_episode) as u32,
                in_episode: answered % per_episode,
            };
            let state = state_from_messages(
                parts.joint_states.as_ref().expect("complete"),
                parts.ef_pose.as_ref().expect("complete"),
                parts.object_pose.as_ref().expect("complete"),
                parts.object_color.as_ref().expect("complete"),
                parts.magnet.as_ref().expect("complete"),
                place.step,
                place.episode,
            )?;
            let drawn = choose(&state, place)?;
            actions
                .publish(action_message(&state, &drawn, place.in_episode))
                .map_err(anyhow::Error::msg)?;
            answered += 1;
        }
    }

    crate::wait_for_final_delivery(actions.dds(), "the last action");
    tracing::info!(
        "{who} answered {answered} of {total} steps; {}",
        refusal_summary(&feeds, &joiner)
    );
    Ok(answered)
}
