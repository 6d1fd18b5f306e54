//! Bridge side: periodic flight-controller messages and the bridge's link-quality reports in,
//! `MAVLORA_COMPACT` frames out.

use crate::time::Duration;
use std::collections::VecDeque;
use tracing::debug;

use crate::dialect::{GLOBAL_POSITION_INT_DATA, LINK_QUALITY_DATA, MavMessage};
use crate::time::Instant;
use crate::wire::ids;

use super::codec::{
    self, AirPart, CompactFrame, GpsPart, HeartbeatPart, MissionPart, Positions, Sample, Status,
    SysPart, round_div,
};

/// Message ids the compactor replaces on the radio (the heartbeat: of the autopilot).
pub const REPLACED_IDS: [u32; 7] = [
    ids::HEARTBEAT,
    ids::CURRENT_MODE,
    ids::SYS_STATUS,
    ids::GPS_RAW_INT,
    ids::GLOBAL_POSITION_INT,
    ids::MISSION_CURRENT,
    ids::VFR_HUD,
];

/// `MAV_MODE_FLAG_SAFETY_ARMED` in a HEARTBEAT's base_mode.
const ARMED: u8 = 0x80;

/// Most samples one frame carries.
pub const MAX_BATCH_SAMPLES: usize = codec::MAX_SAMPLES;

/// A change of mode, arming or state (or the autopilot's heartbeat lost or back) goes in this
/// many frames, [`URGENT_SPACING`] apart, the first at once: the ground must see it within
/// 0.5 s, also when one frame is lost. Spaced so that the copies leave in different radio
/// packets (SiK sends each direction's frames in windows 118 ms apart).
pub const URGENT_COPIES: u32 = 3;

/// See [`URGENT_COPIES`].
pub const URGENT_SPACING: Duration = Duration::from_millis(150);

/// After its copies, an urgent change still rides in every frame for this long (two more
/// frames at the default batching, at no frame's cost of its own): a fade that took all three
/// copies must not leave the ground showing the old mode until the periodic status.
pub const URGENT_FOLLOW: Duration = Duration::from_secs(5);

/// The autopilot's HEARTBEAT missing this long: the status says it has none (it sends one a
/// second; three missed is a lost autopilot, as the bridge's reboot detection counts it).
pub const HEARTBEAT_STALE: Duration = Duration::from_secs(3);

/// Other status changes (fix type, mission item, vehicle type) ride the next frame, at most
/// one such status per this long: a mission of short legs or a flapping fix must not cost a
/// status section per frame (at most ~5 B/s). Sensor health and battery go with the periodic
/// status only: health bits that flicker would otherwise do the same.
pub const STATUS_CHANGE_MIN: Duration = Duration::from_secs(5);

/// A position whose `time_boot_ms` is this much or more behind the newest is a rebooted
/// autopilot's (as the bridge counts a reboot); less, it is an older sample: no news.
const REBOOT_BACK_MS: u32 = 1_000;

/// VFR_HUD's airspeed rides in a frame when it moved this much (cm/s) since the last sent,
/// and with every status; the ground keeps the last (`VFR_HUD` is shown to a few m/s, and a
/// frame's bytes decide the duty cycle).
pub const AIRSPEED_DEADBAND_CMS: i32 = 50;

/// See [`AIRSPEED_DEADBAND_CMS`]: throttle, %.
pub const THROTTLE_DEADBAND: u16 = 5;

/// A change of the altitude offset (mean sea level minus home) this large, dm, starts a new
/// batch; smaller ones within a batch take its newest sample's.
const OFFSET_STEP_DM: u32 = 10;

