//! Tail-loss probe of a reliable Writer: recovery of a lost last sample within
//! a few round trips instead of a heartbeat period.
//!
//! A Reader notices a lost sample only when a later DATA or HEARTBEAT names a
//! higher sequence number. When the lost sample is the last one the Writer has
//! sent for now (a request-reply or lock-step exchange: the peer waits for it
//! before anything else is written), nothing names it until the periodic
//! HEARTBEAT, 100 ms to 1 s later. On loopback a round trip is tens of
//! microseconds, so one lost datagram in a lock-step costs thousands of round
//! trips.
//!
//! The probe follows TCP's tail loss probe (RFC 8985, section 7): once the
//! Writer has been quiet for a probe timeout while some reader still has
//! unacknowledged samples, it sends a HEARTBEAT asking for an ACKNACK. The
//! timeout adapts to the measured acknowledgement round trip (RFC 6298's
//! smoothed RTT and variance), is doubled on each unanswered probe, and probing
//! stops at the fast heartbeat period, where the periodic HEARTBEAT takes over.
//! A Writer that keeps writing never probes, and costs no wake-up: each write
//! moves the probe's deadline (`Timer::move_timeout`), so the timer fires only
//! once the Writer has been quiet for the timeout; and each sample's piggybacked
//! HEARTBEAT names the ones before it.
//!
//! Readers acknowledge only when asked, so a Writer cannot tell a lost tail
//! from a peer that is merely slow to answer (a descheduled process on a
//! loaded machine): on a quiet loopback most probes at the round-trip timeout
//! found every reader holding everything, and cost 3 % of a lock-step's rate.
//! The timeout's floor is therefore learned from the probes' outcomes, as
//! TCP's response to a spurious retransmission timeout does (RFC 4015): a
//! probing episode that ends with the next write and no sample asked for was
//! spurious and raises the floor by a quarter (up to `TAIL_PROBE_FLOOR_MAX`),
//! unless a reader asked for a sample within `LOSS_MEMORY`; any ACKNACK that
//! asks for a sample brings it back to `TAIL_PROBE_MIN`. The floor
//! belongs to the path, not to one Writer: a loss hits one of a lock-step's
//! writers at a time while the others' probes in the same pause are spurious,
//! so a per-writer floor rose on a lossy path too (5 % loss: 12 % of the
//! loss-free rate instead of 36 %). Every Writer of a participant runs on its
//! event-loop thread, so the floor is kept per thread.

use std::{
  cell::Cell,
  time::{Duration, Instant},
};

use crate::structure::sequence_number::SequenceNumber;

/// Shortest probe timeout: a reader's event loop may take this long to wake on
/// a loaded machine, and a probe sent earlier only adds a datagram each way.
pub(crate) const TAIL_PROBE_MIN: Duration = Duration::from_micros(500);
/// Probe timeout until a first round trip is measured.
pub(crate) const TAIL_PROBE_INITIAL: Duration = Duration::from_millis(5);
/// Highest floor spurious probes can raise the timeout to: a lost tail then
/// still costs a few milliseconds, not a heartbeat period.
pub(crate) const TAIL_PROBE_FLOOR_MAX: Duration = Duration::from_millis(8);

thread_local! {
  /// Shortest probe timeout of the Writers on this (event-loop) thread,
  /// learned from the outcomes of their probes.
  static PATH_FLOOR: Cell<Duration> = const { Cell::new(TAIL_PROBE_MIN) };
  /// When a reader of one of them last asked for a sample.
  static LAST_LOSS: Cell<Option<Instant>> = const { Cell::new(None) };
}

/// How long after a reader asked for a sample spurious probes leave the floor
/// alone: the other writers' probes in the pause of a loss are spurious too.
const LOSS_MEMORY: Duration = Duration::from_millis(100);

/// What the Writer does when its probe timer fires.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum ProbeAction {
  /// Send a HEARTBEAT asking for an ACKNACK, and fire again after the delay.
  Probe { next: Duration },
  /// Nothing to probe for (all acknowledged, or probing gave way to the
  /// periodic HEARTBEAT): the timer is not set again until the next write.
  Stop,
}

