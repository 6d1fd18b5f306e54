//! The ground station's parameter download, as QGroundControl does it and as the rig's own
//! QGroundControl-like ground (`fixtures/sitl_gcs.py`, the `sitl` suite's `params` scenario)
//! does it: `PARAM_REQUEST_LIST` (sent again every second until a value comes), the values
//! taken by index as they come; once no new one came for 1 s, the missing ones read with
//! `PARAM_REQUEST_READ` by index, 10 outstanding, each sent again after 1 s, until all of
//! `param_count` are there. A `PARAM_SET` is sent again after 1 s, 5 sends at most, and its
//! echo is the first `PARAM_VALUE` with its name and value.
//!
//! Values are kept as the payload bytes that arrived, so a test can compare them with what the
//! autopilot holds byte for byte.

use std::collections::BTreeMap;

use mavlora::dialect::{
    MavMessage, MavParamType, PARAM_REQUEST_LIST_DATA, PARAM_REQUEST_READ_DATA, PARAM_SET_DATA,
};
use mavlora::{Duration, Instant};

/// Seconds without a new value before the missing ones are read one by one (the rig's
/// `--param-quiet`).
pub const PARAM_QUIET: Duration = Duration::from_secs(1);
/// A read by index (or a set) is sent again after this long.
pub const PARAM_RETRY: Duration = Duration::from_secs(1);
/// Reads by index outstanding at once.
pub const PARAM_OUTSTANDING: usize = 10;
/// Sends of one `PARAM_SET` at most.
pub const SET_TRIES: u32 = 5;
/// How often the ground station looks at its timers (its receive timeout).
const TICK: Duration = Duration::from_millis(50);

/// The autopilot the download talks to (system, component).
const VEHICLE: (u8, u8) = (1, 1);

/// What a download got.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamDownload {
    /// When the list was asked for.
    pub started: Instant,
    /// `param_count`, once a value said it.
    pub total: Option<u16>,
    /// The payload (zero-padded to 25 bytes) last received for each index.
    pub values: BTreeMap<u16, [u8; 25]>,
    /// When the last value that was new to the ground arrived.
    pub last_new: Instant,
    /// `PARAM_REQUEST_READ`s sent.
    pub rereads: u64,
    /// When every value was there (the last new one's arrival).
    pub done: Option<Instant>,
    rereading: bool,
    outstanding: BTreeMap<u16, Instant>,
    last_list: Instant,
    next_tick: Instant,
}

impl ParamDownload {
    /// Seconds from the request to the last missing value, once complete.
    pub fn seconds(&self) -> Option<f64> {
        self.done
            .map(|d| d.saturating_duration_since(self.started).as_secs_f64())
    }

    /// Values still missing (all of them before `param_count` is known).
    pub fn missing(&self) -> usize {
        self.total
            .map_or(usize::MAX, |n| usize::from(n) - self.values.len())
    }
}

/// One `PARAM_SET` and its echo.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSet {
    /// The parameter's name.
    pub name: [u8; 16],
    /// The value's payload bytes as sent (PX4's integers byte-wise: the caller's encoding).
    pub value: [u8; 4],
    /// Its type.
    pub param_type: MavParamType,
    /// First sent.
    pub first: Instant,
    /// Last sent.
    pub last: Instant,
    /// Sends so far.
    pub tries: u32,
    /// When its echo came.
    pub echo: Option<Instant>,
    /// Whether it was sent while a list was being downloaded.
    pub during_list: bool,
}

impl ParamSet {
    /// Seconds from the first send to the echo.
    pub fn echo_s(&self) -> Option<f64> {
        self.echo
            .map(|e| e.saturating_duration_since(self.first).as_secs_f64())
    }
}

/// The download and sets of one ground station.
#[derive(Debug, Default)]
pub struct GcsParams {
    /// The download, once started.
    pub download: Option<ParamDownload>,
    /// Every set, in order.
    pub sets: Vec<ParamSet>,
}

fn list_request() -> MavMessage {
    MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
        target_system: VEHICLE.0,
        target_component: VEHICLE.1,
    })
}

fn read_request(index: u16) -> MavMessage {
    MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        target_system: VEHICLE.0,
        target_component: VEHICLE.1,
        param_index: index as i16,
        ..Default::default()
    })
}

