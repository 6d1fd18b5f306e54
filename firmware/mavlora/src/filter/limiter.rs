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
    /// An `on_change` message the same as the last one forwarded from this sender.
    Unchanged,
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
    /// Dropped by an `on_change` rule: the same as the last one forwarded.
    pub unchanged: u64,
    /// Forwarded past a rate limit or an `on_change` rule as the answer to a request.
    pub requested: u64,
}

/// How long after a ground's request the message asked for passes whatever its rate: PX4
/// 1.16 and ArduPilot 4.6 answer within milliseconds, a busy flight-controller link within
/// a second.
pub const REQUEST_WINDOW: Duration = Duration::from_secs(5);
/// Requests in flight that are remembered (message ids asked for at once).
const REQUESTS_KEPT: usize = 16;
/// Answers one message id lets through in one window: a few ground stations asking at once.
const ANSWERS_PER_REQUEST: u8 = 4;

/// Sans-IO filter applying a [`Profile`]'s radio rules.
///
/// Rate limits are kept per (sender, message id): two vehicles' positions are limited
/// separately. A limited message is due every `1/hz`; a frame arriving on or after its due
/// time passes and the next due time advances by one interval, so an input that is not a
/// multiple of the limit still averages the limit (5 Hz limited to 3 Hz gives 3 Hz, not the
/// 2.5 Hz a plain minimum spacing would, and a jittery 4 Hz still gives 3 Hz). Catching up
/// is bounded: two forwarded frames are never closer than a quarter of an interval, k apart
/// never closer than k - 3/4 intervals, and a quiet period earns no burst.
///
/// A message the ground asked for ([`RadioFilter::requested`]: `MAV_CMD_REQUEST_MESSAGE`)
/// passes its rate limit and `on_change` rule once per request within [`REQUEST_WINDOW`]:
/// the answer is what the ground waits for, and its requests are what it costs.
#[derive(Debug)]
pub struct RadioFilter {
    profile: Profile,
    next_due: HashMap<(StreamId, u32), Instant>,
    /// `on_change` messages: the payload last forwarded, trailing zeros cut (as MAVLink 2
    /// sends it), per sender.
    last_sent: HashMap<(StreamId, u32), Vec<u8>>,
    /// Message id asked for → (until when, answers still to let through).
    requests: HashMap<u32, (Instant, u8)>,
    stats: FilterStats,
}

