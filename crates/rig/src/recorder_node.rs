//! `causal_arm_recorder`: subscribes to every topic of the graph and writes the bag,
//! one complete step at a time, in the same order `causal-arm generate` writes.
//! SIGINT/SIGTERM finalize the bag with every complete step; incomplete trailing steps
//! are reported, not silently dropped. A step is acknowledged to the simulator only once
//! its chunk is closed and handed to the OS, so even a SIGKILL loses no acknowledged step.

use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::bail;
use causal_arm_datagen::{BagSink, StepSink, validate};
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_msgs::std_msgs::msg::String as RosString;
use causal_arm_msgs::tf2_msgs::msg::TFMessage;
use causal_arm_node::{Params, RosArgs, RosNode, qos};
use causal_arm_protocol::{LatchedMessages, StepJoiner, time_from_ns, topics};

use crate::feed::{drain_or_wait, refusal_summary};
use crate::intra::{Inlet, IntraPort, Outlet};
use crate::parts::{FeedSource, RecordParts, record_feeds};
use crate::screen::Screen;
use crate::{ACK_TOPIC, RunSetup, stop_flag};
use causal_arm_node::params::{RecorderParams, RunParams};

/// The run's latched topics: the bag gets them, together, before its first step.
struct LatchedFeed {
    description: Inlet<RosString>,
    tf_static: Inlet<TFMessage>,
    got_description: Option<RosString>,
    got_tf_static: Option<TFMessage>,
    /// Both are in the bag (handed out by [`LatchedFeed::take`], or a resumed bag's):
    /// nothing is missing any more.
    delivered: bool,
}

impl LatchedFeed {
    /// `in_bag`: the bag already holds them (a resumed run).
    fn new(node: &mut RosNode, port: Option<IntraPort<'_>>, in_bag: bool) -> anyhow::Result<Self> {
        Ok(Self {
            description: Inlet::open(node, port, topics::ROBOT_DESCRIPTION, qos::latched())?,
            tf_static: Inlet::open(node, port, topics::TF_STATIC, qos::latched())?,
            got_description: None,
            got_tf_static: None,
            delivered: in_bag,
        })
    }

    /// Whether the bag holds both.
    fn delivered(&self) -> bool {
        self.delivered
    }

    /// Both messages once both have arrived (each is taken as it comes); `None` after.
    fn take(&mut self) -> Option<LatchedMessages> {
        if self.delivered {
            return None;
        }
        if let Some(d) = self.description.try_take() {
            self.got_description = Some(d);
        }
        if let Some(t) = self.tf_static.try_take() {
            self.got_tf_static = Some(t);
        }
        match (&self.got_description, &self.got_tf_static) {
            (Some(_), Some(_)) => {
                self.delivered = true;
                Some(LatchedMessages {
                    robot_description: self.got_description.take()?,
                    tf_static: self.got_tf_static.take()?,
                })
            }
            _ => None,
        }
    }

    /// The latched topics not yet received (the first step waits for them), for the
    /// report of a run that ends waiting.
    fn missing(&self) -> Vec<&'static str> {
        let mut missing = Vec::new();
        if self.delivered {
            return missing;
        }
        if self.got_description.is_none() {
            missing.push(topics::ROBOT_DESCRIPTION);
        }
        if self.got_tf_static.is_none() {
            missing.push(topics::TF_STATIC);
        }
        missing
    }
}

/// The bag of the run: a new one, or the cut-short one at `output` continued from the
/// run's start step.
fn open_sink(output: &Path, overwrite: bool, run: &RunSetup) -> anyhow::Result<BagSink> {
    Ok(match run.options.start_step {
        0 => BagSink::create(output, overwrite, &run.options)?,
        start => BagSink::resume(output, &run.options, Some(start))?.0,
    })
}

