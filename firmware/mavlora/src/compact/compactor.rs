//! Bridge side: periodic flight-controller messages in, compact frames out.

use crate::time::Duration;
use std::collections::VecDeque;

use crate::dialect::{
    GLOBAL_POSITION_INT_DATA, MAVLORA_POSITION_BATCH_DATA, MAVLORA_STATUS_DATA, MavMessage,
};
use crate::time::Instant;
use crate::wire::ids;

/// Message ids the compactor replaces on the radio (the heartbeat: of the autopilot).
pub const REPLACED_IDS: [u32; 6] = [
    ids::HEARTBEAT,
    ids::SYS_STATUS,
    ids::GPS_RAW_INT,
    ids::GLOBAL_POSITION_INT,
    ids::MISSION_CURRENT,
    ids::VFR_HUD,
];

/// Most samples one `MAVLORA_POSITION_BATCH` carries: sample 0 and its five deltas.
pub const MAX_BATCH_SAMPLES: usize = 6;

/// Settings of a [`Compactor`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompactConfig {
    /// Position samples per second (the paper's need: 3 Hz, ≤ 3.4 m between updates at 10 m/s).
    pub sample_hz: f64,
    /// Samples per batch frame, 1..=[`MAX_BATCH_SAMPLES`]: a full batch is sent at once.
    pub batch_samples: usize,
    /// A batch that is not full is sent this long after its first sample (bounds latency).
    pub batch_period: Duration,
    /// A status frame goes at least this often, and immediately on a change of mode, arming,
    /// state, fix type or mission item.
    pub status_period: Duration,
    /// Frames wait this long after the first of them is ready and then leave together, so
    /// that they share one radio packet: on LoRa each packet pays ~30 ms of preamble and
    /// header, which decides whether compact telemetry fits a 10 % duty cycle. Zero (the
    /// default) sends each frame when it is ready. Adds up to this much position latency.
    pub coalesce: Duration,
}