/// Round-trip estimate and probe state of one Writer.
#[derive(Debug)]
pub(crate) struct TailProbe {
  srtt: Option<Duration>,
  rttvar: Duration,
  backoff: u32,
  /// An ACKNACK request in flight, whose answer times a round trip: when it
  /// was sent and the last sequence number it asked about.
  ack_request: Option<(Instant, SequenceNumber)>,
  /// Probing stops once the timeout would exceed this (the fast heartbeat).
  give_up_after: Duration,
  /// Since the last write: a probe went out, and an answer asked for a sample.
  probed: bool,
  found_loss: bool,
}

impl TailProbe {
  pub(crate) fn new(give_up_after: Duration) -> Self {
    Self {
      srtt: None,
      rttvar: Duration::ZERO,
      backoff: 0,
      ack_request: None,
      give_up_after,
      probed: false,
      found_loss: false,
    }
  }

  /// The probe timeout before backoff: srtt + 4 rttvar (RFC 6298), at least
  /// the learned floor.
  pub(crate) fn timeout(&self) -> Duration {
    match self.srtt {
      Some(srtt) => (srtt + 4 * self.rttvar).max(self.floor()),
      None => TAIL_PROBE_INITIAL.max(self.floor()),
    }
  }

  /// The path's floor, below half the heartbeat period.
  fn floor(&self) -> Duration {
    PATH_FLOOR.with(Cell::get).min(self.give_up_after / 2)
  }

  fn backed_off(&self) -> Duration {
    self.timeout().saturating_mul(1 << self.backoff.min(16))
  }

  /// Samples went out: the delay to move the probe timer to. A probing
  /// episode ends here, and its outcome moves the floor.
  pub(crate) fn on_write(&mut self) -> Duration {
    let loss_is_recent = LAST_LOSS.with(|at| at.get().is_some_and(|at| at.elapsed() < LOSS_MEMORY));
    if self.probed && !self.found_loss && !loss_is_recent {
      PATH_FLOOR.with(|floor| floor.set((floor.get() * 5 / 4).min(TAIL_PROBE_FLOOR_MAX)));
    }
    self.probed = false;
    self.found_loss = false;
    self.backoff = 0;
    self.timeout()
  }

  /// A HEARTBEAT asking for an ACKNACK about samples up to `last` went out.
  /// It supersedes a request still unanswered: that one or its answer may have
  /// been lost, and timing an answer from it would count the loss as round
  /// trip (Karn's rule: time only what is unambiguous). Counted, those losses
  /// inflated the timeout past the fast heartbeat at 20 % loss, and probing
  /// stopped: 3 steps/s instead of 300.
  pub(crate) fn on_ack_request(&mut self, now: Instant, last: SequenceNumber) {
    self.ack_request = Some((now, last));
  }

  /// A reader acknowledged every sample before `acked_before`, and asked for
  /// samples if `requested`: a round-trip sample if that answers the request
  /// in flight. Progress also resets the backoff.
  pub(crate) fn on_ack(&mut self, now: Instant, acked_before: SequenceNumber, requested: bool) {
    if requested {
      // The path loses datagrams: probe at the round trip again.
      self.found_loss = self.probed;
      PATH_FLOOR.with(|floor| floor.set(TAIL_PROBE_MIN));
      LAST_LOSS.with(|at| at.set(Some(now)));
    }
    let Some((sent, last)) = self.ack_request else {
      return;
    };
    if acked_before <= last {
      return;
    }
    self.ack_request = None;
    self.backoff = 0;
    let sample = now.saturating_duration_since(sent);
    if sample > self.give_up_after {
      // Past the periodic HEARTBEAT: the answer came by another route than
      // this request (which was lost), not a round trip.
      return;
    }
    match self.srtt {
      None => {
        self.srtt = Some(sample);
        self.rttvar = sample / 2;
      }
      Some(srtt) => {
        let deviation = if srtt > sample { srtt - sample } else { sample - srtt };
        self.rttvar = (self.rttvar * 3 + deviation) / 4;
        self.srtt = Some((srtt * 7 + sample) / 8);
      }
    }
  }

  /// A probe went out since the last write: an ACKNACK now answers it, and the
  /// repair it asks for is the tail the peer waits for, not to be delayed.
  pub(crate) fn probing(&self) -> bool {
    self.backoff > 0
  }

