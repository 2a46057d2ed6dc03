//! Subscriptions feeding a [`StepJoiner`]: each topic's samples are filed under their
//! stamp. The babbler and the recorder each hold one feed per topic they join. Samples
//! from writers of nodes other than the topic's trusted publishers are kept out (see
//! [`Screen`]); what a joiner refuses (stale or duplicate samples) and what cannot be read
//! or is malformed is logged and counted, never fatal: a stray sample never takes the
//! place of the step's real one.

use std::cell::{Cell, RefCell};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::Duration;

use causal_arm_msgs::RosMessage;
use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_protocol::{QuarantineCounts, StepJoiner, StepParts, WellFormed, ns_from_time};

use crate::screen::Screened;

/// Stray samples of one kind logged in full before the rest are only counted (the
/// feeds and the simulator's action wait).
pub(crate) const LOGGED: u64 = 5;

/// One topic's samples into a joiner of `P`.
pub trait Feed<P> {
    /// The topic.
    fn topic(&self) -> &'static str;
    /// Files every sample already waiting; returns how many arrived.
    fn drain(&self, joiner: &mut StepJoiner<P>) -> usize;
    /// Waits up to `timeout` for one sample and files it; returns whether one arrived.
    fn wait(&self, joiner: &mut StepJoiner<P>, timeout: Duration) -> bool;
    /// Samples that could not be read or were malformed (see [`WellFormed`]).
    fn unreadable(&self) -> u64;
    /// Samples kept out for their writer (see [`Screen`]).
    fn screened(&self) -> QuarantineCounts;
}

/// A [`Feed`] of message type `M`: `stamp` says which step a sample belongs to and `put`
/// files it into the step's parts (see [`StepJoiner::insert`]).
pub struct TopicFeed<M, P> {
    topic: &'static str,
    screened: RefCell<Screened<M, M>>,
    stamp: fn(&M) -> &Time,
    put: fn(&mut P, M) -> bool,
    unreadable: Cell<u64>,
}

impl<M, P> TopicFeed<M, P> {
    /// A feed of `topic` from `screened`, its subscription accepting samples only from
    /// writers of the nodes its screen trusts for the topic.
    pub fn new(
        topic: &'static str,
        screened: Screened<M, M>,
        stamp: fn(&M) -> &Time,
        put: fn(&mut P, M) -> bool,
    ) -> Self {
        Self {
            topic,
            screened: RefCell::new(screened),
            stamp,
            put,
            unreadable: Cell::new(0),
        }
    }
}

impl<M: RosMessage + WellFormed, P: StepParts> TopicFeed<M, P> {
    fn file(&self, joiner: &mut StepJoiner<P>, message: M) {
        if let Err(problem) = file_sample(self.topic, self.stamp, self.put, joiner, message) {
            self.count_unreadable(problem);
        }
    }

    fn count_unreadable(&self, problem: impl std::fmt::Display) {
        count_unreadable(&self.unreadable, self.topic, problem);
    }
}

/// Files a well-formed `message` of `topic` under its stamp; a malformed one is returned
/// as the problem to count. What the joiner refuses (stale, duplicate) it counts itself.
fn file_sample<M: WellFormed, P: StepParts>(
    topic: &'static str,
    stamp: fn(&M) -> &Time,
    put: fn(&mut P, M) -> bool,
    joiner: &mut StepJoiner<P>,
    message: M,
) -> Result<(), String> {
    if let Err(problem) = message.well_formed() {
        return Err(format!("malformed: {problem}"));
    }
    let stamp = ns_from_time(stamp(&message));
    if let Err(refusal) = joiner.insert(topic, stamp, |parts| put(parts, message)) {
        let counts = joiner.counts();
        if counts.stale + counts.duplicate <= LOGGED {
            tracing::warn!("ignoring a sample: {refusal}");
        }
    }
    Ok(())
}

/// Counts one sample of `topic` that could not be used; logs the first few.
fn count_unreadable(count: &Cell<u64>, topic: &str, problem: impl std::fmt::Display) {
    let n = count.get() + 1;
    count.set(n);
    if n <= LOGGED {
        tracing::warn!("ignoring an unreadable {topic} sample: {problem}");
    }
}