/// Tells the simulator which steps are safe in the bag: the last landed stamp, once per
/// stamp, and again while the run is idle.
///
/// The topic is volatile, so an acknowledgement written before this writer has matched
/// the simulator's reader reaches nobody. Under packet loss that happens: the simulator's
/// reader can match this writer (it has this node's announcement) while this writer has
/// not yet seen the simulator's, whose repair takes a heartbeat period. If the last
/// acknowledgement of a full window is lost so, the simulator waits for it and this node
/// for steps (seen once in 60 launches at 1 % loss). Repeating the last one while idle
/// ends that within [`ACK_REPEAT`] of the match; acknowledgements are cumulative, so a
/// repeat is harmless.
struct Acknowledger {
    outlet: Outlet<Clock>,
    acked: Option<u64>,
    sent: Instant,
}

/// How often the last acknowledgement is repeated while nothing arrives.
const ACK_REPEAT: Duration = Duration::from_millis(100);

impl Acknowledger {
    fn new(outlet: Outlet<Clock>) -> Self {
        Self {
            outlet,
            acked: None,
            sent: Instant::now(),
        }
    }

    /// Acknowledges every step up to `landed`, if that is news.
    fn landed(&mut self, landed: Option<u64>) {
        if let Some(stamp) = landed
            && self.acked != Some(stamp)
        {
            self.acked = Some(stamp);
            self.send(stamp);
        }
    }

    /// Repeats the last acknowledgement if it is older than [`ACK_REPEAT`].
    fn repeat_if_due(&mut self) {
        if let Some(stamp) = self.acked
            && self.sent.elapsed() >= ACK_REPEAT
        {
            self.send(stamp);
        }
    }

    fn send(&mut self, stamp: u64) {
        // A lost acknowledgement is repeated by the next one; the bag is what counts.
        let _ = self.outlet.publish(Clock {
            clock: time_from_ns(stamp),
        });
        self.sent = Instant::now();
    }
}

/// How long the recorder lets samples gather after a wake-up that took some. Far below
/// the simulator's acknowledgement window (hundreds of steps), so it never holds the run
/// up; at thousands of steps per second it takes several steps per wake-up.
const GATHER: Duration = Duration::from_millis(1);

/// Why a run ended with nothing received for `timeout` after `written` of `total` steps;
/// `waiting`: the latched topics still missing and the steps waiting for them.
fn stall_error(
    timeout: Duration,
    (written, total): (u64, u64),
    waiting: Option<(Vec<&'static str>, usize)>,
) -> anyhow::Error {
    match waiting {
        None => anyhow::anyhow!(
            "nothing received for {timeout:?} after {written} of {total} steps; bag finalized with the complete steps"
        ),
        Some((missing, pending)) => anyhow::anyhow!(
            "the latched {} did not arrive for {timeout:?} ({pending} steps waiting for it); bag finalized without steps",
            missing.join(" and ")
        ),
    }
}

/// Names the steps a run leaves unwritten and what the first of them lacks (`latched`: the
/// latched messages still missing, which every step waits for).
fn warn_of_unwritten_steps(joiner: &StepJoiner<RecordParts>, latched: Vec<&'static str>) {
    if let Some((stamp, mut missing)) = joiner.first_missing() {
        missing.extend(latched);
        tracing::warn!(
            "{} step(s) not written (the first, at {stamp} ns, lacks {})",
            joiner.pending(),
            missing.join(", ")
        );
    }
}

/// The bag directory and the run to record in it, from the recorder's parameters, checked
/// before anything is opened.
fn recording_of(params: &Params) -> anyhow::Result<(RecorderParams, RunSetup)> {
    let own = RecorderParams::from_params(params)?;
    if own.output.is_empty() {
        bail!("parameter \"output\" is required: --ros-args -p output:=bags/NAME");
    }
    let mut run = RunSetup::from_params(&RunParams::from_params(params)?, &own.output)?;
    // Declared ranges keep both non-negative.
    run.options.split = causal_arm_datagen::SplitLimits::from_ros2_units(
        own.max_bag_size as u64,
        own.max_bag_duration as u64,
    );
    run.options.compression = own.chunk_compression.parse().map_err(anyhow::Error::msg)?;
    validate(&run.options)?;
    Ok((own, run))
}

/// Runs the recorder node until every step is written or SIGINT/SIGTERM.
pub fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    run_composed(ros_args, None)
}

