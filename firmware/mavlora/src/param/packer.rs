//! The bridge's side: `PARAM_VALUE`s the autopilot streams wait here, and leave packed, one
//! frame at a time, as full as the radio's budget lets them be.

use std::collections::{HashSet, VecDeque};

use tracing::warn;

use super::pack::{self, MAX_DATA, MAX_VALUE_BYTES, MIN_VALUE_BYTES, ParamValue};
use crate::dialect::MAVLORA_PARAM_VALUES_DATA;
use crate::time::{Duration, Instant};

/// How the bridge packs a parameter list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamPackConfig {
    /// Data bytes a frame carries at most ([`MAX_VALUE_BYTES`]..=[`MAX_DATA`]).
    pub data_bytes: usize,
    /// A frame that is not full leaves this long after its first value arrived.
    pub delay: Duration,
    /// Values that may wait at most; more are dropped (the ground reads them again).
    pub backlog: usize,
    /// Frames leave at most at this many bytes/s, each counted at its length on the radio
    /// (the bridge sets its radio budget): the scheduler's burst allowance would otherwise
    /// pour several frames at once into a radio whose buffer (256 bytes on a LoRa modem)
    /// drops what does not fit, and a dropped frame is ~10 values to read again. `None`: no
    /// pacing.
    pub pace_bytes_per_s: Option<u32>,
}

/// Longest a packed frame should take of the radio budget: a ground station (QGroundControl,
/// the rig's) reads the missing values one by one once its list has been quiet for 1 s, so a
/// list must not go quiet between two frames. Half a second of the whole budget leaves the
/// other telemetry its share and a frame every ~0.7 s on LoRa SF7.
pub const FRAME_PERIOD: Duration = Duration::from_millis(500);

/// What a frame costs on the radio besides its data: MAVLink 2 framing (12), the message's
/// other fields (6) and a signature (13).
pub const FRAME_OVERHEAD: usize = 12 + 6 + 13;

/// Values that wait at most by default: a whole list of any autopilot we know (ArduCopter
/// 4.6 has 1,396, PX4 1.16 904), ~40 bytes each.
pub const BACKLOG: usize = 4096;