impl<M: RosMessage + WellFormed, P: StepParts> Feed<P> for TopicFeed<M, P> {
    fn topic(&self) -> &'static str {
        self.topic
    }

    fn drain(&self, joiner: &mut StepJoiner<P>) -> usize {
        let (arrived, admitted) = self
            .screened
            .borrow_mut()
            .take_admitted(|m| m, |e| self.count_unreadable(e));
        for message in admitted {
            self.file(joiner, message);
        }
        arrived
    }

    fn wait(&self, joiner: &mut StepJoiner<P>, timeout: Duration) -> bool {
        let (arrived, admitted) =
            self.screened
                .borrow_mut()
                .wait_admitted(timeout, |m| m, |e| self.count_unreadable(e));
        for message in admitted {
            self.file(joiner, message);
        }
        arrived
    }

    fn unreadable(&self) -> u64 {
        self.unreadable.get()
    }

    fn screened(&self) -> QuarantineCounts {
        self.screened.borrow().counts()
    }
}

/// A [`Feed`] from a node composed into the same process (see [`crate::intra`]): its
/// publisher is known, so nothing is screened or decoded.
pub struct LocalFeed<M, P> {
    topic: &'static str,
    receiver: Receiver<M>,
    stamp: fn(&M) -> &Time,
    put: fn(&mut P, M) -> bool,
    malformed: Cell<u64>,
}

impl<M, P> LocalFeed<M, P> {
    /// A feed of `topic`'s in-process link `receiver`.
    pub fn new(
        topic: &'static str,
        receiver: Receiver<M>,
        stamp: fn(&M) -> &Time,
        put: fn(&mut P, M) -> bool,
    ) -> Self {
        Self {
            topic,
            receiver,
            stamp,
            put,
            malformed: Cell::new(0),
        }
    }

    fn file(&self, joiner: &mut StepJoiner<P>, message: M)
    where
        M: WellFormed,
        P: StepParts,
    {
        if let Err(problem) = file_sample(self.topic, self.stamp, self.put, joiner, message) {
            count_unreadable(&self.malformed, self.topic, problem);
        }
    }
}

impl<M: WellFormed, P: StepParts> Feed<P> for LocalFeed<M, P> {
    fn topic(&self) -> &'static str {
        self.topic
    }

    fn drain(&self, joiner: &mut StepJoiner<P>) -> usize {
        let mut arrived = 0;
        while let Ok(message) = self.receiver.try_recv() {
            self.file(joiner, message);
            arrived += 1;
        }
        arrived
    }

    /// A publisher that has stopped leaves an empty, closed link: that waits out
    /// `timeout` too (the node's own timeout then says the run went quiet).
    fn wait(&self, joiner: &mut StepJoiner<P>, timeout: Duration) -> bool {
        match self.receiver.recv_timeout(timeout) {
            Ok(message) => {
                self.file(joiner, message);
                true
            }
            Err(RecvTimeoutError::Timeout) => false,
            Err(RecvTimeoutError::Disconnected) => {
                std::thread::sleep(timeout);
                false
            }
        }
    }

    fn unreadable(&self) -> u64 {
        self.malformed.get()
    }

    fn screened(&self) -> QuarantineCounts {
        QuarantineCounts::default()
    }
}

/// Files everything waiting on `feeds`; if nothing was, sleeps until the last of the
/// samples the oldest pending step lacks arrives (or the last feed's, or `timeout`), so an
/// idle loop never polls. Feeds are in the order their topics are published, so a step
/// usually wakes this thread once, when its last sample is in, instead of once per sample.
/// Returns whether anything arrived.
pub fn drain_or_wait<P: StepParts>(
    feeds: &[Box<dyn Feed<P>>],
    joiner: &mut StepJoiner<P>,
    timeout: Duration,
) -> bool {
    let arrived: usize = feeds.iter().map(|f| f.drain(joiner)).sum();
    if arrived > 0 {
        return true;
    }
    let lacking = joiner
        .first_missing()
        .and_then(|(_, missing)| missing.last().copied());
    let feed = lacking
        .and_then(|topic| feeds.iter().find(|f| f.topic() == topic))
        .or(feeds.last());
    feed.is_some_and(|f| f.wait(joiner, timeout))
}

/// One line on what the feeds and the joiner refused, for the node's last log line.
pub fn refusal_summary<P: StepParts>(feeds: &[Box<dyn Feed<P>>], joiner: &StepJoiner<P>) -> String {
    let counts = joiner.counts();
    let unreadable: u64 = feeds.iter().map(|f| f.unreadable()).sum();
    let foreign: u64 = feeds.iter().map(|f| f.screened().foreign).sum();
    let unidentified: u64 = feeds.iter().map(|f| f.screened().unidentified).sum();
    format!(
        "ignored {foreign} samples of other nodes' writers, {unidentified} of unannounced writers, {} stale, {} duplicate and {unreadable} unreadable or malformed samples; dropped {} incomplete steps",
        counts.stale, counts.duplicate, counts.abandoned
    )
}