/// As [`run`], composed with other nodes of the graph in this process (`port`).
pub fn run_composed(ros_args: &RosArgs, port: Option<IntraPort<'_>>) -> anyhow::Result<()> {
    let mut node = RosNode::new(RecorderParams::NODE, &RecorderParams::specs()?, ros_args)?;
    let (own, run) = recording_of(node.params())?;
    let timeout = Duration::from_secs_f64(own.timeout);
    let stop = stop_flag();
    let screen = Rc::new(Screen::new(&mut node, &own.trusted_publishers)?);
    let mut source = FeedSource {
        node: &mut node,
        screen: &screen,
        port,
    };
    let feeds = record_feeds(&mut source, &qos::recorded())?;
    // A resumed bag already holds the latched messages.
    let mut latched = LatchedFeed::new(&mut node, port, run.options.start_step > 0)?;
    let mut ack = Acknowledger::new(Outlet::<Clock>::open(
        &mut node,
        port,
        ACK_TOPIC,
        qos::default_reliable(),
    )?);
    // Nodes that were running before the run know this one from the first step.
    node.wait_for_discovery_settled(crate::SETTLE);

    let start = run.options.start_step;
    let mut sink = open_sink(&PathBuf::from(&own.output), own.overwrite, &run)?;
    let total = run.options.plan.total_steps();
    let mut joiner = StepJoiner::<RecordParts>::new();
    let mut written = start;
    let mut last_activity = Instant::now();
    // The declared range keeps it positive.
    let land_every = own.land_every as usize;
    let mut result = Ok(());
    while written < total && !stop.load(Ordering::SeqCst) {
        let mut arrived = drain_or_wait(&feeds, &mut joiner, Duration::from_millis(100));
        if let Some(messages) = latched.take() {
            sink.latched(&messages)?;
            arrived = true;
        }
        // Older parts may still be in flight on another topic: write strictly in order.
        while latched.delivered()
            && let Some((stamp, parts)) = joiner.pop_complete(true)
        {
            let (messages, action) = parts.into_step().expect("complete");
            sink.state(stamp, messages)?;
            sink.action(stamp, &action)?;
            written += 1;
            if written.is_multiple_of(1000) || written == total {
                tracing::info!("recorded {written}/{total} steps");
            }
        }
        // Acknowledge only steps a kill can no longer lose; land them in a closed chunk
        // every `land_every` steps, or when the simulator has gone quiet (it may be
        // waiting for this very acknowledgement).
        if sink.unlanded_steps() >= land_every || (!arrived && sink.unlanded_steps() > 0) {
            sink.land()?;
        }
        ack.landed(sink.landed_stamp());
        if arrived {
            last_activity = Instant::now();
            // Let the next steps gather (the simulator runs ahead within its window), so
            // one wake-up takes several steps instead of every sample waking this thread.
            std::thread::sleep(GATHER);
        } else if last_activity.elapsed() > timeout {
            let waiting = (!latched.delivered()).then(|| (latched.missing(), joiner.pending()));
            result = Err(stall_error(timeout, (written, total), waiting));
            break;
        } else {
            ack.repeat_if_due();
        }
    }
    tracing::info!("recorder {}", refusal_summary(&feeds, &joiner));
    warn_of_unwritten_steps(&joiner, latched.missing());
    let last_written = sink.last_step_stamp();
    let summary = sink.finish()?;
    // Every step has landed now: acknowledge the last one, and let reliable delivery reach
    // the simulator (it waits for this very acknowledgement before it exits).
    ack.landed(last_written);
    crate::wait_for_final_delivery(ack.outlet.dds(), "the last acknowledgement");
    tracing::info!(
        "wrote {} ({written} steps of {total})",
        summary.dir.display()
    );
    println!("bag: {} ({written} steps)", summary.dir.display());
    result
}
