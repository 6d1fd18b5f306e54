//! The radio filter: drops and rate-limits frames by header only (no payload decoding).

use crate::time::Duration;
use std::collections::HashMap;

use tracing::trace;

use super::profile::{Profile, RadioRule};
use crate::time::Instant;
use crate::wire::{Frame, StreamId};

/// Outcome of [`RadioFilter::check`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Forward the frame.
    Pass,
    /// The profile drops this message.
    Filtered,
    /// Too soon after the last forwarded frame of this message from this sender.
    RateLimited,
}

/// Frames counted by outcome.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FilterStats {
    /// Forwarded.
    pub passed: u64,
    /// Dropped by a `drop` rule.
    pub filtered: u64,
    /// Dropped by a rate limit.
    pub rate_limited: u64,
}

/// Sans-IO filter applying a [`Profile`]'s radio rules.
///
/// Rate limits are kept per (sender, message id): two vehicles' positions are limited
/// separately. A limited message is due every `1/hz`; a frame arriving on or after its due
/// time passes and the next due time advances by one interval, so an input that is not a
/// multiple of the limit still averages the limit (5 Hz limited to 3 Hz gives 3 Hz, not the
/// 2.5 Hz a plain minimum spacing would, and a jittery 4 Hz still gives 3 Hz). Catching up
/// is bounded: two forwarded frames are never closer than a quarter of an interval, k apart
/// never closer than k - 3/4 intervals, and a quiet period earns no burst.
#[derive(Debug)]
pub struct RadioFilter {
    profile: Profile,
    next_due: HashMap<(StreamId, u32), Instant>,
    stats: FilterStats,
}

impl RadioFilter {
    /// A filter with no history.
    pub fn new(profile: Profile) -> Self {
        Self {
            profile,
            next_due: HashMap::new(),
            stats: FilterStats::default(),
        }
    }

    /// The profile in use.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// Counters so far.
    pub fn stats(&self) -> FilterStats {
        self.stats
    }

    /// Decides whether `frame`, arriving at `now`, goes to the radio. A `Pass` counts as sent
    /// for the rate limit.
    pub fn check<T: AsRef<[u8]>>(&mut self, frame: &Frame<T>, now: Instant) -> Verdict {
        let id = frame.message_id();
        let stream = StreamId {
            system: frame.system_id(),
            component: frame.component_id(),
        };
        let verdict = match self.profile.radio_rule(id) {
            RadioRule::Pass => Verdict::Pass,
            RadioRule::Drop => Verdict::Filtered,
            RadioRule::MaxRate(hz) => self.limit(stream, id, hz, now),
        };
        match verdict {
            Verdict::Pass => self.stats.passed += 1,
            Verdict::Filtered => self.stats.filtered += 1,
            Verdict::RateLimited => self.stats.rate_limited += 1,
        }
        trace!(msgid = id, ?verdict, "radio filter");
        verdict
    }

