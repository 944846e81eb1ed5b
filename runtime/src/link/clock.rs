//! The host's estimate of the hand's clock, for deadlines the hand checks.

use crate::protocol::HandTime;
use std::collections::VecDeque;
use std::time::Instant;

/// How many recent ACKs the clock estimate looks at (3 s of heartbeats at
/// the default interval): recent enough that clock drift (tens of ppm) is
/// negligible, enough that one ACK sent without delay is among them.
const CLOCK_SAMPLES: usize = 16;

/// The host's estimate of the hand's clock, from the hand time stamped in
/// each ACK. An ACK stamped `h` (whole milliseconds, rounded down) and
/// received at host time `r` bounds the offset (hand minus host) from
/// below, by the ACK's travel time. The largest recent bound is the
/// estimate, so a host instant converted with it lands at or before the
/// true hand time: a deadline on the hand's clock can only come early.
#[derive(Debug)]
pub struct HandClock {
    epoch: Instant,
    /// The last sample's raw and unwrapped hand time (ms).
    last: Option<(u32, i64)>,
    /// Offsets, hand minus host, in microseconds.
    offsets_us: VecDeque<i64>,
}

impl HandClock {
    pub fn new() -> Self {
        HandClock {
            epoch: Instant::now(),
            last: None,
            offsets_us: VecDeque::with_capacity(CLOCK_SAMPLES),
        }
    }

    /// Forgets the samples (a new session may be another hand).
    pub fn reset(&mut self) {
        self.last = None;
        self.offsets_us.clear();
    }

    fn host_us(&self, t: Instant) -> i64 {
        match t.checked_duration_since(self.epoch) {
            Some(d) => d.as_micros() as i64,
            None => -(self.epoch.duration_since(t).as_micros() as i64),
        }
    }

    /// Records an ACK stamped `hand` and received at `received`.
    pub fn observe(&mut self, hand: HandTime, received: Instant) {
        // Unwrapped across the 32-bit wrap of the hand's clock.
        let unwrapped = match self.last {
            None => i64::from(hand.0),
            Some((raw, prev)) => prev + hand.since(HandTime(raw)),
        };
        self.last = Some((hand.0, unwrapped));
        if self.offsets_us.len() == CLOCK_SAMPLES {
            self.offsets_us.pop_front();
        }
        self.offsets_us
            .push_back(unwrapped * 1000 - self.host_us(received));
    }

    /// The hand time at host instant `t` (at or before the true one);
    /// `None` before any sample.
    pub fn to_hand(&self, t: Instant) -> Option<HandTime> {
        let offset = *self.offsets_us.iter().max()?;
        let ms = (self.host_us(t) + offset).div_euclid(1000);
        // Reduced modulo 2^32: the hand's clock wraps.
        Some(HandTime(ms.rem_euclid(1 << 32) as u32))
    }
}

impl Default for HandClock {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// A hand whose clock reads `hand_zero_ms` at the host clock's epoch.
    fn sample(clock: &mut HandClock, hand_zero_ms: u32, sent_ms: u64, travel_us: u64) {
        let stamped = HandTime(hand_zero_ms.wrapping_add(sent_ms as u32));
        let received =
            clock.epoch + Duration::from_millis(sent_ms) + Duration::from_micros(travel_us);
        clock.observe(stamped, received);
    }

    #[test]
    fn the_estimate_never_runs_ahead_of_the_hand() {
        let mut clock = HandClock::new();
        assert_eq!(clock.to_hand(clock.epoch), None, "no sample yet");
        // ACKs sent at whole hand milliseconds, delayed 0.3 to 80 ms.
        for (i, travel_us) in [80_000, 300, 5_000, 40_000].iter().enumerate() {
            sample(&mut clock, 1_000, 100 * i as u64, *travel_us);
        }
        for at_ms in [0, 250, 10_000] {
            let t = clock.epoch + Duration::from_millis(at_ms);
            let estimate = clock.to_hand(t).unwrap();
            let truth = HandTime(1_000 + at_ms as u32);
            assert!(!truth.is_before(estimate), "{estimate:?} after {truth:?}");
            // The quickest ACK (0.3 ms) makes it good to a millisecond.
            assert!(truth.since(estimate) <= 1, "{estimate:?} vs {truth:?}");
        }
    }

    #[test]
    fn the_estimate_follows_the_hand_clock_across_its_wrap() {
        let mut clock = HandClock::new();
        let zero = u32::MAX - 150; // wraps 150 ms after the host's epoch
        for i in 0..6 {
            sample(&mut clock, zero, 100 * i, 200);
        }
        let t = clock.epoch + Duration::from_millis(700);
        let truth = HandTime(zero.wrapping_add(700));
        assert_eq!(truth, HandTime(549), "past the wrap");
        // The 0.2 ms travel time rounds the estimate a millisecond early.
        assert_eq!(clock.to_hand(t), Some(HandTime(548)));
    }

    #[test]
    fn a_new_session_forgets_the_old_hand() {
        let mut clock = HandClock::new();
        sample(&mut clock, 50_000, 0, 100);
        clock.reset();
        sample(&mut clock, 7, 10, 100);
        let t = clock.epoch + Duration::from_millis(20);
        // The new hand reads 27 then; the 0.1 ms travel time rounds down.
        assert_eq!(clock.to_hand(t), Some(HandTime(26)));
    }
}