impl Default for CompactConfig {
    fn default() -> Self {
        Self {
            // Six samples every 2 s rather than three every second: each frame pays 25 bytes
            // of framing and signature on a signed radio, so one frame a second alone is
            // 53 B/s, over the 50 B/s compact telemetry may use in all; one every 2 s is
            // 34 B/s. Lag grows to ~2 s, within the bound of 1.5 batch periods.
            sample_hz: 3.0,
            batch_samples: MAX_BATCH_SAMPLES,
            batch_period: Duration::from_secs(2),
            status_period: Duration::from_secs(10),
            coalesce: Duration::ZERO,
        }
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CompactStats {
    /// Standard messages taken in (and so kept off the radio).
    pub absorbed: u64,
    /// Position batches produced.
    pub batches: u64,
    /// Status frames produced.
    pub statuses: u64,
}

#[derive(Debug, Clone, Copy)]
struct Sample {
    time_boot_ms: u32,
    lat: i32,
    lon: i32,
    rel_dm: i16,
}

/// Sans-IO compactor: feed it decoded flight-controller messages with
/// [`observe`](Self::observe), take compact messages with [`poll`](Self::poll) and wake it at
/// [`poll_timeout`](Self::poll_timeout).
#[derive(Debug)]
pub struct Compactor {
    config: CompactConfig,
    samples: Vec<Sample>,
    batch_started: Option<Instant>,
    next_sample_due: Option<Instant>,
    newest: Option<GLOBAL_POSITION_INT_DATA>,
    status: MAVLORA_STATUS_DATA,
    heartbeat_seen: bool,
    last_sent_status: Option<MAVLORA_STATUS_DATA>,
    next_status: Option<Instant>,
    last_sent: Option<Instant>,
    out: VecDeque<MavMessage>,
    /// When the first frame now in `out` was ready (coalescing).
    held_since: Option<Instant>,
    /// A coalesced group is leaving: hand out the rest of `out` without waiting.
    releasing: bool,
    stats: CompactStats,
}

impl Compactor {
    /// A compactor with nothing observed.
    pub fn new(config: CompactConfig) -> Self {
        Self {
            config,
            samples: Vec::with_capacity(MAX_BATCH_SAMPLES),
            batch_started: None,
            next_sample_due: None,
            newest: None,
            status: MAVLORA_STATUS_DATA {
                voltage_battery: u16::MAX,
                mission_seq: u16::MAX,
                satellites_visible: u8::MAX,
                battery_remaining: -1,
                ..MAVLORA_STATUS_DATA::default()
            },
            heartbeat_seen: false,
            last_sent_status: None,
            next_status: None,
            last_sent: None,
            out: VecDeque::new(),
            held_since: None,
            releasing: false,
            stats: CompactStats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> CompactStats {
        self.stats
    }

    /// Takes in one message from the flight controller's autopilot. Returns whether the
    /// message is one the compact frames replace (the caller keeps it off the radio).
    pub fn observe(&mut self, msg: &MavMessage, now: Instant) -> bool {
        let s = &mut self.status;
        match msg {
            MavMessage::HEARTBEAT(hb) => {
                s.mavtype = hb.mavtype;
                s.autopilot = hb.autopilot;
                s.base_mode = hb.base_mode;
                s.custom_mode = hb.custom_mode;
                s.system_status = hb.system_status;
                self.heartbeat_seen = true;
            }
            MavMessage::SYS_STATUS(st) => {
                s.voltage_battery = st.voltage_battery;
                s.battery_remaining = st.battery_remaining;
            }
            MavMessage::GPS_RAW_INT(gps) => {
                s.fix_type = gps.fix_type;
                s.satellites_visible = gps.satellites_visible;
            }
            MavMessage::MISSION_CURRENT(mc) => s.mission_seq = mc.seq,
            MavMessage::GLOBAL_POSITION_INT(pos) => {
                s.alt_offset = round_div(i64::from(pos.alt) - i64::from(pos.relative_alt), 100)
                    .clamp(i16::MIN.into(), i16::MAX.into()) as i16;
                self.sample(pos, now);
            }
            MavMessage::VFR_HUD(_) => {}
            _ => return false,
        }
        self.stats.absorbed += 1;
        true
    }

    fn sample(&mut self, pos: &GLOBAL_POSITION_INT_DATA, now: Instant) {
        let interval = Duration::from_secs_f64(1.0 / self.config.sample_hz);
        let due = self.next_sample_due.unwrap_or(now);
        // A sample a little early counts as on time: from a 4 Hz autopilot every fourth
        // sample falls on a 3 Hz slot, and with its clock's jitter it comes a few ms before
        // the slot half of the time; refused, it costs the slot (2.85 Hz instead of 3 over
        // ptys). An eighth of an interval, far less than the 1/12 s between the two rates.
        if now + interval / 8 < due {
            return;
        }
        // Same catch-up rule as the radio filter: 5 Hz in gives 3 Hz out, not 2.5.
        self.next_sample_due = Some((due + interval).max(now + interval / 2));
        self.newest = Some(pos.clone());
        let sample = Sample {
            time_boot_ms: pos.time_boot_ms,
            lat: pos.lat,
            lon: pos.lon,
            rel_dm: round_div(pos.relative_alt.into(), 100).clamp(i16::MIN.into(), i16::MAX.into())
                as i16,
        };
        if let Some(first) = self.samples.first()
            && !fits(first, &sample)
        {
            self.flush_batch(now);
        }
        if self.samples.is_empty() {
            self.batch_started = Some(now);
        }
        self.samples.push(sample);
        if self.samples.len() >= self.config.batch_samples.clamp(1, MAX_BATCH_SAMPLES) {
            self.flush_batch(now);
        }
    }

    fn flush_batch(&mut self, now: Instant) {
        let Some((first, rest)) = self.samples.split_first() else {
            return;
        };
        let mut batch = MAVLORA_POSITION_BATCH_DATA {
            time_boot_ms: first.time_boot_ms,
            lat: first.lat,
            lon: first.lon,
            relative_alt: first.rel_dm,
            count: self.samples.len() as u8,
            hdg: u16::MAX,
            ..MAVLORA_POSITION_BATCH_DATA::default()
        };
        for (i, s) in rest.iter().enumerate() {
            // `fits` checked every narrowing below
            batch.dlat[i] = (s.lat - first.lat) as i16;
            batch.dlon[i] = (s.lon - first.lon) as i16;
            batch.drelative_alt[i] = (s.rel_dm - first.rel_dm) as i8;
            batch.dt[i] = round_div(
                i64::from(s.time_boot_ms.wrapping_sub(first.time_boot_ms)),
                10,
            ) as u8;
        }
        if let Some(newest) = &self.newest {
            batch.hdg = newest.hdg;
            let speed = f64::from(newest.vx).hypot(f64::from(newest.vy));
            batch.groundspeed = (speed / 10.0).round().clamp(0.0, 255.0) as u8;
            batch.climb = (-f64::from(newest.vz) / 10.0).round().clamp(-127.0, 127.0) as i8;
        }
        self.samples.clear();
        self.batch_started = None;
        self.stats.batches += 1;
        self.enqueue(MavMessage::MAVLORA_POSITION_BATCH(batch), now);
    }

    fn enqueue(&mut self, msg: MavMessage, now: Instant) {
        if self.out.is_empty() {
            self.held_since = Some(now);
        }
        self.out.push_back(msg);
    }

    /// Whether the status changed in a way the ground must learn now.
    fn status_changed(&self) -> bool {
        let Some(last) = &self.last_sent_status else {
            return true;
        };
        let s = &self.status;
        s.base_mode != last.base_mode
            || s.custom_mode != last.custom_mode
            || s.system_status != last.system_status
            || s.fix_type != last.fix_type
            || s.mission_seq != last.mission_seq
    }

    /// The next compact message due at `now`, if any.
    pub fn poll(&mut self, now: Instant) -> Option<MavMessage> {
        if let Some(started) = self.batch_started
            && now >= started + self.config.batch_period
        {
            self.flush_batch(now);
        }
        if self.heartbeat_seen {
            let periodic = self.next_status.is_none_or(|t| now >= t);
            // Keep-alive: the router makes a HEARTBEAT of every compact frame, so without
            // position (no GPS on the bench) the status must go after a batch period of
            // silence, plus half a period of slack: batches close on their last sample, so
            // on a real clock they come a little later than `batch_period` apart, and a
            // keep-alive due at exactly one period added a status to most batches
            // (+10 B/s, found by the rig's real-time table_ii scenario).
            let silent =
                self.out.is_empty() && self.last_sent.is_none_or(|t| now >= t + self.keep_alive());
            let status_waiting = self
                .out
                .iter()
                .any(|m| matches!(m, MavMessage::MAVLORA_STATUS(_)));
            // Without coalescing a status never waits behind a batch: it goes on its own turn.
            let room = if self.config.coalesce.is_zero() {
                self.out.is_empty()
            } else {
                !status_waiting
            };
            if (periodic || silent || self.status_changed()) && room {
                self.last_sent_status = Some(self.status.clone());
                self.next_status = Some(now + self.config.status_period);
                self.stats.statuses += 1;
                self.enqueue(MavMessage::MAVLORA_STATUS(self.status.clone()), now);
            }
        }
        if !self.releasing
            && let Some(since) = self.held_since
            && now < since + self.config.coalesce
        {
            return None;
        }
        let Some(msg) = self.out.pop_front() else {
            self.releasing = false;
            self.held_since = None;
            return None;
        };
        self.releasing = !self.out.is_empty();
        if !self.releasing {
            self.held_since = None;
        }
        self.last_sent = Some(now);
        Some(msg)
    }

    /// Whether frames are held for coalescing (`coalesce` > 0).
    pub fn coalescing(&self) -> bool {
        !self.config.coalesce.is_zero()
    }

    /// Silence after which a status goes as a keep-alive (see `poll`).
    fn keep_alive(&self) -> Duration {
        self.config.batch_period * 3 / 2
    }

    /// When [`poll`](Self::poll) next has something to give.
    pub fn poll_timeout(&self) -> Option<Instant> {
        if !self.out.is_empty() {
            if self.releasing {
                return self.last_sent.or(Some(Instant::ZERO));
            }
            let since = self.held_since.unwrap_or(Instant::ZERO);
            return Some(since + self.config.coalesce);
        }
        let batch = self.batch_started.map(|t| t + self.config.batch_period);
        let status = self.heartbeat_seen.then(|| {
            let keep_alive = self
                .last_sent
                .map_or(Instant::ZERO, |t| t + self.keep_alive());
            let periodic = self.next_status.unwrap_or(Instant::ZERO);
            keep_alive.min(periodic)
        });
        [batch, status].into_iter().flatten().min()
    }
}

/// Whether `s` can ride in the batch that starts with `first`.
fn fits(first: &Sample, s: &Sample) -> bool {
    let in_i16 = |d: i64| (i64::from(i16::MIN)..=i64::from(i16::MAX)).contains(&d);
    in_i16(i64::from(s.lat) - i64::from(first.lat))
        && in_i16(i64::from(s.lon) - i64::from(first.lon))
        && (i16::from(i8::MIN)..=i16::from(i8::MAX))
            .contains(&(s.rel_dm.saturating_sub(first.rel_dm)))
        && round_div(
            i64::from(s.time_boot_ms.wrapping_sub(first.time_boot_ms)),
            10,
        ) <= 255
}

/// `n / d` rounded to nearest, halves away from zero.
pub(crate) fn round_div(n: i64, d: i64) -> i64 {
    if n >= 0 {
        (n + d / 2) / d
    } else {
        (n - d / 2) / d
    }
}
