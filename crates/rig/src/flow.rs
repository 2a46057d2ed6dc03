//! The simulator's flow control: it never runs more than a window of steps ahead of the
//! recorder's acknowledgements, so a slow recorder slows the run instead of losing steps.

/// How far ahead of the last acknowledged step the simulator may publish.
#[derive(Debug, Clone)]
pub struct AckWindow {
    steps: u64,
    step_ns: f64,
    acked: Option<u64>,
    published: Option<u64>,
    refused: u64,
}

impl AckWindow {
    /// At most `steps` published steps unacknowledged, each `step_ns` of sim time long;
    /// nothing acknowledged yet.
    pub fn new(steps: u64, step_ns: f64) -> Self {
        Self {
            steps,
            step_ns,
            acked: None,
            published: None,
            refused: 0,
        }
    }

    /// The step stamped `stamp` has gone out.
    pub fn published(&mut self, stamp: u64) {
        self.published = Some(self.published.map_or(stamp, |p| p.max(stamp)));
    }

    /// A resumed run: the steps up to `stamp` are already in the bag.
    pub fn resume_after(&mut self, stamp: u64) {
        self.published(stamp);
        self.acked = Some(stamp);
    }

    /// The recorder has written every step up to `stamp` (acks may arrive out of order).
    /// An acknowledgement of a step not yet published cannot be the recorder's: it is
    /// refused and counted (a stray one would let the simulator run unboundedly ahead).
    /// Returns whether it was taken.
    pub fn ack(&mut self, stamp: u64) -> bool {
        if self.published.is_none_or(|p| stamp > p) {
            self.refused += 1;
            return false;
        }
        self.acked = Some(self.acked.map_or(stamp, |a| a.max(stamp)));
        true
    }

    /// Acknowledgements refused by [`AckWindow::ack`].
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// The last acknowledged stamp.
    pub fn acked(&self) -> Option<u64> {
        self.acked
    }

    /// Whether the step stamped `stamp` may be published now: it would leave at most
    /// `steps` steps unacknowledged (stamps start at 0 and are rounded to the ns, hence
    /// the half-step margin).
    pub fn allows(&self, stamp: u64) -> bool {
        let unacknowledged = match self.acked {
            Some(acked) => (stamp as f64 - acked as f64) / self.step_ns,
            None => stamp as f64 / self.step_ns + 1.0,
        };
        unacknowledged < self.steps as f64 + 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STEP: f64 = 41_666_666.7;

    fn stamp(k: u64) -> u64 {
        (k as f64 * STEP).round() as u64
    }

    #[test]
    fn the_first_window_goes_before_any_ack() {
        let w = AckWindow::new(4, STEP);
        assert!((0..4).all(|k| w.allows(stamp(k))));
        assert!(!w.allows(stamp(4)));
    }

    #[test]
    fn an_ack_moves_the_window_and_old_acks_do_not_move_it_back() {
        let mut w = AckWindow::new(4, STEP);
        w.published(stamp(10));
        w.ack(stamp(10));
        assert!(w.allows(stamp(14)));
        assert!(!w.allows(stamp(15)));
        w.ack(stamp(3));
        assert_eq!(w.acked(), Some(stamp(10)));
        assert!(!w.allows(stamp(15)));
    }

    #[test]
    fn a_window_of_one_is_lock_step_with_the_recorder() {
        let mut w = AckWindow::new(1, STEP);
        assert!(w.allows(stamp(0)));
        assert!(!w.allows(stamp(1)));
        w.published(stamp(0));
        w.ack(stamp(0));
        assert!(w.allows(stamp(1)));
        assert!(!w.allows(stamp(2)));
    }

    #[test]
    fn an_ack_of_a_step_not_yet_published_is_refused_and_counted() {
        let mut w = AckWindow::new(4, STEP);
        assert!(!w.ack(stamp(0)), "nothing published yet");
        w.published(stamp(5));
        assert!(!w.ack(stamp(1_000)));
        assert_eq!(w.acked(), None);
        assert!(!w.allows(stamp(9)));
        assert!(w.ack(stamp(5)));
        assert!(w.allows(stamp(9)));
        assert_eq!(w.refused(), 2);
    }

    #[test]
    fn a_resumed_window_starts_after_the_kept_steps() {
        let mut w = AckWindow::new(4, STEP);
        w.resume_after(stamp(99));
        assert!(w.allows(stamp(103)));
        assert!(!w.allows(stamp(104)));
        assert!(w.ack(stamp(99)));
    }
}
