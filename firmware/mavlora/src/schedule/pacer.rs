//! Pacing the radio budget by the radio's own word: a SiK radio (and RFD900, mLRS) reports
//! the free share of its transmit buffer (`txbuf` in `RADIO_STATUS`) about once a second.
//! A configured rate is the radio's nominal one; its real throughput can be half of it
//! (ECC on, a busy channel, a lower air rate than configured), and then whatever the budget
//! offers above it fills the radio's buffer until the radio drops bytes, whole frames lost
//! where nobody counts them.
//!
//! [`TxbufPacer`] is additive increase, multiplicative decrease on that report, with the
//! thresholds ArduPilot paces its streams by (`GCS_MAVLINK::handle_radio_status`): below 20 %
//! free it halves the rate, below 50 % it takes a quarter off, above 95 % it adds 1/16 of the
//! configured rate and above 90 % 1/64; in between it holds. The configured rate stays the
//! ceiling. The start is slow: half the configured rate until the radio's first report, so
//! the burst of a start (an autopilot streaming at full rate at once) does not overflow a
//! radio at half its nominal throughput before it has said anything (measured: 306 bytes
//! dropped in the first seconds without it). A radio that has reported nothing after
//! [`PROBATION`] reports nothing: the configured rate stands from then on.

use crate::time::{Duration, Instant};

/// How long the pacer waits for a first report at half rate: SiK reports after each
/// HEARTBEAT its host sends, about once a second.
pub const PROBATION: Duration = Duration::from_secs(3);

/// The budget's rate, paced by the radio's free transmit buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TxbufPacer {
    ceiling: u32,
    floor: u32,
    rate: u32,
    /// Until when the slow start waits for a first report; `None` once it came or the
    /// wait is over.
    probation: Option<Instant>,
    reports: u64,
}

/// The least the pacer goes down to, as a share of the configured rate: a sixteenth still
/// carries commands and acks, and a radio whose buffer stays full below it is broken.
const FLOOR_DIVISOR: u32 = 16;

impl TxbufPacer {
    /// Paces a budget configured at `ceiling` bytes per second, from `now`: half of it until
    /// the radio's first report or [`PROBATION`].
    pub fn new(ceiling: u32, now: Instant) -> Self {
        let floor = (ceiling / FLOOR_DIVISOR).max(1);
        Self {
            ceiling,
            floor,
            rate: (ceiling / 2).max(floor),
            probation: Some(now + PROBATION),
            reports: 0,
        }
    }

    /// The rate the budget should run at now, bytes per second.
    pub fn rate(&self) -> u32 {
        self.rate
    }

    /// Ends the slow start of a radio that said nothing for [`PROBATION`]; returns the
    /// configured rate then.
    pub fn poll(&mut self, now: Instant) -> Option<u32> {
        match self.probation {
            Some(until) if now >= until => {
                self.probation = None;
                self.rate = self.ceiling;
                Some(self.ceiling)
            }
            _ => None,
        }
    }

    /// Reports taken.
    pub fn reports(&self) -> u64 {
        self.reports
    }

    /// The radio reported `txbuf_pct` % of its transmit buffer free; returns the new rate
    /// when it changed.
    pub fn handle_txbuf(&mut self, txbuf_pct: u8) -> Option<u32> {
        self.reports += 1;
        self.probation = None;
        let rate = self.rate;
        let next = match txbuf_pct {
            0..20 => rate / 2,
            20..50 => rate - rate / 4,
            91..=95 => rate.saturating_add(self.ceiling / 64),
            96.. => rate.saturating_add(self.ceiling / 16),
            _ => rate,
        }
        .clamp(self.floor, self.ceiling);
        self.rate = next;
        (next != rate).then_some(next)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T0: Instant = Instant::ZERO;

    #[test]
    fn a_radio_that_says_nothing_gets_half_for_the_probation_then_the_configured_rate() {
        let mut p = TxbufPacer::new(4000, T0);
        assert_eq!(p.rate(), 2000);
        assert_eq!(p.poll(T0 + Duration::from_millis(2999)), None);
        assert_eq!(p.poll(T0 + PROBATION), Some(4000));
        assert_eq!(p.poll(T0 + PROBATION * 2), None);
    }

    #[test]
    fn a_free_buffer_climbs_from_the_slow_start_to_the_ceiling_and_no_further() {
        let mut p = TxbufPacer::new(4000, T0);
        assert_eq!(p.handle_txbuf(100), Some(2250));
        let mut reports = 1;
        while p.rate() < 4000 {
            p.handle_txbuf(100);
            reports += 1;
        }
        assert_eq!(
            reports, 8,
            "half to full in 1/16 steps: 8 reports (about 8 s)"
        );
        assert_eq!(p.handle_txbuf(100), None, "never above the ceiling");
        assert_eq!(p.poll(T0 + PROBATION), None, "a report ended the probation");
    }

    #[test]
    fn a_filling_buffer_cuts_the_rate_harder_the_fuller_it_is() {
        let mut p = TxbufPacer::new(4000, T0);
        assert_eq!(p.handle_txbuf(70), None, "held");
        assert_eq!(p.handle_txbuf(40), Some(1500));
        assert_eq!(p.handle_txbuf(10), Some(750));
        for _ in 0..10 {
            p.handle_txbuf(0);
        }
        assert_eq!(p.rate(), 250, "the floor: a sixteenth");
    }

    #[test]
    fn a_nearly_free_buffer_creeps_up_slowly() {
        let mut p = TxbufPacer::new(6400, T0);
        assert_eq!(p.handle_txbuf(93), Some(3300));
        assert_eq!(p.handle_txbuf(90), None, "90 % holds");
    }
}