impl RadioFilter {
    /// A filter with no history.
    pub fn new(profile: Profile) -> Self {
        Self {
            profile,
            next_due: HashMap::new(),
            last_sent: HashMap::new(),
            requests: HashMap::new(),
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

    /// The ground asked for message `id` at `now` (a `MAV_CMD_REQUEST_MESSAGE` on its way to
    /// the flight controller): the next frame of it passes whatever its rate or `on_change`
    /// rule (a `drop` rule still drops it).
    pub fn requested(&mut self, id: u32, now: Instant) {
        self.requests.retain(|_, (until, _)| *until > now);
        if self.requests.len() >= REQUESTS_KEPT && !self.requests.contains_key(&id) {
            return;
        }
        let entry = self.requests.entry(id).or_insert((now, 0));
        entry.0 = now + REQUEST_WINDOW;
        entry.1 = (entry.1 + 1).min(ANSWERS_PER_REQUEST);
    }

    /// Decides whether `frame`, arriving at `now`, goes to the radio. A `Pass` counts as sent
    /// for the rate limit.
    pub fn check<T: AsRef<[u8]>>(&mut self, frame: &Frame<T>, now: Instant) -> Verdict {
        let id = frame.message_id();
        let stream = StreamId {
            system: frame.system_id(),
            component: frame.component_id(),
        };
        let rule = self.profile.radio_rule(id);
        let on_change = self.profile.on_change(id);
        let payload = || {
            let p = frame.payload();
            let end = p.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
            &p[..end]
        };
        // A request matters only where a frame could be held back other than by `drop`.
        let holds = match rule {
            RadioRule::Drop => false,
            RadioRule::Pass => on_change,
            RadioRule::MaxRate(_) => true,
        };
        let verdict = if holds && self.take_request(id, now) {
            self.stats.requested += 1;
            Verdict::Pass
        } else if on_change
            && self
                .last_sent
                .get(&(stream, id))
                .is_some_and(|last| last.as_slice() == payload())
        {
            Verdict::Unchanged
        } else {
            match rule {
                RadioRule::Pass => Verdict::Pass,
                RadioRule::Drop => Verdict::Filtered,
                RadioRule::MaxRate(hz) => self.limit(stream, id, hz, now),
            }
        };
        match verdict {
            Verdict::Pass => self.stats.passed += 1,
            Verdict::Filtered => self.stats.filtered += 1,
            Verdict::RateLimited => self.stats.rate_limited += 1,
            Verdict::Unchanged => self.stats.unchanged += 1,
        }
        if verdict == Verdict::Pass && on_change {
            self.last_sent.insert((stream, id), payload().to_vec());
        }
        trace!(msgid = id, ?verdict, "radio filter");
        verdict
    }

    /// Uses up one answer to a request for `id`, if one is open at `now`.
    fn take_request(&mut self, id: u32, now: Instant) -> bool {
        let Some((until, left)) = self.requests.get_mut(&id) else {
            return false;
        };
        if *until <= now {
            self.requests.remove(&id);
            return false;
        }
        *left -= 1;
        if *left == 0 {
            self.requests.remove(&id);
        }
        true
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
                ..FilterStats::default()
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

    /// HOME_POSITION as the compact profiles treat it, and a dropped message.
    fn home_profile() -> Profile {
        Profile::parse(
            "[messages.HOME_POSITION]\nradio = 0.1\non_change = true\n\
             [messages.ATTITUDE]\nradio = \"drop\"\non_change = true\n",
            "test",
        )
        .unwrap()
    }

    const HOME_POSITION: u32 = 242;

    /// A HOME_POSITION from system `sysid` at latitude `lat` (1e-7 degrees).
    fn home(sysid: u8, lat: i32) -> crate::wire::OwnedFrame {
        use crate::dialect::{HOME_POSITION_DATA, MavMessage};
        let msg = MavMessage::HOME_POSITION(HOME_POSITION_DATA {
            latitude: lat,
            ..Default::default()
        });
        crate::wire::encode(
            mavlink::MavlinkVersion::V2,
            crate::testutil::header(sysid, 1, 0),
            &msg,
        )
    }

    #[test]
    fn on_change_holds_repeats_and_caps_changes() {
        let mut filter = RadioFilter::new(home_profile());
        let same = home(1, 7);
        let at = |s: u64| Instant::from_millis(s * 1000);
        assert_eq!(filter.check(&same, at(0)), Verdict::Pass);
        assert_eq!(filter.check(&same, at(20)), Verdict::Unchanged);
        // a change passes once its slot (10 s) allows, not before
        let moved = home(1, 8);
        assert_eq!(filter.check(&moved, at(20)), Verdict::Pass);
        let again = home(1, 9);
        assert_eq!(filter.check(&again, at(22)), Verdict::RateLimited);
        assert_eq!(filter.check(&again, at(30)), Verdict::Pass);
        // another sender's home is its own
        assert_eq!(filter.check(&home(2, 9), at(30)), Verdict::Pass);
        let s = filter.stats();
        assert_eq!((s.unchanged, s.rate_limited, s.passed), (1, 1, 4));
    }

    #[test]
    fn a_requested_frame_passes_once_within_the_window_but_never_a_drop() {
        let mut filter = RadioFilter::new(home_profile());
        let home = home(1, 7);
        let ms = Instant::from_millis;
        assert_eq!(filter.check(&home, ms(0)), Verdict::Pass);
        filter.requested(HOME_POSITION, ms(1000));
        assert_eq!(filter.check(&home, ms(1001)), Verdict::Pass, "the answer");
        assert_eq!(filter.check(&home, ms(1002)), Verdict::Unchanged, "once");
        // a request the autopilot did not answer in time lets nothing through later
        filter.requested(HOME_POSITION, ms(2000));
        assert_eq!(
            filter.check(&home, ms(2000) + REQUEST_WINDOW),
            Verdict::Unchanged
        );
        filter.requested(30, ms(8000));
        assert_eq!(
            filter.check(&frame(30, 1, 1, 0), ms(8001)),
            Verdict::Filtered
        );
        assert_eq!(filter.stats().requested, 1);
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
