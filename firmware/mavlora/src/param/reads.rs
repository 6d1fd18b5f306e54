//! The router's side of a list in flight: which of a ground station's reads by index go to the
//! radio.
//!
//! A ground station reads what is missing once its list has been quiet for a while
//! (QGroundControl and the rig's own ground: 1 s, 10 reads outstanding, each again every
//! second). A slow radio's pause between two packed frames, or a fade, looks like the list's
//! end: it then reads, one by one, what the list is about to bring, and asks again every second
//! while the answers queue on the radio. On LoRa SF7 at 10 % loss that was ~450 B/s of reads up
//! and as many answers down on links that carry ~250 B/s each way: nothing else got through,
//! position at the ground fell to 0.03 Hz and the list never ended. The router holds, as it
//! drops a ground's retries of a command in flight:
//! - a read of an index above the highest the list has brought, while the list is in flight
//!   (a packed frame of that component came within [`LIST_QUIET`]): the list brings it;
//! - a read of a value it gave the ground less than [`DELIVERED_GRACE`] ago: the ground asked
//!   before it had read it (its reads and the router's values cross on the local link; with
//!   the real ArduCopter on LoRa SF7 a third of the answers were such copies);
//! - a read of an index it forwarded less than a retransmission timeout ago (RFC 6298, from
//!   the round trips of reads to their answers, [`REPEAT_HOLD_MIN`]..=[`REPEAT_HOLD_MAX`]),
//!   whose answer has not come: on SiK the answer comes in ~0.3 s and every repeat of the
//!   ground's (1 s) goes; on a loaded LoRa link the answer is still on its way.
//!
//! Everything else goes to the radio: a value the list lost (below its progress), a read by
//! name, any read once the list stopped, and a repeat after the timeout (the read or its
//! answer was lost).

use std::collections::VecDeque;

use super::ParamValue;
use crate::dialect::PARAM_REQUEST_READ_DATA;
use crate::mission::RttEstimator;
use crate::time::{Duration, Instant};

/// A list counts as in flight while its packed frames come at most this far apart: on LoRa SF7
/// one comes about every 0.7 s, but a fade, or what goes ahead of parameters (real
/// ArduCopter's boot messages, `STATUSTEXT`s that go first, held a list back for 20 s), pauses
/// it for seconds; reads let through then fetch, one by one at 50 bytes, what the list brings
/// at ~11. Only reads of what the list has not reached wait: a value it lost is read at once.
pub const LIST_QUIET: Duration = Duration::from_secs(10);

/// A read forwarded is not forwarded again for at least this long unless its answer came...
pub const REPEAT_HOLD_MIN: Duration = Duration::from_millis(500);
/// ...and at most this long (before a round trip is measured: 1.5 s).
pub const REPEAT_HOLD_MAX: Duration = Duration::from_secs(3);

/// A value given to the ground this recently is on its way to it: a read of it crossed it.
pub const DELIVERED_GRACE: Duration = Duration::from_secs(1);

/// Values remembered as given to the ground (a LoRa frame holds ~10).
const MAX_DELIVERED: usize = 512;

/// Lists followed at once (one per component of a vehicle that sends one).
const MAX_LISTS: usize = 16;
/// Reads remembered at once: a ground station keeps ~10 in flight.
const MAX_READS: usize = 64;

#[derive(Debug, Clone, Copy)]
struct List {
    system: u8,
    component: u8,
    count: u16,
    highest: u16,
    last: Instant,
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReadGateStats {
    /// Reads forwarded.
    pub forwarded: u64,
    /// Reads held because the list in flight brings their value.
    pub held_ahead: u64,
    /// Reads held because the same read is in flight.
    pub held_repeat: u64,
    /// Reads held because the router gave the ground that value a moment before.
    pub held_delivered: u64,
}

/// A read forwarded and not answered yet.
#[derive(Debug, Clone, Copy)]
struct Read {
    system: u8,
    component: u8,
    index: u16,
    at: Instant,
    /// Forwarded before (its answer would not tell which copy it answers: Karn's rule).
    again: bool,
}

/// Sans-IO: tell it the list's values and the answers that come from the radio, ask it about
/// each read from the ground.
#[derive(Debug)]
pub struct ReadGate {
    lists: VecDeque<List>,
    reads: VecDeque<Read>,
    /// Indices read recently, to tell a repeat (Karn's rule).
    recent: VecDeque<(u8, u8, u16, Instant)>,
    /// Values given to the ground lately: (system, component, index, when).
    delivered: VecDeque<(u8, u8, u16, Instant)>,
    rtt: RttEstimator,
    stats: ReadGateStats,
}

impl Default for ReadGate {
    fn default() -> Self {
        Self {
            lists: VecDeque::new(),
            reads: VecDeque::new(),
            recent: VecDeque::new(),
            delivered: VecDeque::new(),
            rtt: RttEstimator::new(
                Duration::from_millis(1500),
                REPEAT_HOLD_MIN,
                REPEAT_HOLD_MAX,
            ),
            stats: ReadGateStats::default(),
        }
    }
}

fn targets(system: u8, component: u8, target: (u8, u8)) -> bool {
    target.0 == system && (target.1 == component || target.1 == 0)
}

impl ReadGate {
    /// Counters so far.
    pub fn stats(&self) -> ReadGateStats {
        self.stats
    }