/// Settings of a [`Compactor`] (a profile's `[compact]` table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompactConfig {
    /// Position samples per second (the paper's need: 3 Hz, ≤ 3.4 m between updates at 10 m/s).
    pub sample_hz: f64,
    /// Samples per frame, 1..=[`MAX_BATCH_SAMPLES`]: a full batch is sent at once.
    pub batch_samples: usize,
    /// A batch that is not full is sent this long after its first sample (bounds latency);
    /// also the longest a status change of no urgency or a link report waits for a batch.
    pub batch_period: Duration,
    /// The status rides along at least this often (battery, satellites), and at once on a
    /// change of mode, arming or state.
    pub status_period: Duration,
    /// Frames wait this long after the first of them is ready and then leave together, so
    /// that they share one radio packet: on LoRa each packet pays ~30 ms of preamble and
    /// header against a duty-cycle rule. Zero (the default) sends each frame when it is ready.
    /// Adds up to this much position latency.
    pub coalesce: Duration,
    /// How often the bridge asks the autopilot for its mode and arming (HEARTBEAT, which
    /// ArduPilot streams faster when asked, and CURRENT_MODE, which PX4 does: PX4 keeps its
    /// HEARTBEAT at 1 Hz). At 1 Hz a change reached the bridge up to 1 s late, and the ground
    /// showed it 0.7-1 s after the vehicle's own link did (the `sitl` suite, limit 0.5 s).
    /// Costs the flight controller's link ~20 B a message, never the radio's.
    pub state_hz: f64,
}