  /// The probe timer fired: the Writer has been quiet for the (backed-off)
  /// timeout. `readers_behind` tells whether some reader has not acknowledged
  /// everything sent.
  pub(crate) fn on_fire(&mut self, readers_behind: bool) -> ProbeAction {
    if !readers_behind {
      self.backoff = 0;
      return ProbeAction::Stop;
    }
    if self.backed_off() > self.give_up_after {
      return ProbeAction::Stop;
    }
    // A probe whose answer was lost must not time the next one's.
    self.ack_request = None;
    self.backoff += 1;
    self.probed = true;
    ProbeAction::Probe {
      next: self.backed_off(),
    }
  }
}

#[cfg(test)]
mod tests {
  use super::*;

  const GIVE_UP: Duration = Duration::from_millis(100);

  fn sn(n: i64) -> SequenceNumber {
    SequenceNumber::new(n)
  }

  fn measured(rtt: Duration) -> (TailProbe, Instant) {
    PATH_FLOOR.with(|floor| floor.set(TAIL_PROBE_MIN));
    LAST_LOSS.with(|at| at.set(None));
    let mut probe = TailProbe::new(GIVE_UP);
    let t0 = Instant::now();
    for i in 0..20 {
      let at = t0 + Duration::from_millis(i * 10);
      probe.on_ack_request(at, sn(i as i64 + 1));
      probe.on_ack(at + rtt, sn(i as i64 + 2), false);
    }
    (probe, t0 + Duration::from_secs(1))
  }

  #[test]
  fn the_timeout_follows_the_measured_round_trip() {
    let (probe, _) = measured(Duration::from_millis(2));
    let timeout = probe.timeout();
    assert!(
      timeout >= Duration::from_millis(2) && timeout < Duration::from_micros(2600),
      "{timeout:?}"
    );
    // Loopback: tens of microseconds, clamped to the minimum.
    let (fast, _) = measured(Duration::from_micros(40));
    assert_eq!(fast.timeout(), TAIL_PROBE_MIN);
    assert_eq!(TailProbe::new(GIVE_UP).timeout(), TAIL_PROBE_INITIAL);
  }

  #[test]
  fn an_ack_of_less_than_was_asked_is_no_round_trip_sample() {
    let mut probe = TailProbe::new(GIVE_UP);
    let t0 = Instant::now();
    probe.on_ack_request(t0, sn(5));
    probe.on_ack(t0 + Duration::from_millis(50), sn(5), false); // 5 itself not yet acknowledged
    assert_eq!(probe.timeout(), TAIL_PROBE_INITIAL);
    probe.on_ack(t0 + Duration::from_millis(1), sn(6), false);
    assert!(probe.timeout() >= Duration::from_millis(1));
  }

  #[test]
  fn a_request_superseded_before_its_answer_is_not_timed() {
    // The first request (or its answer) was lost; the answer to the second
    // comes 40 us after it, 50 ms after the first.
    let mut probe = TailProbe::new(GIVE_UP);
    let t0 = Instant::now();
    probe.on_ack_request(t0, sn(5));
    probe.on_ack_request(t0 + Duration::from_millis(50), sn(6));
    probe.on_ack(t0 + Duration::from_micros(50_040), sn(7), false);
    assert_eq!(probe.timeout(), TAIL_PROBE_MIN, "timed from the second request");
  }

  #[test]
  fn an_answer_slower_than_the_heartbeat_period_is_no_round_trip_sample() {
    let mut probe = TailProbe::new(GIVE_UP);
    let t0 = Instant::now();
    probe.on_ack_request(t0, sn(5));
    probe.on_ack(t0 + GIVE_UP + Duration::from_millis(1), sn(6), false);
    assert_eq!(probe.timeout(), TAIL_PROBE_INITIAL, "no sample taken");
  }

  #[test]
  fn a_quiet_writer_with_readers_behind_probes_and_backs_off_until_the_heartbeat_takes_over() {
    let (mut probe, _) = measured(Duration::from_micros(40));
    assert_eq!(probe.on_write(), TAIL_PROBE_MIN);
    let mut sent = 0;
    while let ProbeAction::Probe { next } = probe.on_fire(true) {
      sent += 1;
      assert_eq!(next, TAIL_PROBE_MIN * (1 << sent));
    }
    // 0.5, 1, 2, ... 64 ms: 8 probes before the 100 ms heartbeat takes over.
    assert_eq!(sent, 8);
    assert!(probe.probing());
    // No answer asked for a sample: the episode was spurious.
    assert_eq!(probe.on_write(), TAIL_PROBE_MIN * 5 / 4, "a new write starts over");
    assert!(!probe.probing());
  }

