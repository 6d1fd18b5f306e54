//! Duty cycle: the share of a sliding window a transmitter may spend on air.
//!
//! EU 433 MHz SRD (ERC/REC 70-03 annex 1, band h1.4) allows 10 % over an hour
//! at 10 mW e.r.p.; the paper flew on Danish channels with 100 %. A link
//! always *tracks* its airtime (scenario 6 reports the share); with `enforce`
//! it *holds* a packet that would break the budget until enough old airtime
//! has left the window. Holding rather than dropping is what a radio that
//! honours the rule does (SiK's `duty_cycle_wait` stops transmitting); bytes
//! still pile up in the serial buffer meanwhile and overflow there, so loss
//! under an exhausted budget shows up as buffer drops, counted as such.
//!
//! Checking only at the start of each packet suffices: the window holding the
//! most airtime always ends at the end of some packet, and the check includes
//! the new packet in the window ending at its own end.

use std::collections::VecDeque;
use timebase::{Duration, Instant};

use serde::{Deserialize, Serialize};

use super::error::{ConfigError, check_range};

/// A duty-cycle rule.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DutyCycle {
    /// Sliding window, seconds.
    pub window_s: f64,
    /// Largest share of the window on air, 0..=1.
    pub max_share: f64,
    /// Hold packets that would exceed the share (else only report).
    pub enforce: bool,
}

impl Default for DutyCycle {
    /// The EU 433 MHz SRD rule, reported but not enforced.
    fn default() -> Self {
        DutyCycle {
            window_s: 3600.0,
            max_share: 0.10,
            enforce: false,
        }
    }
}

impl DutyCycle {
    /// EU 433 MHz SRD: 10 % over a sliding hour, enforced.
    pub fn eu_433_srd() -> DutyCycle {
        DutyCycle {
            enforce: true,
            ..DutyCycle::default()
        }
    }

    /// The window, in whole microseconds.
    pub fn window(&self) -> Duration {
        Duration::from_secs_f64(self.window_s)
    }

    /// Airtime allowed per window: the share of [`window`](Self::window), rounded down (up,
    /// the rounding would let the share be exceeded).
    pub fn budget(&self) -> Duration {
        Duration::from_micros((self.window().as_micros() as f64 * self.max_share) as u64)
    }

    pub(crate) fn validate(
        &self,
        longest_packet: Duration,
        payload: usize,
    ) -> Result<(), ConfigError> {
        check_range("window_s", self.window_s, 1e-3, 1e7, "0.001..=1e7 s")?;
        check_range("max_share", self.max_share, 0.0, 1.0, "0..=1")?;
        if self.enforce && self.budget() < longest_packet {
            return Err(ConfigError::DutyBudgetTooSmall {
                budget_ms: self.budget().as_secs_f64() * 1e3,
                payload,
                airtime_ms: longest_packet.as_secs_f64() * 1e3,
            });
        }
        Ok(())
    }
}

/// One transmission: start and end.
#[derive(Debug, Clone, Copy)]
struct Burst {
    start: Instant,
    end: Instant,
}

/// Airtime bookkeeping for one transmitter; transmissions never overlap.
#[derive(Debug, Clone)]
pub struct DutyTracker {
    rule: DutyCycle,
    window: Duration,
    budget: Duration,
    /// Transmissions that may still overlap a future window, oldest first.
    recent: VecDeque<Burst>,
    /// Sum of `recent`'s durations.
    recent_sum: Duration,
    total: Duration,
    peak: Duration,
}

impl DutyTracker {
    /// A tracker for a rule.
    pub fn new(rule: DutyCycle) -> DutyTracker {
        DutyTracker {
            rule,
            window: rule.window(),
            budget: rule.budget(),
            recent: VecDeque::new(),
            recent_sum: Duration::ZERO,
            total: Duration::ZERO,
            peak: Duration::ZERO,
        }
    }

    /// The rule tracked.
    pub fn rule(&self) -> DutyCycle {
        self.rule
    }

    /// Airtime of transmissions (parts) at or after `left`.
    fn airtime_since(&self, left: Instant) -> Duration {
        let mut sum = self.recent_sum;
        for b in &self.recent {
            if b.start >= left {
                break;
            }
            sum -= b.end.min(left) - b.start;
        }
        sum
    }

    /// Airtime within the window ending at `now`.
    pub fn used(&self, now: Instant) -> Duration {
        let mut sum = self.airtime_since(now - self.window);
        // A transmission still on air counts up to now only.
        for b in self.recent.iter().rev() {
            if b.end <= now {
                break;
            }
            sum -= b.end - b.start.max(now);
        }
        sum
    }

