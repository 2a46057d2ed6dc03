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

use std::time::{Duration, Instant};

use crate::structure::sequence_number::SequenceNumber;

/// Shortest probe timeout: a reader's event loop may take this long to wake on
/// a loaded machine, and a probe sent earlier only adds a datagram each way.
pub(crate) const TAIL_PROBE_MIN: Duration = Duration::from_micros(500);
/// Probe timeout until a first round trip is measured.
pub(crate) const TAIL_PROBE_INITIAL: Duration = Duration::from_millis(5);

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
}

impl TailProbe {
  pub(crate) fn new(give_up_after: Duration) -> Self {
    Self {
      srtt: None,
      rttvar: Duration::ZERO,
      backoff: 0,
      ack_request: None,
      give_up_after,
    }
  }

  /// The probe timeout before backoff: srtt + 4 rttvar (RFC 6298), at least
  /// `TAIL_PROBE_MIN`.
  pub(crate) fn timeout(&self) -> Duration {
    match self.srtt {
      Some(srtt) => (srtt + 4 * self.rttvar).max(TAIL_PROBE_MIN),
      None => TAIL_PROBE_INITIAL,
    }
  }

  fn backed_off(&self) -> Duration {
    self.timeout().saturating_mul(1 << self.backoff.min(16))
  }

  /// Samples went out: the delay to move the probe timer to.
  pub(crate) fn on_write(&mut self) -> Duration {
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

  /// A reader acknowledged every sample before `acked_before`: a round-trip
  /// sample if that answers the request in flight. Progress also resets the
  /// backoff.
  pub(crate) fn on_ack(&mut self, now: Instant, acked_before: SequenceNumber) {
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
    let mut probe = TailProbe::new(GIVE_UP);
    let t0 = Instant::now();
    for i in 0..20 {
      let at = t0 + Duration::from_millis(i * 10);
      probe.on_ack_request(at, sn(i as i64 + 1));
      probe.on_ack(at + rtt, sn(i as i64 + 2));
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
    probe.on_ack(t0 + Duration::from_millis(50), sn(5)); // 5 itself not yet acknowledged
    assert_eq!(probe.timeout(), TAIL_PROBE_INITIAL);
    probe.on_ack(t0 + Duration::from_millis(1), sn(6));
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
    probe.on_ack(t0 + Duration::from_micros(50_040), sn(7));
    assert_eq!(probe.timeout(), TAIL_PROBE_MIN, "timed from the second request");
  }

  #[test]
  fn an_answer_slower_than_the_heartbeat_period_is_no_round_trip_sample() {
    let mut probe = TailProbe::new(GIVE_UP);
    let t0 = Instant::now();
    probe.on_ack_request(t0, sn(5));
    probe.on_ack(t0 + GIVE_UP + Duration::from_millis(1), sn(6));
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
    assert_eq!(probe.on_write(), TAIL_PROBE_MIN, "a new write starts over");
    assert!(!probe.probing());
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
    probe.on_ack(now + Duration::from_micros(50), sn(101));
    assert!(matches!(
      probe.on_fire(true),
      ProbeAction::Probe { next } if next == TAIL_PROBE_MIN * 2
    ));
  }
}