    /// A packed frame of a list from (`system`, `component`) with `values` came at `now`.
    /// Values without a place in the list (an index at or above the count: ArduPilot's 65535
    /// for a parameter that changed by itself) do not move its progress.
    pub fn list_values(&mut self, now: Instant, system: u8, component: u8, values: &[ParamValue]) {
        for v in values {
            self.answered(now, system, component, v.index);
        }
        let mut listed = values.iter().filter(|v| v.index < v.count);
        let Some(first) = listed.next() else {
            return;
        };
        let last = listed.next_back().unwrap_or(first);
        let at = self
            .lists
            .iter()
            .position(|l| (l.system, l.component) == (system, component));
        match at {
            Some(at) => {
                let l = &mut self.lists[at];
                // A new list (another count, or one that starts again) restarts the progress.
                if l.count != first.count || now >= l.last + LIST_QUIET {
                    l.highest = last.index;
                } else {
                    l.highest = l.highest.max(last.index);
                }
                l.count = first.count;
                l.last = now;
            }
            None => {
                if self.lists.len() == MAX_LISTS {
                    self.lists.pop_front();
                }
                self.lists.push_back(List {
                    system,
                    component,
                    count: first.count,
                    highest: last.index,
                    last: now,
                });
            }
        }
    }

    /// How long a read forwarded holds its repeats now.
    pub fn hold(&self) -> Duration {
        self.rtt.rto()
    }

    /// The value of `index` from (`system`, `component`) came at `now` (an answer, or the
    /// list's).
    pub fn answered(&mut self, now: Instant, system: u8, component: u8, index: u16) {
        if self.delivered.len() == MAX_DELIVERED {
            self.delivered.pop_front();
        }
        self.delivered.push_back((system, component, index, now));
        let Some(at) = self.reads.iter().position(|r| {
            r.index == index && r.system == system && (r.component == component || r.component == 0)
        }) else {
            return;
        };
        let read = self.reads.remove(at).expect("found");
        if !read.again {
            self.rtt.sample(now.saturating_duration_since(read.at));
        }
    }