    fn limit(&mut self, stream: StreamId, id: u32, hz: f64, now: Instant) -> Verdict {
        let interval = Duration::from_secs_f64(1.0 / hz);
        let due = self.next_due.entry((stream, id)).or_insert(now);
        if now < *due {
            return Verdict::RateLimited;
        }
        // A quarter, not a half: an input a third faster than the limit (ArduPilot's 4 Hz
        // for a 3 Hz profile) passes up to 3/4 of an interval late, and a bound above
        // 1/4 then moved every later slot (2.85 Hz on a real clock's jitter).
        *due = (*due + interval).max(now + interval / 4);
        Verdict::Pass
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::frame;
    use proptest::prelude::*;

    const ATTITUDE: u32 = 30;
    const GLOBAL_POSITION_INT: u32 = 33;
    const HEARTBEAT: u32 = 0;

    fn profile() -> Profile {
        Profile::parse(
            "[messages.ATTITUDE]\nradio = \"drop\"\n[messages.GLOBAL_POSITION_INT]\nradio = 3\n",
            "test",
        )
        .unwrap()
    }

    /// Feeds one message at `input_hz` for `secs` and returns the pass times in µs.
    fn run(filter: &mut RadioFilter, id: u32, input_hz: f64, secs: f64) -> Vec<u64> {
        let f = frame(id, 1, 1, 0);
        let period = 1e6 / input_hz;
        let n = (secs * input_hz) as u64;
        (0..n)
            .map(|k| (k as f64 * period) as u64)
            .filter(|&t| filter.check(&f, Instant::from_micros(t)) == Verdict::Pass)
            .collect()
    }

    #[test]
    fn drop_and_pass_rules() {
        let mut filter = RadioFilter::new(profile());
        assert_eq!(
            filter.check(&frame(ATTITUDE, 1, 1, 0), Instant::ZERO),
            Verdict::Filtered
        );
        assert_eq!(
            filter.check(&frame(HEARTBEAT, 1, 1, 0), Instant::ZERO),
            Verdict::Pass
        );
        assert_eq!(
            filter.stats(),
            FilterStats {
                passed: 1,
                filtered: 1,
                rate_limited: 0
            }
        );
    }

    #[test]
    fn position_at_50hz_is_limited_to_3hz() {
        let mut filter = RadioFilter::new(profile());
        let passes = run(&mut filter, GLOBAL_POSITION_INT, 50.0, 10.0);
        assert!((29..=31).contains(&passes.len()), "{}", passes.len());
        assert_eq!(filter.stats().rate_limited, 500 - passes.len() as u64);
    }

    #[test]
    fn input_not_a_multiple_of_the_limit_still_averages_the_limit() {
        // 5 Hz in, 3 Hz allowed: a plain minimum spacing would give 2.5 Hz.
        let mut filter = RadioFilter::new(profile());
        let passes = run(&mut filter, GLOBAL_POSITION_INT, 5.0, 20.0);
        assert!((59..=61).contains(&passes.len()), "{}", passes.len());
    }

    #[test]
    fn jittery_input_faster_than_the_limit_still_averages_the_limit() {
        // An autopilot's 4 Hz on a real clock, a few ms early or late, limited to 3 Hz: with
        // the catch-up bound at half an interval, a frame passing 250 ms late moved every
        // later slot, and the rig's ArduPilot position came out at 2.85 Hz.
        let mut filter = RadioFilter::new(profile());
        let f = frame(GLOBAL_POSITION_INT, 1, 1, 0);
        let mut rng = 0x2545_f491_u32;
        let passes = (0..4 * 120u64)
            .filter(|&k| {
                rng ^= rng << 13;
                rng ^= rng >> 17;
                rng ^= rng << 5;
                let jitter_us = u64::from(rng % 8_000);
                let at = Instant::from_micros(10_000 + k * 250_000 + jitter_us - 4_000);
                filter.check(&f, at) == Verdict::Pass
            })
            .count();
        assert!(
            (359..=361).contains(&passes),
            "{passes} in 120 s, 3 Hz asked"
        );
    }

    #[test]
    fn slower_input_passes_untouched() {
        let mut filter = RadioFilter::new(profile());
        let passes = run(&mut filter, GLOBAL_POSITION_INT, 2.0, 10.0);
        assert_eq!(passes.len(), 20);
    }

    #[test]
    fn senders_are_limited_separately() {
        let mut filter = RadioFilter::new(profile());
        let a = frame(GLOBAL_POSITION_INT, 1, 1, 0);
        let b = frame(GLOBAL_POSITION_INT, 2, 1, 0);
        assert_eq!(filter.check(&a, Instant::ZERO), Verdict::Pass);
        assert_eq!(filter.check(&b, Instant::ZERO), Verdict::Pass);
        assert_eq!(
            filter.check(&a, Instant::from_millis(10)),
            Verdict::RateLimited
        );
    }

    proptest! {
        /// Whatever the arrival times, forwarded frames k apart are at least (k - 3/4)
        /// intervals apart: at most `window * hz + 1.75` frames in any window.
        #[test]
        fn limit_holds_for_any_arrivals(
            gaps in prop::collection::vec(0u64..1_000_000, 1..300),
            hz in 0.2f64..50.0,
        ) {
            let p = Profile::parse(&format!("[messages.33]\nradio = {hz}\n"), "p").unwrap();
            let mut filter = RadioFilter::new(p);
            let f = frame(GLOBAL_POSITION_INT, 1, 1, 0);
            let mut t = 0;
            let mut passes = Vec::new();
            for gap in gaps {
                t += gap;
                if filter.check(&f, Instant::from_micros(t)) == Verdict::Pass {
                    passes.push(t);
                }
            }
            let interval = 1e6 / hz;
            for i in 0..passes.len() {
                for j in i + 1..passes.len() {
                    let spacing = (passes[j] - passes[i]) as f64;
                    // 1 µs of slack for Duration's rounding of the interval
                    let floor = ((j - i) as f64 - 0.75) * interval - (j - i) as f64;
                    prop_assert!(spacing >= floor, "{} apart after {} intervals", spacing, j - i);
                }
            }
        }
    }
}