    /// Share of the window ending at `now` spent on air.
    pub fn share(&self, now: Instant) -> f64 {
        self.used(now).as_secs_f64() / self.window.as_secs_f64()
    }

    /// Highest share any window has held so far.
    pub fn peak_share(&self) -> f64 {
        self.peak.as_secs_f64() / self.window.as_secs_f64()
    }

    /// All airtime recorded.
    pub fn total(&self) -> Duration {
        self.total
    }

    /// Earliest start ≥ `t0` at which a packet of `airtime` keeps every window
    /// within budget; `t0` itself when not enforcing. `None` if it never fits.
    pub fn earliest_start(&self, t0: Instant, airtime: Duration) -> Option<Instant> {
        if !self.rule.enforce {
            return Some(t0);
        }
        let need = self.budget.checked_sub(airtime)?;
        // The window ending at the packet's end starts at `left`; airtime
        // since `left` only falls as `left` moves on.
        let left = (t0 + airtime) - self.window;
        let mut tail = self.airtime_since(left);
        if tail <= need {
            return Some(t0);
        }
        for b in &self.recent {
            if b.end <= left {
                continue;
            }
            let part = b.end - b.start.max(left);
            let rest = tail - part;
            if rest <= need {
                // Within this burst: tail(l) = (end − l) + rest ≤ need.
                let l = b.end - (need - rest);
                return Some(l + self.window - airtime);
            }
            tail = rest;
        }
        // Every recent burst expired; tail is zero.
        Some(t0)
    }

    /// Records a transmission starting at `start` (not before earlier ones end).
    pub fn record(&mut self, start: Instant, airtime: Duration) {
        let cutoff = start - self.window;
        while let Some(b) = self.recent.front() {
            if b.end > cutoff {
                break;
            }
            self.recent_sum -= b.end - b.start;
            self.recent.pop_front();
        }
        let end = start + airtime;
        self.recent.push_back(Burst { start, end });
        self.recent_sum += airtime;
        self.total += airtime;
        let in_window = self.airtime_since(end - self.window);
        self.peak = self.peak.max(in_window);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rule(window_s: f64, max_share: f64) -> DutyTracker {
        DutyTracker::new(DutyCycle {
            window_s,
            max_share,
            enforce: true,
        })
    }

    const MS: Duration = Duration::from_millis(1);

    fn at(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    #[test]
    fn holds_until_old_airtime_leaves_the_window() {
        // 1 s window, 10 % → 100 ms budget. Two 50 ms packets at 0 and 100 ms.
        let mut d = rule(1.0, 0.1);
        d.record(Instant::ZERO, 50 * MS);
        assert_eq!(d.earliest_start(at(100), 50 * MS), Some(at(100)));
        d.record(at(100), 50 * MS);
        assert_eq!(d.used(at(150)), 100 * MS);
        assert!((d.peak_share() - 0.1).abs() < 1e-12);
        // A 20 ms packet at 200 ms would end at 220 ms; the window [−780, 220]
        // holds 100 ms. It must wait until 20 ms of the first packet leave:
        // window start 20 ms → end 1020 ms → start 1000 ms.
        assert_eq!(d.earliest_start(at(200), 20 * MS), Some(at(1000)));
        // A 60 ms packet needs the whole first packet gone and 10 ms of the
        // second: window start 110 ms → end 1110 ms → start 1050 ms.
        assert_eq!(d.earliest_start(at(200), 60 * MS), Some(at(1050)));
        // Longer than the budget: never.
        assert_eq!(d.earliest_start(at(200), 101 * MS), None);
    }

    #[test]
    fn used_counts_only_the_window_and_only_the_past() {
        let mut d = rule(1.0, 1.0);
        d.record(Instant::ZERO, 100 * MS);
        assert_eq!(d.used(at(40)), 40 * MS);
        assert_eq!(d.used(at(1050)), 50 * MS);
        assert_eq!(d.used(at(2000)), Duration::ZERO);
        assert_eq!(d.total(), 100 * MS);
    }

    #[test]
    fn reporting_only_never_holds() {
        let mut d = DutyTracker::new(DutyCycle {
            window_s: 1.0,
            max_share: 0.1,
            enforce: false,
        });
        d.record(Instant::ZERO, 500 * MS);
        assert_eq!(d.earliest_start(at(500), 500 * MS), Some(at(500)));
        assert!((d.share(at(600)) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn refuses_a_budget_below_one_packet() {
        let r = DutyCycle {
            window_s: 1.0,
            max_share: 0.01,
            enforce: true,
        };
        assert!(r.validate(11 * MS, 10).is_err());
        assert!(r.validate(10 * MS, 10).is_ok());
    }
}