impl ParamPackConfig {
    /// For a radio budget of `rate` bytes/s: frames of at most [`FRAME_PERIOD`] of it
    /// (LoRa SF7's ~250 B/s: 94 data bytes; SiK's: [`MAX_DATA`]), a 100 ms delay, paced at
    /// `rate`.
    pub fn for_rate(rate: u32) -> Self {
        let budget = (u64::from(rate) * FRAME_PERIOD.as_millis() / 1000) as usize;
        Self {
            data_bytes: budget
                .saturating_sub(FRAME_OVERHEAD)
                .clamp(MAX_VALUE_BYTES, MAX_DATA),
            delay: Duration::from_millis(100),
            backlog: BACKLOG,
            pace_bytes_per_s: Some(rate),
        }
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ParamPackStats {
    /// Values taken in to pack.
    pub values: u64,
    /// Frames made.
    pub frames: u64,
    /// Values that left packed.
    pub values_packed: u64,
    /// Values dropped because the backlog was full (the ground reads them again).
    pub dropped: u64,
    /// Values dropped because the autopilot's answer to the ground's own question about the
    /// same parameter left first (a stale copy must not follow it).
    pub superseded: u64,
    /// Values that took the place of a waiting one of the same index (a list asked for again
    /// while the first is still waiting: it is not sent twice; the newer value is sent).
    pub replaced: u64,
}

#[derive(Debug, Clone, Copy)]
struct Waiting {
    system: u8,
    component: u8,
    value: ParamValue,
    at: Instant,
}

/// Sans-IO packer: [`push`](Self::push) each `PARAM_VALUE` of a list, take frames with
/// [`poll`](Self::poll) whenever the radio's parameter queue is empty, wake at
/// [`poll_timeout`](Self::poll_timeout).
#[derive(Debug)]
pub struct ParamPacker {
    config: ParamPackConfig,
    backlog: VecDeque<Waiting>,
    /// (system, component, index) of each value waiting.
    waiting: HashSet<(u8, u8, u16)>,
    /// No frame before this (pacing).
    next_release: Instant,
    stats: ParamPackStats,
}

impl ParamPacker {
    /// An empty packer.
    pub fn new(config: ParamPackConfig) -> Self {
        Self {
            config: ParamPackConfig {
                data_bytes: config.data_bytes.clamp(MAX_VALUE_BYTES, MAX_DATA),
                ..config
            },
            backlog: VecDeque::new(),
            waiting: HashSet::new(),
            next_release: Instant::ZERO,
            stats: ParamPackStats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> ParamPackStats {
        self.stats
    }

    /// Values waiting.
    pub fn waiting(&self) -> usize {
        self.backlog.len()
    }

    /// Takes `value` from (`system`, `component`) at `now`, if it is a list's (its index
    /// below its count: ArduPilot tells of a parameter that changed by itself with index
    /// 65535, and that is no place in a list) and can be packed ([`ParamValue::packable`]);
    /// whether it was taken (a full backlog takes it and drops it, counted). A value of an
    /// index already waiting takes its place.
    pub fn push(&mut self, now: Instant, system: u8, component: u8, value: ParamValue) -> bool {
        if !value.packable() || value.index >= value.count {
            return false;
        }
        self.stats.values += 1;
        if self.waiting.contains(&(system, component, value.index))
            && let Some(w) = self.backlog.iter_mut().find(|w| {
                (w.system, w.component, w.value.index, w.value.count)
                    == (system, component, value.index, value.count)
            })
        {
            w.value = value;
            self.stats.replaced += 1;
            return true;
        }
        if self.backlog.len() >= self.config.backlog {
            self.stats.dropped += 1;
            let n = self.stats.dropped;
            if n.is_power_of_two() {
                warn!(%now, dropped = n, "parameter backlog full, dropped a PARAM_VALUE (logged at the 1st, 2nd, 4th... drop)");
            }
            return true;
        }
        self.backlog.push_back(Waiting {
            system,
            component,
            value,
            at: now,
        });
        self.waiting.insert((system, component, value.index));
        true
    }

    /// The autopilot answered the ground's own question about `value`'s parameter (the echo
    /// of a set, a read): the list's copies still waiting are stale or redundant, and are
    /// dropped. Matched by name, or by index where the answer has one (ArduPilot echoes a set
    /// with index 65535).
    pub fn answered(&mut self, system: u8, component: u8, value: &ParamValue) {
        let before = self.backlog.len();
        let waiting = &mut self.waiting;
        self.backlog.retain(|w| {
            let same = w.system == system
                && w.component == component
                && (w.value.name == value.name
                    || (value.index != u16::MAX
                        && w.value.index == value.index
                        && w.value.count == value.count));
            if same {
                waiting.remove(&(w.system, w.component, w.value.index));
            }
            !same
        });
        self.stats.superseded += (before - self.backlog.len()) as u64;
    }

    /// The next frame and the system it speaks for, if one is due at `now`: the pace allows
    /// it, and it is full (its next value would not fit, or belongs to another run) or its
    /// first value waited [`ParamPackConfig::delay`]. Tell [`charge`](Self::charge) what it
    /// costs on the radio.
    pub fn poll(&mut self, now: Instant) -> Option<(u8, MAVLORA_PARAM_VALUES_DATA)> {
        let first = *self.backlog.front()?;
        if now < self.next_release {
            return None;
        }
        let run = self
            .backlog
            .iter()
            .take_while(|w| (w.system, w.component) == (first.system, first.component))
            .map(|w| &w.value);
        let (n, data) = pack::pack(run, self.config.data_bytes);
        if n == 0 {
            // Cannot happen (only packable values are taken); never stall on one.
            if let Some(w) = self.backlog.pop_front() {
                self.waiting.remove(&(w.system, w.component, w.value.index));
            }
            return None;
        }
        let full = n < self.backlog.len() || data.len() + MIN_VALUE_BYTES > self.config.data_bytes;
        if !full && now < first.at + self.config.delay {
            return None;
        }
        let values: Vec<ParamValue> = self.backlog.drain(..n).map(|w| w.value).collect();
        for v in &values {
            self.waiting
                .remove(&(first.system, first.component, v.index));
        }
        self.stats.frames += 1;
        self.stats.values_packed += n as u64;
        Some((first.system, pack::frame(first.component, &values, &data)))
    }

    /// The frame [`poll`](Self::poll) gave last takes `bytes` on the radio, from `now`: the
    /// next leaves no sooner than the pace allows.
    pub fn charge(&mut self, now: Instant, bytes: usize) {
        if let Some(rate) = self.config.pace_bytes_per_s.filter(|r| *r > 0) {
            let micros = (bytes as u64 * 1_000_000).div_ceil(u64::from(rate));
            self.next_release = now + Duration::from_micros(micros);
        }
    }

    /// When the frame being gathered is due (the pace, and its first value's delay;
    /// [`poll`](Self::poll) may have one sooner once it is full, as soon as the pace allows);
    /// `None` with nothing waiting.
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.backlog
            .front()
            .map(|w| (w.at + self.config.delay).max(self.next_release))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(name: &str, index: u16) -> ParamValue {
        let mut n = [0u8; 16];
        n[..name.len()].copy_from_slice(name.as_bytes());
        ParamValue {
            value: 1.0f32.to_le_bytes(),
            count: 100,
            index,
            name: n,
            param_type: 9,
        }
    }

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    #[test]
    fn a_frame_leaves_when_full_or_after_the_delay() {
        let mut p = ParamPacker::new(ParamPackConfig {
            data_bytes: 40,
            delay: Duration::from_millis(100),
            backlog: 10,
            pace_bytes_per_s: None,
        });
        assert!(p.push(ms(0), 1, 1, value("ATC_RAT_PIT_P", 0)));
        assert_eq!(p.poll(ms(50)), None, "not full, not due");
        assert_eq!(p.poll_timeout(), Some(ms(100)));
        let (sys, f) = p.poll(ms(100)).expect("due");
        assert_eq!((sys, f.values, f.param_index), (1, 1, 0));
        // 17 bytes for the first (2 + 13 + 2), 5 for each next (2 + 1 + 2): five fill 40 bytes
        // and leave at once
        for i in 1..=6 {
            p.push(ms(200), 1, 1, value(&format!("ATC_RAT_PIT_{i}"), i));
        }
        let (_, f) = p.poll(ms(200)).expect("full");
        assert_eq!((f.values, f.param_index), (5, 1));
        assert_eq!(p.waiting(), 1);
    }

    #[test]
    fn runs_break_at_another_component_count_or_a_lower_index() {
        let mut p = ParamPacker::new(ParamPackConfig::for_rate(3000));
        p.push(ms(0), 1, 1, value("A", 0));
        p.push(ms(0), 1, 1, value("B", 1));
        p.push(ms(0), 1, 100, value("C", 2));
        p.push(ms(0), 1, 100, value("D", 1));
        let lens: Vec<u8> = std::iter::from_fn(|| p.poll(ms(0)).map(|(_, f)| f.values)).collect();
        // the last one alone is not full yet
        assert_eq!(lens, vec![2, 1]);
        assert_eq!(p.poll(ms(100)).map(|(_, f)| f.component), Some(100));
    }

    #[test]
    fn an_answer_drops_the_lists_stale_copies_and_a_full_backlog_drops_and_counts() {
        let mut p = ParamPacker::new(ParamPackConfig {
            backlog: 3,
            ..ParamPackConfig::for_rate(3000)
        });
        for i in 0..4 {
            p.push(ms(0), 1, 1, value(&format!("P{i}"), i));
        }
        assert_eq!((p.waiting(), p.stats().dropped), (3, 1));
        // ArduPilot's echo: index 65535, matched by name
        p.answered(
            1,
            1,
            &ParamValue {
                index: u16::MAX,
                ..value("P1", 0)
            },
        );
        // PX4's read: by index
        p.answered(1, 1, &value("OTHER", 2));
        assert_eq!((p.waiting(), p.stats().superseded), (1, 2));
    }

    #[test]
    fn frames_leave_at_the_pace_of_the_budget() {
        let mut p = ParamPacker::new(ParamPackConfig::for_rate(250));
        for i in 0..40 {
            p.push(ms(0), 1, 1, value(&format!("PARAM_{i}"), i));
        }
        let (_, f) = p.poll(ms(0)).expect("full");
        // 125 bytes at 250 B/s: the next after half a second
        p.charge(ms(0), 125);
        assert_eq!(p.poll(ms(499)), None);
        assert_eq!(p.poll_timeout(), Some(ms(500)));
        assert!(p.poll(ms(500)).is_some());
        assert!(usize::from(f.values) > 10, "{}", f.values);
    }

    #[test]
    fn a_list_asked_for_again_while_waiting_is_not_sent_twice() {
        let mut p = ParamPacker::new(ParamPackConfig::for_rate(250));
        for i in 0..10 {
            p.push(ms(0), 1, 1, value(&format!("P{i}"), i));
        }
        // the ground asked again: the autopilot streams it all again, one value changed
        for i in 0..10 {
            let mut v = value(&format!("P{i}"), i);
            if i == 4 {
                v.value = 7.0f32.to_le_bytes();
            }
            p.push(ms(50), 1, 1, v);
        }
        assert_eq!((p.waiting(), p.stats().replaced), (10, 10));
        let (_, f) = p.poll(ms(100)).expect("due");
        let values = super::super::pack::unpack(&f).unwrap();
        assert_eq!(values.len(), 10);
        assert_eq!(values[4].value, 7.0f32.to_le_bytes(), "the newer value");
        // and once sent, the same index is taken again
        p.push(ms(600), 1, 1, value("P4", 4));
        assert_eq!(p.waiting(), 1);
    }

    /// Real ArduCopter tells of its calibrations at boot with index 65535 while a list streams:
    /// packed, such a value cut the list's frames short and, at the router, made the list
    /// look complete (its progress 65535), so every read by index went to the radio.
    #[test]
    fn a_value_told_with_index_65535_is_no_part_of_the_list() {
        let mut p = ParamPacker::new(ParamPackConfig::for_rate(3000));
        assert!(p.push(ms(0), 1, 1, value("A", 0)));
        let told = ParamValue {
            index: u16::MAX,
            ..value("INS_GYROFFS_X", 0)
        };
        assert!(!p.push(ms(0), 1, 1, told), "goes as it came");
        assert!(p.push(ms(0), 1, 1, value("B", 1)));
        let (_, f) = p.poll(ms(100)).expect("due");
        assert_eq!(f.values, 2);
    }

    #[test]
    fn frame_size_follows_the_budget() {
        assert_eq!(ParamPackConfig::for_rate(250).data_bytes, 94);
        assert_eq!(ParamPackConfig::for_rate(2400).data_bytes, MAX_DATA);
        assert_eq!(ParamPackConfig::for_rate(10).data_bytes, MAX_VALUE_BYTES);
    }
}
