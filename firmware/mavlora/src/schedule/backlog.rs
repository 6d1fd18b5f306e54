//! What the radio holds and has not sent yet, estimated: bytes handed to it, drained at the
//! budget's rate (below the radio's real rate, so the estimate errs high). A frame leaves
//! the scheduler only while that estimate is under a limit, so a backlog waits in the
//! scheduler, where commands overtake, samples are replaced and compact frames merge, and
//! not in the radio's buffer, where nothing overtakes: on LoRa SF7 a 280-byte burst is half a
//! second on air, and a mode change queued behind it reached the ground 0.9 s late (issue 21).
//!
//! Unlike the token bucket's burst, the limit may be below one largest frame: a frame goes
//! whenever the estimate is under the limit, whatever its length, so over any window `w` at
//! most `rate * w + limit + one frame` bytes leave.

use crate::time::{Duration, Instant};

const MICRO: u64 = 1_000_000;

/// The binaries' limit (`--radio-backlog-ms`): with a change of mode queued behind it and
/// LoRa SF7's air time for the change's own frame, the ground sees the change within ~0.5 s.
pub const DEFAULT_RADIO_BACKLOG: Duration = Duration::from_millis(200);

/// Estimated bytes in the radio not yet on air.
#[derive(Debug, Clone)]
pub struct RadioBacklog {
    rate: u64,
    limit_micro: u64,
    level_micro: u64,
    last: Instant,
}

impl RadioBacklog {
    /// A radio draining `rate` bytes per second, holding at most `limit` of them (as time at
    /// that rate) before the next frame may be handed to it; empty at `now`.
    pub fn new(rate_bytes_per_s: u32, limit: Duration, now: Instant) -> Self {
        let rate = u64::from(rate_bytes_per_s);
        Self {
            rate,
            limit_micro: rate.saturating_mul(limit.as_micros()),
            level_micro: 0,
            last: now,
        }
    }

    /// Drains at a new rate from the last update on (the radio's buffer report moved the
    /// budget); the limit, in bytes, stays.
    pub fn set_rate(&mut self, rate_bytes_per_s: u32) {
        self.rate = rate_bytes_per_s.into();
    }

    fn drain(&mut self, now: Instant) {
        let elapsed = now.as_micros().saturating_sub(self.last.as_micros());
        self.level_micro = self
            .level_micro
            .saturating_sub(elapsed.saturating_mul(self.rate));
        self.last = self.last.max(now);
    }

    /// Whether a frame may be handed to the radio at `now`.
    pub fn admits(&mut self, now: Instant) -> bool {
        self.drain(now);
        self.level_micro <= self.limit_micro
    }

    /// A frame of `bytes` was handed to the radio.
    pub fn add(&mut self, bytes: usize) {
        self.level_micro = self
            .level_micro
            .saturating_add((bytes as u64).saturating_mul(MICRO));
    }

    /// Earliest time a frame may be handed to the radio (the last update or later), `None`
    /// if never (zero rate with a level above the limit). Does not drain.
    pub fn ready_at(&self) -> Option<Instant> {
        if self.level_micro <= self.limit_micro {
            return Some(self.last);
        }
        if self.rate == 0 {
            return None;
        }
        let over = self.level_micro - self.limit_micro;
        Some(Instant::from_micros(
            self.last.as_micros() + over.div_ceil(self.rate),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_larger_than_the_limit_goes_into_an_empty_radio_and_the_next_waits_for_it() {
        // 250 B/s, 0.2 s: 50 bytes
        let mut b = RadioBacklog::new(250, Duration::from_millis(200), Instant::ZERO);
        assert!(b.admits(Instant::ZERO));
        b.add(200);
        assert!(!b.admits(Instant::ZERO));
        // 150 bytes over the limit drain in 0.6 s
        assert_eq!(
            b.ready_at(),
            Some(Instant::from_millis(0) + Duration::from_millis(600))
        );
        assert!(!b.admits(Instant::from_millis(599)));
        assert!(b.admits(Instant::from_millis(600)));
    }

    #[test]
    fn small_frames_go_until_the_estimate_passes_the_limit() {
        let mut b = RadioBacklog::new(100, Duration::from_millis(500), Instant::ZERO);
        let mut sent = 0;
        while b.admits(Instant::ZERO) {
            b.add(20);
            sent += 20;
        }
        // the limit (50 bytes) plus the frame that crossed it
        assert_eq!(sent, 60);
        // a long pause empties it, and no credit builds up beyond empty
        assert!(b.admits(Instant::from_millis(60_000)));
        b.add(60);
        assert!(!b.admits(Instant::from_millis(60_000)));
    }

    #[test]
    fn a_slower_rate_drains_slower() {
        let mut b = RadioBacklog::new(100, Duration::ZERO, Instant::ZERO);
        b.add(10);
        b.set_rate(50);
        assert!(!b.admits(Instant::from_millis(100)));
        assert!(b.admits(Instant::from_millis(200)));
    }
}