fn set_request(s: &ParamSet) -> MavMessage {
    MavMessage::PARAM_SET(PARAM_SET_DATA {
        target_system: VEHICLE.0,
        target_component: VEHICLE.1,
        param_id: s.name.into(),
        param_value: f32::from_le_bytes(s.value),
        param_type: s.param_type,
    })
}

impl GcsParams {
    /// Starts the download at `now`: the messages to send.
    pub fn start(&mut self, now: Instant) -> Vec<MavMessage> {
        self.download = Some(ParamDownload {
            started: now,
            total: None,
            values: BTreeMap::new(),
            last_new: now,
            rereads: 0,
            done: None,
            rereading: false,
            outstanding: BTreeMap::new(),
            last_list: now,
            next_tick: now + TICK,
        });
        vec![list_request()]
    }

    /// Sends `PARAM_SET` of `name` to `value` (its payload bytes) at `now`.
    pub fn set(
        &mut self,
        now: Instant,
        name: &str,
        value: [u8; 4],
        param_type: MavParamType,
    ) -> Vec<MavMessage> {
        let mut n = [0u8; 16];
        n[..name.len()].copy_from_slice(name.as_bytes());
        let during_list = self.download.as_ref().is_some_and(|d| d.done.is_none());
        let s = ParamSet {
            name: n,
            value,
            param_type,
            first: now,
            last: now,
            tries: 1,
            echo: None,
            during_list,
        };
        let msg = set_request(&s);
        self.sets.push(s);
        vec![msg]
    }

    /// A `PARAM_VALUE` from (`system`, `component`) with `payload`, at `now`.
    pub fn value(&mut self, now: Instant, from: (u8, u8), payload: &[u8]) {
        if from != VEHICLE || payload.len() > 25 {
            return;
        }
        let mut p = [0u8; 25];
        p[..payload.len()].copy_from_slice(payload);
        let name = &p[8..24];
        for s in &mut self.sets {
            if s.echo.is_none() && s.name == name && s.value == p[..4] {
                s.echo = Some(now);
            }
        }
        let Some(d) = &mut self.download else { return };
        let count = u16::from_le_bytes([p[4], p[5]]);
        let index = u16::from_le_bytes([p[6], p[7]]);
        if index >= count {
            return;
        }
        d.total = Some(count);
        d.outstanding.remove(&index);
        if d.values.insert(index, p).is_none() && d.done.is_none() {
            d.last_new = now;
            if d.values.len() == usize::from(count) {
                d.done = Some(now);
            }
        }
    }

    /// What is due at `now`: the messages to send.
    pub fn handle_timeout(&mut self, now: Instant) -> Vec<MavMessage> {
        let mut out = Vec::new();
        for s in &mut self.sets {
            if s.echo.is_none() && s.tries < SET_TRIES && now >= s.last + PARAM_RETRY {
                s.tries += 1;
                s.last = now;
                out.push(set_request(s));
            }
        }
        let Some(d) = &mut self.download else {
            return out;
        };
        if d.done.is_some() || now < d.next_tick {
            return out;
        }
        d.next_tick = now + TICK;
        let Some(total) = d.total else {
            if now >= d.last_list + PARAM_QUIET {
                d.last_list = now;
                out.push(list_request());
            }
            return out;
        };
        d.rereading |= now >= d.last_new + PARAM_QUIET;
        if !d.rereading {
            return out;
        }
        for (index, sent) in d.outstanding.iter_mut() {
            if now >= *sent + PARAM_RETRY {
                *sent = now;
                d.rereads += 1;
                out.push(read_request(*index));
            }
        }
        let room = PARAM_OUTSTANDING.saturating_sub(d.outstanding.len());
        let missing: Vec<u16> = (0..total)
            .filter(|i| !d.values.contains_key(i) && !d.outstanding.contains_key(i))
            .take(room)
            .collect();
        for index in missing {
            d.outstanding.insert(index, now);
            d.rereads += 1;
            out.push(read_request(index));
        }
        out
    }

    /// When [`handle_timeout`](Self::handle_timeout) is next needed.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let sets = self
            .sets
            .iter()
            .filter(|s| s.echo.is_none() && s.tries < SET_TRIES)
            .map(|s| s.last + PARAM_RETRY);
        let download = self
            .download
            .as_ref()
            .filter(|d| d.done.is_none())
            .map(|d| d.next_tick);
        sets.chain(download).min()
    }
}