impl Default for CompactConfig {
    fn default() -> Self {
        Self {
            // Three samples every second: a sample is at most 2/3 s old when its frame
            // leaves, so the ground's position age stays under 1 s at the 95th percentile
            // (six every 2 s gave 1.7 s). Each frame pays 25 bytes of framing and signature
            // on a signed radio; the status and the link report ride in these frames rather
            // than in frames of their own, so a second's frame is ~55 bytes and compact
            // telemetry ~60 B/s in all, under 10 % of LoRa SF7 (68 B/s; docs/measurements.md).
            sample_hz: 3.0,
            batch_samples: 3,
            batch_period: Duration::from_secs(1),
            status_period: Duration::from_secs(10),
            coalesce: Duration::ZERO,
            // A change seen within 0.2 s leaves 0.3 s of the 0.5 s for the radio.
            state_hz: 5.0,
        }
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CompactStats {
    /// Standard messages taken in (and so kept off the radio).
    pub absorbed: u64,
    /// Frames carrying positions.
    pub batches: u64,
    /// Frames carrying the status.
    pub statuses: u64,
    /// Frames carrying a link-quality report.
    pub link_reports: u64,
    /// Bytes the link-quality reports took in those frames (what link monitoring costs the
    /// downlink in compact mode: the reports pay no framing of their own).
    pub link_bytes: u64,
    /// Compact frames made.
    pub frames: u64,
}

/// Sans-IO compactor: feed it decoded flight-controller messages with
/// [`observe`](Self::observe) and the bridge's link-quality reports with
/// [`link_report`](Self::link_report), take compact messages with [`poll`](Self::poll) and
/// wake it at [`poll_timeout`](Self::poll_timeout).
#[derive(Debug)]
pub struct Compactor {
    config: CompactConfig,
    samples: Vec<Sample>,
    batch_started: Option<Instant>,
    /// The vehicle's `time_boot_ms` from which the next sample is due.
    next_sample_due: Option<u32>,
    /// `time_boot_ms` of the newest position seen (sampled or not).
    last_position_ms: Option<u32>,
    /// The newest position sampled: velocity, heading and the altitude offset of a batch.
    newest: Option<GLOBAL_POSITION_INT_DATA>,
    /// The autopilot's latest VFR_HUD (airspeed, throttle), and when it came.
    air: Option<(AirPart, Instant)>,
    /// The air data last sent.
    air_sent: Option<AirPart>,
    /// What the autopilot said, each part once it said it.
    status: Status,
    /// When the autopilot's last HEARTBEAT came.
    heartbeat_at: Option<Instant>,
    /// The status as last sent.
    sent_status: Option<Status>,
    /// Frames still to carry an urgent change, and when the next of them goes.
    urgent_left: u32,
    next_urgent: Option<Instant>,
    /// Frames carry the status until then (see [`URGENT_FOLLOW`]).
    follow_until: Option<Instant>,
    /// A status waits for the next frame (a change of no urgency, or the period), since.
    status_wanted: Option<Instant>,
    /// When the last status of no urgency went.
    last_change: Option<Instant>,
    /// A change of no urgency waits for [`STATUS_CHANGE_MIN`] after the last.
    change_held: bool,
    /// When the periodic status is next due.
    next_status: Option<Instant>,
    /// A link report waiting for the next frame, and since when.
    link: Option<(LINK_QUALITY_DATA, Instant)>,
    last_sent: Option<Instant>,
    /// Frames made, each with whether it carries a change at once (an urgent copy).
    out: VecDeque<(MavMessage, bool)>,
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
            last_position_ms: None,
            newest: None,
            air: None,
            air_sent: None,
            status: Status::default(),
            heartbeat_at: None,
            sent_status: None,
            urgent_left: 0,
            next_urgent: None,
            follow_until: None,
            status_wanted: None,
            last_change: None,
            change_held: false,
            next_status: None,
            link: None,
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

    /// The settings.
    pub fn config(&self) -> &CompactConfig {
        &self.config
    }

    /// Takes in one message from the flight controller's autopilot. Returns whether the
    /// message is one the compact frames replace (the caller keeps it off the radio).
    pub fn observe(&mut self, msg: &MavMessage, now: Instant) -> bool {
        let s = &mut self.status;
        match msg {
            MavMessage::HEARTBEAT(hb) => {
                s.heartbeat = Some(HeartbeatPart {
                    mavtype: hb.mavtype as u32 as u8,
                    autopilot: hb.autopilot as u32 as u8,
                    base_mode: hb.base_mode.bits(),
                    custom_mode: hb.custom_mode,
                    system_status: hb.system_status as u32 as u8,
                });
                self.heartbeat_at = Some(now);
            }
            // PX4's mode, between its 1 Hz HEARTBEATs; the arming still comes from those.
            // Before the first HEARTBEAT names the vehicle there is nothing to change.
            MavMessage::CURRENT_MODE(m) => {
                if let Some(h) = &mut s.heartbeat {
                    h.custom_mode = m.custom_mode;
                }
            }
            MavMessage::SYS_STATUS(st) => {
                s.sys = Some(SysPart {
                    sensors_present: st.onboard_control_sensors_present.bits(),
                    sensors_enabled: st.onboard_control_sensors_enabled.bits(),
                    sensors_health: st.onboard_control_sensors_health.bits(),
                    voltage_battery: st.voltage_battery,
                    current_battery: st.current_battery,
                    battery_remaining: st.battery_remaining,
                    load: st.load,
                });
            }
            MavMessage::GPS_RAW_INT(gps) => {
                s.gps = Some(GpsPart {
                    fix_type: gps.fix_type as u32 as u8,
                    satellites_visible: gps.satellites_visible,
                    eph: gps.eph,
                    epv: gps.epv,
                });
            }
            MavMessage::MISSION_CURRENT(mc) => {
                s.mission = Some(MissionPart {
                    seq: mc.seq,
                    total: mc.total,
                    state: mc.mission_state as u32 as u8,
                    mode: mc.mission_mode,
                });
            }
            MavMessage::GLOBAL_POSITION_INT(pos) => self.sample(pos, now),
            MavMessage::VFR_HUD(hud) => {
                let airspeed = f64::from(hud.airspeed) * 100.0;
                self.air = airspeed.is_finite().then(|| {
                    let part = AirPart {
                        // A million cm/s is no aircraft's; the bound keeps the field at 3 bytes.
                        airspeed_cms: airspeed.round().clamp(-1e6, 1e6) as i32,
                        throttle: hud.throttle,
                    };
                    (part, now)
                });
            }
            _ => return false,
        }
        self.stats.absorbed += 1;
        true
    }

    /// The bridge's link-quality report: it rides in the next frame (within a batch period),
    /// so it pays no frame of its own. A newer report replaces one still waiting.
    pub fn link_report(&mut self, report: LINK_QUALITY_DATA, now: Instant) {
        let since = self.link.as_ref().map_or(now, |(_, t)| *t);
        self.link = Some((report, since));
    }

    fn sample(&mut self, pos: &GLOBAL_POSITION_INT_DATA, now: Instant) {
        // Slots on the vehicle's clock, not on arrival: an autopilot sending at the sample
        // rate (ArduPilot asked for 3 Hz) reaches the bridge with the host's jitter, tens of
        // ms on a loaded machine, and a sample that came early lost its slot (670 ms gaps,
        // 2.83 Hz at the ground in a CI run) while its own clock said 330 ms.
        let interval = (1000.0 / self.config.sample_hz).round() as u32;
        let t = pos.time_boot_ms;
        let due = match (self.next_sample_due, self.last_position_ms) {
            // the same sample again, or an older one: nothing new
            (_, Some(last)) if t == last || (t < last && last - t < REBOOT_BACK_MS) => return,
            // the clock went back (a reboot) or jumped a minute on: start again
            (Some(due), Some(last)) if t > last && t - last < 60_000 => due,
            _ => t,
        };
        self.last_position_ms = Some(t);
        // A sample a little early counts as on time: from a 4 Hz autopilot every fourth
        // sample falls on a 3 Hz slot, and with its clock's jitter it comes a few ms before
        // the slot half of the time; refused, it costs the slot (2.85 Hz instead of 3). An
        // eighth of an interval, far less than the 1/12 s between the two rates.
        if t.saturating_add(interval / 8) < due {
            return;
        }
        // Same catch-up rule as the radio filter: 5 Hz in gives 3 Hz out, not 2.5.
        self.next_sample_due = Some((due + interval).max(t + interval / 2));
        let sample = Sample {
            time_boot_ms: pos.time_boot_ms,
            lat: pos.lat,
            lon: pos.lon,
            rel_dm: round_div(pos.relative_alt.into(), 100) as i32,
        };
        // A clock that went back (a reboot) or jumped a minute on starts a new batch: a batch's
        // times are steps of 10 ms from its first, each small.
        if let (Some(first), Some(last)) = (self.samples.first(), self.samples.last())
            && (sample.time_boot_ms.wrapping_sub(last.time_boot_ms) > 60_000
                || sample.time_boot_ms.wrapping_sub(first.time_boot_ms) > 60_000
                || sample.time_boot_ms < last.time_boot_ms)
        {
            self.flush_batch(now, false);
        }
        // The altitude offset is the batch's (its newest sample's): one that moved a metre or
        // more (a new home) starts a new batch. Not less: an offset that sits on a rounding
        // boundary flickers by a decimetre and would cut every batch short.
        if self
            .newest
            .as_ref()
            .is_some_and(|n| alt_offset_dm(n).abs_diff(alt_offset_dm(pos)) >= OFFSET_STEP_DM)
            && !self.samples.is_empty()
        {
            self.flush_batch(now, false);
        }
        self.newest = Some(pos.clone());
        if self.samples.is_empty() {
            self.batch_started = Some(now);
        }
        self.samples.push(sample);
        if self.samples.len() >= self.config.batch_samples.clamp(1, MAX_BATCH_SAMPLES) {
            self.flush_batch(now, false);
        }
    }

    /// The status to send: the autopilot's heartbeat only while it keeps coming.
    fn current_status(&self, now: Instant) -> Status {
        let fresh = self.heartbeat_at.is_some_and(|t| now < t + HEARTBEAT_STALE);
        Status {
            heartbeat: self.status.heartbeat.filter(|_| fresh),
            ..self.status
        }
    }

    /// Whether the autopilot's heartbeat is fresh.
    fn heartbeat_fresh(&self, now: Instant) -> bool {
        self.current_status(now).heartbeat.is_some()
    }

    /// Compares the status with the one last sent: `Some(true)` a change the ground must see
    /// at once (mode, arming, state, the heartbeat lost or back), `Some(false)` one that rides
    /// the next frame.
    fn change(&self, now: Instant) -> Option<bool> {
        let s = self.current_status(now);
        if s == Status::default() {
            return None;
        }
        let Some(last) = &self.sent_status else {
            return Some(true);
        };
        // Urgent: what a pilot acts on. The rest of base_mode follows the mode (PX4's
        // CURRENT_MODE brings the mode before the HEARTBEAT brings its flags: one change).
        let mode = |h: &Option<HeartbeatPart>| {
            h.map(|h| (h.base_mode & ARMED, h.custom_mode, h.system_status))
        };
        if mode(&s.heartbeat) != mode(&last.heartbeat) {
            return Some(true);
        }
        let kind = |h: &Option<HeartbeatPart>| h.map(|h| (h.mavtype, h.autopilot, h.base_mode));
        let fix = |g: &Option<GpsPart>| g.map(|g| g.fix_type);
        let mission = |m: &Option<MissionPart>| m.map(|m| (m.seq, m.total, m.state, m.mode));
        (kind(&s.heartbeat) != kind(&last.heartbeat)
            || fix(&s.gps) != fix(&last.gps)
            || mission(&s.mission) != mission(&last.mission)
            // a part the autopilot sent for the first time
            || s.sys.is_some() != last.sys.is_some())
        .then_some(false)
    }

    /// Looks at what is due at `now`: urgent copies, a status or link report that waited
    /// long enough, the keep-alive, a batch that waited its period.
    fn tick(&mut self, now: Instant) {
        self.change_held = false;
        match self.change(now) {
            Some(true) => {
                let h = self.status.heartbeat;
                debug!(%now, mode = ?h.map(|h| h.custom_mode), base_mode = ?h.map(|h| h.base_mode), "status change, sent at once");
                self.urgent_left = URGENT_COPIES;
                self.next_urgent = Some(now);
                self.follow_until = Some(now + URGENT_FOLLOW);
                self.sent_status = Some(self.current_status(now));
            }
            Some(false) => {
                if self
                    .last_change
                    .is_none_or(|t| now >= t + STATUS_CHANGE_MIN)
                {
                    self.status_wanted.get_or_insert(now);
                    self.last_change = Some(now);
                    self.sent_status = Some(self.current_status(now));
                } else {
                    self.change_held = true;
                }
            }
            None => {}
        }
        if self.next_status.is_some_and(|t| now >= t) {
            self.status_wanted.get_or_insert(now);
        }
        if self.next_urgent.is_some_and(|t| now >= t) {
            self.flush_batch(now, true);
            return;
        }
        let wait = self.config.batch_period;
        let batch_waited = self.batch_started.is_some_and(|t| now >= t + wait);
        let status_waited = self.status_wanted.is_some_and(|t| now >= t + wait);
        let link_waited = self.link.as_ref().is_some_and(|(_, t)| now >= *t + wait);
        // Keep-alive: the router makes a HEARTBEAT of every frame with a status or
        // positions, so without positions (no GPS on the bench) a status goes after 1.5 batch
        // periods of silence; the half period of slack keeps batches that close a little late
        // on a real clock from drawing one each.
        let silent = self.heartbeat_fresh(now)
            && self.out.is_empty()
            && self.last_sent.is_none_or(|t| now >= t + self.keep_alive());
        if silent {
            self.status_wanted.get_or_insert(now);
        }
        if batch_waited || status_waited || link_waited || silent {
            self.flush_batch(now, false);
        }
    }

    /// Makes a frame of what is waiting: the samples, the status if it is wanted (or `urgent`),
    /// the link report.
    fn flush_batch(&mut self, now: Instant, urgent: bool) {
        let following = self.follow_until.is_some_and(|t| now < t);
        let with_status =
            urgent || self.urgent_left > 0 || following || self.status_wanted.is_some();
        let status = with_status.then(|| self.current_status(now));
        let air = self
            .air
            .filter(|(_, at)| now < *at + HEARTBEAT_STALE)
            .map(|(a, _)| a)
            .filter(|a| {
                with_status
                    || self.air_sent.is_none_or(|s| {
                        (a.airspeed_cms - s.airspeed_cms).abs() >= AIRSPEED_DEADBAND_CMS
                            || a.throttle.abs_diff(s.throttle) >= THROTTLE_DEADBAND
                    })
            });
        let positions = (!self.samples.is_empty()).then(|| {
            let newest = self.newest.clone().unwrap_or_default();
            Positions {
                samples: std::mem::take(&mut self.samples),
                alt_offset_dm: alt_offset_dm(&newest),
                vx: newest.vx,
                vy: newest.vy,
                vz: newest.vz,
                hdg: newest.hdg,
                air,
            }
        });
        if let Some(p) = &positions
            && p.air.is_some()
        {
            self.air_sent = p.air;
        }
        self.batch_started = None;
        let link = self.link.take().map(|(l, _)| l);
        if positions.is_none() && status.is_none() && link.is_none() {
            return;
        }
        let frame = CompactFrame {
            positions,
            status,
            link,
        };
        let Ok(data) = frame.encode() else {
            // Cannot happen with what observe() takes in (the codec's worst case fits); a
            // frame that did not fit would be dropped rather than sent cut.
            debug_assert!(false, "compact frame does not fit: {frame:?}");
            return;
        };
        if frame.positions.is_some() {
            self.stats.batches += 1;
        }
        if let Some(s) = frame.status {
            self.stats.statuses += 1;
            self.sent_status = Some(s);
            self.status_wanted = None;
            self.next_status = Some(now + self.config.status_period);
            if self.urgent_left > 0 {
                self.urgent_left -= 1;
                self.next_urgent = (self.urgent_left > 0).then(|| now + URGENT_SPACING);
            }
        }
        if frame.link.is_some() {
            self.stats.link_reports += 1;
            let without = CompactFrame {
                link: None,
                ..frame.clone()
            };
            let len = |f: &CompactFrame| f.encoded_len().unwrap_or(0) as u64;
            self.stats.link_bytes += len(&frame).saturating_sub(len(&without));
        }
        self.stats.frames += 1;
        if urgent {
            // Goes at once, and takes any coalesced group with it.
            self.releasing = true;
        }
        if self.out.is_empty() {
            self.held_since = Some(now);
        }
        self.out
            .push_back((MavMessage::MAVLORA_COMPACT(data), urgent));
    }

    /// The next compact message due at `now`, if any.
    pub fn poll(&mut self, now: Instant) -> Option<MavMessage> {
        self.poll_urgency(now).map(|(msg, _)| msg)
    }

    /// [`poll`](Self::poll), and whether the message is a copy of a change of mode, arming or
    /// state made at once (the bridge sends those with the commands: they are a command's
    /// visible effect).
    pub fn poll_urgency(&mut self, now: Instant) -> Option<(MavMessage, bool)> {
        self.tick(now);
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

    /// Silence after which a status goes as a keep-alive (see `tick`).
    fn keep_alive(&self) -> Duration {
        self.config.batch_period * 3 / 2
    }

    /// When [`poll`](Self::poll) next has something to do.
    pub fn poll_timeout(&self) -> Option<Instant> {
        if !self.out.is_empty() {
            if self.releasing {
                return self.last_sent.or(Some(Instant::ZERO));
            }
            let since = self.held_since.unwrap_or(Instant::ZERO);
            return Some(since + self.config.coalesce);
        }
        let wait = self.config.batch_period;
        // Each deadline only while it can still make something happen, so that none stays
        // in the past.
        let stale = self.heartbeat_at.map(|t| t + HEARTBEAT_STALE);
        let heartbeat_lost = stale.filter(|_| {
            self.sent_status
                .as_ref()
                .is_some_and(|s| s.heartbeat.is_some())
        });
        let keep_alive = self
            .last_sent
            .map_or(Some(Instant::ZERO), |t| Some(t + self.keep_alive()))
            .filter(|t| stale.is_some_and(|s| *t < s));
        [
            self.next_urgent,
            self.batch_started.map(|t| t + wait),
            self.status_wanted.map(|t| t + wait),
            self.link.as_ref().map(|(_, t)| *t + wait),
            self.next_status.filter(|_| self.status_wanted.is_none()),
            self.last_change
                .map(|t| t + STATUS_CHANGE_MIN)
                .filter(|_| self.change_held),
            keep_alive,
            heartbeat_lost,
        ]
        .into_iter()
        .flatten()
        .min()
    }
}

/// Altitude above mean sea level minus altitude above home, dm.
fn alt_offset_dm(pos: &GLOBAL_POSITION_INT_DATA) -> i32 {
    round_div(i64::from(pos.alt) - i64::from(pos.relative_alt), 100) as i32
}
