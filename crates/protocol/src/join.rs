//! Joining samples that arrive topic by topic into whole steps, by stamp.
//!
//! The simulator stamps every message of one step with the same sim time, but the topics
//! travel separately: a subscriber (the babbler, the recorder) and a bag reader (the
//! dataset builder) see them interleaved. [`StepJoiner`] collects the parts of each step
//! under its stamp and hands out complete steps, oldest first. It refuses what cannot be
//! part of the run — a second sample for a part already held, a sample older than a step
//! already handed out — and counts every refusal, so a stray publisher can neither corrupt
//! a step nor stall the loop.

use std::collections::BTreeMap;

/// The parts of one step a consumer waits for: one `Option` per topic.
pub trait StepParts: Default {
    /// Topics whose part is still missing, in the graph's order (empty when complete).
    fn missing(&self) -> Vec<&'static str>;

    /// Whether every part is in.
    fn is_complete(&self) -> bool {
        self.missing().is_empty()
    }
}

/// Declares a [`StepParts`] struct: one `Option` field per topic, `missing()` listing the
/// topics of the empty ones in declaration order.
///
/// ```
/// causal_arm_protocol::step_parts! {
///     /// What a consumer needs of one step.
///     pub struct Needed {
///         joint_states: Vec<f64> = "/joint_states",
///         magnet: bool = "/magnet/state",
///     }
/// }
/// use causal_arm_protocol::join::StepParts;
/// let parts = Needed { magnet: Some(true), ..Default::default() };
/// assert_eq!(parts.missing(), vec!["/joint_states"]);
/// ```
#[macro_export]
macro_rules! step_parts {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $($(#[$field_meta:meta])* $field:ident: $ty:ty = $topic:expr),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Default)]
        $vis struct $name {
            $($(#[$field_meta])* #[doc = concat!("The part from `", stringify!($field), "`.")] pub $field: Option<$ty>,)*
        }

        impl $crate::join::StepParts for $name {
            fn missing(&self) -> Vec<&'static str> {
                let mut missing = Vec::new();
                $(if self.$field.is_none() {
                    missing.push($topic);
                })*
                missing
            }
        }
    };
}

/// Why a sample was not joined.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// Its step was already handed out (or is older than one that was).
    #[error("{topic} stamped {stamp} ns is not newer than the last complete step ({last} ns)")]
    Stale {
        /// Topic of the sample.
        topic: &'static str,
        /// Its stamp, ns.
        stamp: u64,
        /// Stamp of the last step handed out, ns.
        last: u64,
    },
    /// The step already holds this part.
    #[error("a second {topic} sample stamped {stamp} ns")]
    Duplicate {
        /// Topic of the sample.
        topic: &'static str,
        /// Its stamp, ns.
        stamp: u64,
    },
}

/// Counts of what a joiner refused or gave up on, for the node's logs and exit report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct JoinCounts {
    /// Samples older than the last complete step.
    pub stale: u64,
    /// Second samples for a part already held.
    pub duplicate: u64,
    /// Incomplete steps dropped because a newer one completed while they could no
    /// longer (see [`StepJoiner::pop_complete`]).
    pub abandoned: u64,
}

/// Puts `value` into an empty `slot`; returns true, keeping the old value, when the slot
/// was already filled. This is the `put` of [`StepJoiner::insert`] for one part.
pub fn fill<T>(slot: &mut Option<T>, value: T) -> bool {
    if slot.is_some() {
        return true;
    }
    *slot = Some(value);
    false
}

/// Collects step parts by stamp and hands out complete steps in stamp order.
#[derive(Debug)]
pub struct StepJoiner<P> {
    pending: BTreeMap<u64, P>,
    last_complete: Option<u64>,
    counts: JoinCounts,
}

impl<P: StepParts> Default for StepJoiner<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<P: StepParts> StepJoiner<P> {
    /// An empty joiner.
    pub fn new() -> Self {
        Self {
            pending: BTreeMap::new(),
            last_complete: None,
            counts: JoinCounts::default(),
        }
    }

    /// Files one sample: `put` stores it into the step's parts and returns whether that
    /// part was already there (then the first one is kept, as `put` must not overwrite).
    pub fn insert(
        &mut self,
        topic: &'static str,
        stamp: u64,
        put: impl FnOnce(&mut P) -> bool,
    ) -> Result<(), Refusal> {
        if let Some(last) = self.last_complete
            && stamp <= last
        {
            self.counts.stale += 1;
            return Err(Refusal::Stale { topic, stamp, last });
        }
        if put(self.pending.entry(stamp).or_default()) {
            self.counts.duplicate += 1;
            return Err(Refusal::Duplicate { topic, stamp });
        }
        Ok(())
    }

    /// The oldest step if it is complete. With `strict` false, a complete step also
    /// releases the incomplete ones older than it, which are dropped and counted: use it
    /// where the producer never starts a step before the previous one was answered (the
    /// babbler), not where older parts may still be in flight (the recorder).
    pub fn pop_complete(&mut self, strict: bool) -> Option<(u64, P)> {
        if !strict && let Some(stamp) = self.newest_complete() {
            let older: Vec<u64> = self.pending.range(..stamp).map(|(s, _)| *s).collect();
            for s in older {
                self.pending.remove(&s);
                self.counts.abandoned += 1;
            }
        }
        let entry = self.pending.first_entry()?;
        if !entry.get().is_complete() {
            return None;
        }
        let (stamp, parts) = entry.remove_entry();
        self.last_complete = Some(stamp);
        Some((stamp, parts))
    }

