//! The simulator's flow control: it never runs more than a window of steps ahead of the
//! recorder's acknowledgements, so a slow recorder slows the run instead of losing steps.

/// How far ahead of the last acknowledged step the simulator may publish.
#[derive(Debug, Clone)]
pub struct AckWindow {
    steps: u64,
    step_ns: f64,
    acked: Option<u64>,
}

impl AckWindow {
    /// At most `steps` published steps unacknowledged, each `step_ns` of sim time long;
    /// nothing acknowledged yet.
    pub fn new(steps: u64, step_ns: f64) -> Self {
        Self {
            steps,
            step_ns,
            acked: None,
        }
    }

    /// The recorder has written every step up to `stamp` (acks may arrive out of order).
    pub fn ack(&mut self, stamp: u64) {
        self.acked = Some(self.acked.map_or(stamp, |a| a.max(stamp)));
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
        w.ack(stamp(0));
        assert!(w.allows(stamp(1)));
        assert!(!w.allows(stamp(2)));
    }
}