  // Probes answered with nothing missing (a slow peer, not a lost tail) raise
  // the floor, up to its maximum; one answer that asks for a sample lowers it.
  #[test]
  fn spurious_probes_raise_the_floor_and_a_found_loss_lowers_it() {
    let (mut probe, now) = measured(Duration::from_micros(40));
    let mut timeouts = vec![probe.on_write()];
    for k in 0..14 {
      assert!(matches!(probe.on_fire(true), ProbeAction::Probe { .. }));
      let answered = now + Duration::from_millis(k);
      probe.on_ack_request(answered, sn(100 + k as i64));
      probe.on_ack(answered + Duration::from_micros(40), sn(101 + k as i64), false);
      timeouts.push(probe.on_write());
    }
    let us = |us: u64| Duration::from_micros(us);
    let ns = |ns: u64| Duration::from_nanos(ns);
    assert_eq!(timeouts[..4], [us(500), us(625), ns(781_250), ns(976_562)]);
    assert!(timeouts.windows(2).all(|w| w[1] >= w[0]));
    assert_eq!(timeouts[13..], [TAIL_PROBE_FLOOR_MAX, TAIL_PROBE_FLOOR_MAX]);

    assert!(matches!(probe.on_fire(true), ProbeAction::Probe { .. }));
    probe.on_ack(now + Duration::from_millis(20), sn(115), true);
    assert_eq!(probe.on_write(), TAIL_PROBE_MIN, "a found loss brings the floor back down");
    assert_eq!(probe.on_write(), TAIL_PROBE_MIN, "a write without a probe changes nothing");
    // Right after a loss, the probes of the same pause are not taken as spurious.
    probe.on_fire(true);
    assert_eq!(probe.on_write(), TAIL_PROBE_MIN);
    LAST_LOSS.with(|at| at.set(Some(Instant::now() - LOSS_MEMORY)));
    probe.on_fire(true);
    assert_eq!(probe.on_write(), TAIL_PROBE_MIN * 5 / 4, "a loss long ago does not");
  }

  // The floor is the path's: another Writer's spurious probes raise it for
  // this one, and its found loss lowers it for them.
  #[test]
  fn the_writers_of_a_participant_share_the_floor() {
    let (mut a, _) = measured(Duration::from_micros(40));
    let mut b = TailProbe::new(GIVE_UP);
    b.on_ack_request(Instant::now(), sn(1));
    b.on_ack(Instant::now(), sn(2), false);
    for _ in 0..4 {
      a.on_fire(true);
      a.on_write();
    }
    assert!(b.timeout() > Duration::from_millis(1), "{:?}", b.timeout());
    b.on_fire(true);
    b.on_ack(Instant::now(), sn(2), true);
    b.on_write();
    assert_eq!(a.timeout(), TAIL_PROBE_MIN);
  }

  #[test]
  fn the_floor_stays_below_the_heartbeat() {
    PATH_FLOOR.with(|floor| floor.set(TAIL_PROBE_FLOOR_MAX));
    let probe = TailProbe::new(Duration::from_millis(6));
    assert_eq!(probe.floor(), Duration::from_millis(3), "half the heartbeat");
  }

  #[test]
  fn nothing_is_probed_once_everything_is_acknowledged() {
    let mut probe = TailProbe::new(GIVE_UP);
    probe.on_write();
    assert_eq!(probe.on_fire(false), ProbeAction::Stop);
  }

  #[test]
  fn an_answered_probe_resets_the_backoff() {
    let (mut probe, now) = measured(Duration::from_micros(40));
    probe.on_write();
    assert!(!probe.probing());
    assert!(matches!(probe.on_fire(true), ProbeAction::Probe { .. }));
    assert!(probe.probing());
    probe.on_ack_request(now, sn(100));
    probe.on_ack(now + Duration::from_micros(50), sn(101), false);
    assert!(matches!(
      probe.on_fire(true),
      ProbeAction::Probe { next } if next == TAIL_PROBE_MIN * 2
    ));
  }
}