    /// The step at `stamp` if it is complete, wherever it is in the queue (for a reader
    /// that sorts the steps afterwards).
    pub fn take_if_complete(&mut self, stamp: u64) -> Option<P> {
        if !self.pending.get(&stamp)?.is_complete() {
            return None;
        }
        self.pending.remove(&stamp)
    }

    fn newest_complete(&self) -> Option<u64> {
        self.pending
            .iter()
            .rev()
            .find(|(_, p)| p.is_complete())
            .map(|(s, _)| *s)
    }

    /// The oldest incomplete step: its stamp and the topics it lacks.
    pub fn first_missing(&self) -> Option<(u64, Vec<&'static str>)> {
        self.pending.iter().next().map(|(s, p)| (*s, p.missing()))
    }

    /// Steps still waiting for parts.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// What was refused or dropped so far.
    pub fn counts(&self) -> JoinCounts {
        self.counts
    }

    /// The steps still waiting, oldest first (to report them when the run ends).
    pub fn into_pending(self) -> BTreeMap<u64, P> {
        self.pending
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::step_parts! {
        struct Two {
            a: u32 = "/a",
            b: u32 = "/b",
        }
    }

    fn put_a(v: u32) -> impl FnOnce(&mut Two) -> bool {
        move |p| fill(&mut p.a, v)
    }
    fn put_b(v: u32) -> impl FnOnce(&mut Two) -> bool {
        move |p| fill(&mut p.b, v)
    }

    #[test]
    fn steps_come_out_whole_and_in_stamp_order() {
        let mut j = StepJoiner::<Two>::new();
        j.insert("/b", 20, put_b(2)).unwrap();
        j.insert("/a", 10, put_a(1)).unwrap();
        j.insert("/a", 20, put_a(2)).unwrap();
        // Step 10 lacks /b: nothing comes out, although step 20 is complete.
        assert!(j.pop_complete(true).is_none());
        assert_eq!(j.first_missing(), Some((10, vec!["/b"])));
        j.insert("/b", 10, put_b(1)).unwrap();
        let first = j.pop_complete(true).unwrap();
        assert_eq!((first.0, first.1.a, first.1.b), (10, Some(1), Some(1)));
        assert_eq!(j.pop_complete(true).unwrap().0, 20);
        assert!(j.pop_complete(true).is_none());
    }

    #[test]
    fn a_duplicate_keeps_the_first_sample_and_is_counted() {
        let mut j = StepJoiner::<Two>::new();
        j.insert("/a", 10, put_a(1)).unwrap();
        let refused = j.insert("/a", 10, put_a(99)).unwrap_err();
        assert_eq!(
            refused,
            Refusal::Duplicate {
                topic: "/a",
                stamp: 10
            }
        );
        j.insert("/b", 10, put_b(1)).unwrap();
        assert_eq!(j.pop_complete(true).unwrap().1.a, Some(1));
        assert_eq!(j.counts().duplicate, 1);
    }

    #[test]
    fn a_stale_sample_is_refused_and_cannot_reopen_a_step() {
        let mut j = StepJoiner::<Two>::new();
        j.insert("/a", 10, put_a(1)).unwrap();
        j.insert("/b", 10, put_b(1)).unwrap();
        j.pop_complete(true).unwrap();
        for stamp in [10, 3] {
            let refused = j.insert("/a", stamp, put_a(5)).unwrap_err();
            assert!(
                matches!(refused, Refusal::Stale { last: 10, .. }),
                "{refused}"
            );
        }
        assert_eq!(j.pending(), 0);
        assert_eq!(j.counts().stale, 2);
    }

    #[test]
    fn lenient_popping_drops_an_orphan_that_would_block_the_queue() {
        // A stray sample at a stamp no step has: strict popping would wait forever.
        let mut j = StepJoiner::<Two>::new();
        j.insert("/a", 15, put_a(7)).unwrap();
        j.insert("/a", 20, put_a(2)).unwrap();
        j.insert("/b", 20, put_b(2)).unwrap();
        assert!(j.pop_complete(true).is_none());
        assert_eq!(j.pop_complete(false).unwrap().0, 20);
        assert_eq!(j.counts().abandoned, 1);
    }

    #[test]
    fn a_complete_step_can_be_taken_out_of_order() {
        let mut j = StepJoiner::<Two>::new();
        j.insert("/a", 10, put_a(1)).unwrap();
        j.insert("/a", 20, put_a(2)).unwrap();
        j.insert("/b", 20, put_b(2)).unwrap();
        assert!(j.take_if_complete(10).is_none());
        assert_eq!(j.take_if_complete(20).unwrap().a, Some(2));
        assert_eq!(
            j.into_pending().keys().copied().collect::<Vec<_>>(),
            vec![10]
        );
    }
}
