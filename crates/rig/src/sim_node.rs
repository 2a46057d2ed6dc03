//! `causal_arm_sim`: the simulator as a ROS 2 node. It runs the same step loop as
//! `causal-arm generate` ([`causal_arm_datagen::drive`]), with DDS on both sides: states
//! go out on the graph's topics (never more than `ack_window` steps ahead of the
//! recorder) and each command is the babbler node's answer to that very state.

use std::collections::VecDeque;
use std::rc::Rc;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use anyhow::bail;
use causal_arm_datagen::{
    CommandSource, GenerateError, StepSink, drive_range, fast_forward, validate,
};
use causal_arm_msgs::geometry_msgs::msg::PoseStamped;
use causal_arm_msgs::msg::{Action, MagnetState, ObjectColor};
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_msgs::std_msgs::msg::String as RosString;
use causal_arm_msgs::tf2_msgs::msg::TFMessage;
use causal_arm_msgs::visualization_msgs::msg::MarkerArray;
use causal_arm_node::{RosArgs, RosNode, qos};
use causal_arm_protocol::{
    Command, Drawn, LatchedMessages, QuarantineCounts, Scene, SimState, StepMessages, command_of,
    markers_key, ns_from_time, scene_markers, topics,
};

use crate::feed::LOGGED;
use crate::flow::AckWindow;
use crate::intra::{IntraPort, Outlet, local_receiver};
use crate::screen::{Screen, Screened};
use crate::{ACK_TOPIC, RunSetup, stop_flag};
use causal_arm_node::params::{RunParams, SimParams};

fn publish<M: causal_arm_msgs::RosMessage + Clone>(
    p: &Outlet<M>,
    msg: M,
) -> Result<(), GenerateError> {
    p.publish(msg).map_err(GenerateError::Transport)
}

/// The state topics as a [`StepSink`], paced by the recorder's acknowledgements.
struct DdsStatePublisher {
    joint_states: Outlet<JointState>,
    ef_pose: Outlet<PoseStamped>,
    object_pose: Outlet<PoseStamped>,
    object_color: Outlet<ObjectColor>,
    magnet: Outlet<MagnetState>,
    clock: Outlet<Clock>,
    tf: Outlet<TFMessage>,
    description: Outlet<RosString>,
    tf_static: Outlet<TFMessage>,
    /// Published when what they show changes (latched); bags hold them every step.
    markers: Outlet<MarkerArray>,
    scene: Scene,
    shown: Option<([u32; 3], bool, bool)>,
    /// `Some` when the recorder paces the run.
    acks: Option<AckFeed>,
    stop: Arc<AtomicBool>,
    last_stamp: u64,
}

impl DdsStatePublisher {
    /// Waits for the graph file's readers of each state topic (those composed with this
    /// node take it in process); `Ok(false)` when stopped.
    fn wait_for_readers(
        &self,
        node: &mut RosNode,
        with_recorder: bool,
        timeout: Duration,
        stop: &AtomicBool,
    ) -> anyhow::Result<bool> {
        // `/clock` is left out: every ROS node reads it (ros2-client's own clock reader),
        // so its count says nothing; the recorder creates its `/clock` reader before its
        // `/tf` one.
        macro_rules! wait {
            ($publisher:expr, $topic:expr) => {
                let needed = crate::expected_readers($topic, with_recorder)?
                    .saturating_sub($publisher.local_subscribers());
                if needed > 0
                    && !node.wait_for_subscribers(
                        $publisher.dds(),
                        needed,
                        timeout,
                        Duration::ZERO,
                        stop,
                    )
                {
                    if stop.load(Ordering::SeqCst) {
                        return Ok(false);
                    }
                    bail!(
                        "{needed} subscriber(s) of {} did not appear within {timeout:?}",
                        $topic
                    );
                }
            };
        }
        macro_rules! each_state_topic {
            ($action:ident) => {
                $action!(&self.joint_states, topics::JOINT_STATES);
                $action!(&self.ef_pose, topics::EF_POSE);
                $action!(&self.object_pose, topics::OBJECT_POSE);
                $action!(&self.object_color, topics::OBJECT_COLOR);
                $action!(&self.magnet, topics::MAGNET_STATE);
                $action!(&self.tf, topics::TF);
            };
        }
        each_state_topic!(wait);
        // Then until every reader has matched us on its side too, within one settle time.
        let deadline = Instant::now() + crate::SETTLE;
        macro_rules! confirm {
            ($publisher:expr, $topic:expr) => {
                let needed = crate::expected_readers($topic, with_recorder)?
                    .saturating_sub($publisher.local_subscribers());
                if !RosNode::confirm_subscribers($publisher.dds(), needed, deadline) {
                    tracing::debug!(
                        "not every reader of {} confirmed within {:?}",
                        $topic,
                        crate::SETTLE
                    );
                }
            };
        }
        each_state_topic!(confirm);
        // Subscribers outside the graph file that were running before the run (an rclpy
        // echo) get its first step too.
        node.wait_for_discovery_settled(crate::SETTLE);
        Ok(true)
    }