    /// Whether the ground's read `r` goes to the radio at `now` (else it is held, counted).
    pub fn read(&mut self, now: Instant, r: &PARAM_REQUEST_READ_DATA) -> bool {
        // -1: by name, not the list's business.
        let Ok(index) = u16::try_from(r.param_index) else {
            self.stats.forwarded += 1;
            return true;
        };
        let target = (r.target_system, r.target_component);
        self.delivered
            .retain(|&(_, _, _, at)| now < at + DELIVERED_GRACE);
        if self
            .delivered
            .iter()
            .any(|&(s, c, i, _)| i == index && targets(s, c, target))
        {
            self.stats.held_delivered += 1;
            return false;
        }
        let ahead = self.lists.iter().any(|l| {
            targets(l.system, l.component, target)
                && now < l.last + LIST_QUIET
                && index > l.highest
                && index < l.count
        });
        if ahead {
            self.stats.held_ahead += 1;
            return false;
        }
        // Unanswered within the timeout: the read or its answer was lost (on a radio, loss is
        // not congestion: no backoff).
        let hold = self.rtt.rto();
        self.reads.retain(|r| now < r.at + hold);
        let same = |s: u8, c: u8, i: u16| i == index && targets(s, c, target);
        if self
            .reads
            .iter()
            .any(|r| same(r.system, r.component, r.index))
        {
            self.stats.held_repeat += 1;
            return false;
        }
        self.recent
            .retain(|&(_, _, _, at)| now < at + REPEAT_HOLD_MAX * 4);
        let again = self.recent.iter().any(|&(s, c, i, _)| same(s, c, i));
        if self.reads.len() == MAX_READS {
            self.reads.pop_front();
        }
        if self.recent.len() == MAX_READS {
            self.recent.pop_front();
        }
        self.reads.push_back(Read {
            system: target.0,
            component: target.1,
            index,
            at: now,
            again,
        });
        self.recent.push_back((target.0, target.1, index, now));
        self.stats.forwarded += 1;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    fn value(index: u16) -> ParamValue {
        ParamValue {
            value: [0; 4],
            count: 100,
            index,
            name: [b'X'; 16],
            param_type: 9,
        }
    }

    fn read(index: i16) -> PARAM_REQUEST_READ_DATA {
        PARAM_REQUEST_READ_DATA {
            target_system: 1,
            target_component: 1,
            param_index: index,
            ..Default::default()
        }
    }

    #[test]
    fn reads_ahead_of_a_list_in_flight_wait_for_it_and_lost_values_are_read() {
        let mut g = ReadGate::default();
        g.list_values(ms(0), 1, 1, &[value(0), value(1), value(2)]);
        g.list_values(ms(500), 1, 1, &[value(5), value(6)]);
        // 3 and 4 were lost: read; 7 is coming
        assert!(g.read(ms(1600), &read(3)));
        assert!(g.read(ms(1600), &read(4)));
        assert!(!g.read(ms(1600), &read(7)));
        // by name: always
        assert!(g.read(ms(1600), &read(-1)));
        // the list went quiet: 7 is read
        assert!(!g.read(ms(10_000), &read(7)));
        assert!(g.read(ms(10_500), &read(7)));
        assert_eq!(
            g.stats(),
            ReadGateStats {
                forwarded: 4,
                held_ahead: 2,
                held_repeat: 0,
                held_delivered: 0,
            }
        );
    }

    #[test]
    fn a_read_crossing_the_value_it_asks_for_is_not_sent() {
        let mut g = ReadGate::default();
        g.list_values(ms(0), 1, 1, &[value(0), value(1), value(2)]);
        // the ground asked for 2 before it read it
        assert!(!g.read(ms(50), &read(2)));
        assert_eq!(g.stats().held_delivered, 1);
        // a second later it would not have: it lost it
        assert!(g.read(ms(1100), &read(2)));
    }

    #[test]
    fn a_value_without_a_place_in_the_list_does_not_move_its_progress() {
        let mut g = ReadGate::default();
        let told = ParamValue {
            index: u16::MAX,
            ..value(0)
        };
        g.list_values(ms(0), 1, 1, &[value(0), value(1), told]);
        assert!(!g.read(ms(500), &read(2)), "the list brings it");
    }

    #[test]
    fn a_read_in_flight_is_not_sent_again_until_answered_or_held_long_enough() {
        let mut g = ReadGate::default();
        assert_eq!(
            g.hold(),
            Duration::from_millis(1500),
            "before a round trip is measured"
        );
        assert!(g.read(ms(0), &read(9)));
        assert!(!g.read(ms(1000), &read(9)), "a repeat while in flight");
        assert!(g.read(ms(1500), &read(9)), "its answer was lost");
        g.answered(ms(1600), 1, 1, 9);
        assert!(!g.read(ms(1700), &read(9)), "crossed its answer");
        assert!(g.read(ms(2700), &read(9)), "asked again after the answer");
        assert_eq!((g.stats().held_repeat, g.stats().held_delivered), (1, 1));
    }

    #[test]
    fn the_hold_follows_the_round_trip_of_reads() {
        let mut g = ReadGate::default();
        // SiK: answers in 300 ms; the ground's repeats a second later all go
        for i in 0..20 {
            let t = 1000 * u64::from(i);
            assert!(g.read(ms(t), &read(i as i16)));
            g.answered(ms(t + 300), 1, 1, i);
        }
        assert_eq!(g.hold(), REPEAT_HOLD_MIN);
        assert!(g.read(ms(30_000), &read(100)));
        assert!(
            g.read(ms(31_000), &read(100)),
            "a repeat after a second goes"
        );
        // a slow link: answers after 2.5 s, repeats held until then
        let mut g = ReadGate::default();
        for i in 0..20 {
            let t = 3000 * u64::from(i);
            assert!(g.read(ms(t), &read(i as i16)));
            g.answered(ms(t + 2500), 1, 1, i);
        }
        assert!(g.hold() >= Duration::from_millis(2500), "{:?}", g.hold());
        assert!(g.read(ms(100_000), &read(100)));
        assert!(!g.read(ms(101_000), &read(100)));
        assert!(!g.read(ms(102_000), &read(100)));
    }
}