    fn new(
        node: &mut RosNode,
        paced_by: Option<AckWindow>,
        (screen, port): (&Rc<Screen>, Option<IntraPort<'_>>),
        scene: Scene,
    ) -> anyhow::Result<Self> {
        let recorded = qos::recorded();
        let acks = match paced_by {
            Some(window) => Some(AckFeed {
                source: match local_receiver(port, ACK_TOPIC)? {
                    Some(local) => AckSource::Local(local),
                    None => AckSource::Dds(Box::new(Screened::new(
                        node,
                        ACK_TOPIC,
                        qos::default_reliable(),
                        screen,
                    )?)),
                },
                window,
                unreadable: 0,
            }),
            None => None,
        };
        macro_rules! outlet {
            ($topic:expr, $qos:expr) => {
                Outlet::open(node, port, $topic, $qos)?
            };
        }
        Ok(Self {
            joint_states: outlet!(topics::JOINT_STATES, recorded.clone()),
            ef_pose: outlet!(topics::EF_POSE, recorded.clone()),
            object_pose: outlet!(topics::OBJECT_POSE, recorded.clone()),
            object_color: outlet!(topics::OBJECT_COLOR, recorded.clone()),
            magnet: outlet!(topics::MAGNET_STATE, recorded.clone()),
            clock: outlet!(topics::CLOCK, recorded.clone()),
            tf: outlet!(topics::TF, recorded),
            description: outlet!(topics::ROBOT_DESCRIPTION, qos::latched()),
            tf_static: outlet!(topics::TF_STATIC, qos::latched()),
            markers: outlet!(topics::SCENE_MARKERS, qos::latched()),
            scene,
            shown: None,
            acks,
            stop: stop_flag(),
            last_stamp: 0,
        })
    }

    fn take_acks(&mut self) {
        if let Some(feed) = &mut self.acks {
            feed.take();
        }
    }

    /// Waits until the recorder's window lets `stamp` go out.
    fn wait_for_window(&mut self, stamp: u64) -> Result<(), GenerateError> {
        loop {
            self.take_acks();
            match &self.acks {
                Some(feed) if !feed.window.allows(stamp) => {}
                _ => return Ok(()),
            }
            if self.stop.load(Ordering::SeqCst) {
                return Err(GenerateError::Stopped);
            }
            std::thread::sleep(Duration::from_micros(100));
        }
    }

    /// Waits (up to `timeout`) until the recorder acknowledged the last step published.
    fn wait_until_recorded(&mut self, timeout: Duration) {
        let start = Instant::now();
        loop {
            self.take_acks();
            let done = match &self.acks {
                Some(feed) => feed.window.acked() == Some(self.last_stamp),
                None => true,
            };
            if done || self.stop.load(Ordering::SeqCst) || start.elapsed() > timeout {
                return;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// The recorder's acknowledgements, paced into the window.
struct AckFeed {
    source: AckSource,
    window: AckWindow,
    /// Acknowledgements that could not be read.
    unreadable: u64,
}

/// Where acknowledgements come from: over DDS only from the recorder's writers (screened
/// as actions are: a forged acknowledgement would let the simulator run ahead of the
/// bag), or in process from the recorder composed with this node.
enum AckSource {
    Dds(Box<Screened<Clock, u64>>),
    Local(Receiver<Clock>),
}

impl AckFeed {
    /// Feeds the window every acknowledgement the screen admits. Called in the window's
    /// wait loop: reads the graph's announcements only when there is something to screen.
    fn take(&mut self) {
        let stamps = match &mut self.source {
            AckSource::Local(receiver) => receiver
                .try_iter()
                .map(|a| ns_from_time(&a.clock))
                .collect(),
            AckSource::Dds(screened) => {
                let unreadable = &mut self.unreadable;
                let stamp = |ack: Clock| ns_from_time(&ack.clock);
                let (_, stamps) = screened.take_admitted(stamp, |e| {
                    *unreadable += 1;
                    if *unreadable <= LOGGED {
                        tracing::warn!("ignoring an unreadable acknowledgement: {e}");
                    }
                });
                stamps
            }
        };
        for stamp in stamps {
            if !self.window.ack(stamp) && self.window.refused() <= LOGGED {
                tracing::warn!("ignoring an acknowledgement of step {stamp} ns, not yet published");
            }
        }
    }

    /// Acknowledgements kept out for their writer (none in process).
    fn screened(&self) -> QuarantineCounts {
        match &self.source {
            AckSource::Dds(screened) => screened.counts(),
            AckSource::Local(_) => QuarantineCounts::default(),
        }
    }
}

impl StepSink for DdsStatePublisher {
    fn latched(&mut self, m: &LatchedMessages) -> Result<(), GenerateError> {
        let description = m.robot_description.clone();
        publish(&self.description, description)?;
        publish(&self.tf_static, m.tf_static.clone())
    }

    fn state(&mut self, stamp_ns: u64, m: StepMessages) -> Result<(), GenerateError> {
        self.wait_for_window(stamp_ns)?;
        let shows = markers_key(&m);
        if self.shown != Some(shows) {
            let markers = scene_markers(&m, &self.scene);
            publish(&self.markers, markers)?;
            self.shown = Some(shows);
        }
        publish(&self.joint_states, m.joint_states)?;
        publish(&self.ef_pose, m.ef_pose)?;
        publish(&self.object_pose, m.object_pose)?;
        publish(&self.object_color, m.object_color)?;
        publish(&self.magnet, m.magnet)?;
        publish(&self.clock, m.clock)?;
        publish(&self.tf, m.tf)?;
        if let Some(feed) = &mut self.acks {
            feed.window.published(stamp_ns);
        }
        self.last_stamp = stamp_ns;
        Ok(())
    }

    /// The babbler node published the action itself; the recorder takes it from there.
    fn action(&mut self, _stamp_ns: u64, _action: &Action) -> Result<(), GenerateError> {
        Ok(())
    }
}

/// The babbler node's answers as the loop's [`CommandSource`]. Actions of other nodes'
/// writers are kept out (see [`Screen`]); answers to other stamps and malformed ones are
/// counted and skipped.
struct DdsCommands {
    source: ActionSource,
    timeout: Duration,
    stop: Arc<AtomicBool>,
    ignored: u64,
    /// Actions admitted by the screen, not looked at yet.
    admitted: VecDeque<Action>,
}

/// Where actions come from: over DDS, screened, or in process from the babbler composed
/// with this node.
enum ActionSource {
    Dds(Box<Screened<Action, Action>>),
    Local(Receiver<Action>),
}

impl DdsCommands {
    fn new(
        (node, port): (&mut RosNode, Option<IntraPort<'_>>),
        screen: Rc<Screen>,
        timeout: Duration,
        stop: Arc<AtomicBool>,
    ) -> anyhow::Result<Self> {
        let source = match local_receiver(port, topics::ACTION)? {
            Some(local) => ActionSource::Local(local),
            None => ActionSource::Dds(Box::new(Screened::new(
                node,
                topics::ACTION,
                qos::recorded(),
                &screen,
            )?)),
        };
        Ok(Self {
            source,
            timeout,
            stop,
            ignored: 0,
            admitted: VecDeque::new(),
        })
    }

    /// Actions kept out for their writer (none in process).
    fn screened(&self) -> QuarantineCounts {
        match &self.source {
            ActionSource::Dds(screened) => screened.counts(),
            ActionSource::Local(_) => QuarantineCounts::default(),
        }
    }

    /// Logs the first few skipped actions; the rest are only counted.
    fn skip(&mut self, why: std::fmt::Arguments<'_>) {
        self.ignored += 1;
        if self.ignored <= LOGGED {
            tracing::warn!("ignoring an action: {why}");
        }
    }

    /// Waits up to 100 ms for an action; queues what the screen admits.
    fn receive(&mut self) {
        const WAIT: Duration = Duration::from_millis(100);
        let mut undecodable = None;
        let admitted = match &mut self.source {
            ActionSource::Local(receiver) => receiver.recv_timeout(WAIT).into_iter().collect(),
            ActionSource::Dds(screened) => {
                let keep = |action| action;
                screened
                    .wait_admitted(WAIT, keep, |e| undecodable = Some(e))
                    .1
            }
        };
        self.admitted.extend(admitted);
        if let Some(e) = undecodable {
            self.skip(format_args!("undecodable: {e:#}"));
        }
    }

    /// The command of the well-formed action answering the state stamped `stamp`.
    fn answer(&mut self, stamp: u64) -> Result<Command, GenerateError> {
        let asked = Instant::now();
        loop {
            if self.stop.load(Ordering::SeqCst) {
                return Err(GenerateError::Stopped);
            }
            if asked.elapsed() > self.timeout {
                return Err(GenerateError::Transport(format!(
                    "no {} answering stamp {stamp} ns within {:?}",
                    topics::ACTION,
                    self.timeout
                )));
            }
            let Some(a) = self.admitted.pop_front() else {
                self.receive();
                continue;
            };
            if ns_from_time(&a.header.stamp) != stamp {
                self.skip(format_args!(
                    "stamped {} ns while waiting for {stamp} ns",
                    ns_from_time(&a.header.stamp)
                ));
                continue;
            }
            match command_of(&a) {
                Ok(command) => return Ok(command),
                Err(problem) => self.skip(format_args!("at {stamp} ns: {problem}")),
            }
        }
    }
}

impl CommandSource for DdsCommands {
    /// The babbler node starts its new episode itself, from the step count.
    fn new_episode(&mut self) {}

    /// The babbler node's command; the recorder records its action as it was sent, so
    /// its design is not needed here.
    fn command(&mut self, state: &SimState, _k: u64) -> Result<Drawn, GenerateError> {
        Ok(Drawn {
            command: self.answer(state.stamp_ns)?,
            design: Vec::new(),
        })
    }
}

/// Runs the simulator node until the run is complete or SIGINT/SIGTERM.
pub fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    run_composed(ros_args, None)
}

/// As [`run`], composed with other nodes of the graph in this process (`port`).
pub fn run_composed(ros_args: &RosArgs, port: Option<IntraPort<'_>>) -> anyhow::Result<()> {
    let mut node = RosNode::new(SimParams::NODE, &SimParams::specs()?, ros_args)?;
    let run = RunSetup::from_params(&RunParams::from_params(node.params())?, "")?;
    let own = SimParams::from_params(node.params())?;
    validate(&run.options)?;
    // The declared range keeps the window positive.
    let window = own.ack_window as u64;
    let wait_for_recorder = own.wait_for_recorder;
    let timeout = Duration::from_secs_f64(own.timeout);
    let stop = stop_flag();

    let start = run.options.start_step;
    let pacing = wait_for_recorder.then(|| {
        let mut window = AckWindow::new(window, run.step_ns());
        // Resuming: the bag already holds the steps before `start`.
        if start > 0 {
            window.resume_after(((start - 1) as f64 * run.step_ns()).round() as u64);
        }
        window
    });
    let screen = Rc::new(Screen::new(&mut node, &own.trusted_publishers)?);
    let scene = run.options.sim.scene();
    let mut states = DdsStatePublisher::new(&mut node, pacing, (&screen, port), scene)?;
    let mut commands =
        DdsCommands::new((&mut node, port), Rc::clone(&screen), timeout, stop.clone())?;
    let (mut sim, _) = fast_forward(&run.options, start)?;
    states.latched(&sim.latched_messages())?;

    // Wait until every reader the graph declares (the babbler, the recorder) has matched
    // every state topic, then let their side settle.
    if !states.wait_for_readers(&mut node, wait_for_recorder, timeout, &stop)? {
        return Ok(());
    }
    let plan = &run.options.plan;
    tracing::info!(
        "simulator starting: {} × {} steps",
        plan.episodes,
        plan.steps_per_episode
    );
    if start > 0 {
        tracing::info!("resuming at step {start}: the simulator re-ran the steps before it");
    }
    let steps = start..plan.total_steps();
    match drive_range(
        plan,
        steps,
        &mut sim,
        &mut commands,
        &mut states,
        &mut |_, _| {},
    ) {
        Ok(_) => {}
        Err(GenerateError::Stopped) => return Ok(()),
        Err(e) => return Err(e.into()),
    }
    states.wait_until_recorded(timeout);
    let screened = commands.screened();
    let acks = states
        .acks
        .as_ref()
        .map(AckFeed::screened)
        .unwrap_or_default();
    tracing::info!(
        "simulator done at sim time {:.3} s; ignored {} actions of other nodes' writers, {} of unannounced writers and {} stray or malformed actions; {} acknowledgements of other nodes' writers and {} of unannounced writers",
        states.last_stamp as f64 * 1e-9,
        screened.foreign,
        screened.unidentified,
        commands.ignored,
        acks.foreign,
        acks.unidentified
    );
    Ok(())
}
