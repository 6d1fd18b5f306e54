//! A flight controller that behaves like PX4 where it matters for the link: the "Normal"
//! stream profile, `SET_MESSAGE_INTERVAL`, and mission upload with 250 ms item retries
//! (PX4 issue #11078).

use std::collections::VecDeque;
use std::time::Duration;

use mavlink::MavlinkVersion;

use super::rng::SplitMix64;
use crate::dialect::{
    ATTITUDE_DATA, COMMAND_ACK_DATA, GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, GpsFixType,
    HEARTBEAT_DATA, MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA,
    MISSION_REQUEST_INT_DATA, MavAutopilot, MavCmd, MavMessage, MavMissionResult, MavModeFlag,
    MavResult, MavState, MavType, SYS_STATUS_DATA, VFR_HUD_DATA,
};
use crate::time::Instant;
use crate::wire::{FrameReader, OwnedFrame, Sender, known};

/// One stream of the profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamSpec {
    /// Message id.
    pub id: u32,
    /// Default rate.
    pub hz: f64,
    /// Payload length (base message, no extensions), for messages sent with filler payloads.
    pub payload_len: usize,
}

const fn s(id: u32, hz: f64, payload_len: usize) -> StreamSpec {
    StreamSpec {
        id,
        hz,
        payload_len,
    }
}

/// PX4's "Normal" MAVLink stream profile (rates from the brief; payload lengths from
/// common.xml without extensions).
pub const PX4_NORMAL: &[StreamSpec] = &[
    s(30, 15.0, 28), // ATTITUDE
    s(33, 5.0, 28),  // GLOBAL_POSITION_INT
    s(65, 5.0, 42),  // RC_CHANNELS
    s(74, 4.0, 20),  // VFR_HUD
    s(83, 2.0, 37),  // ATTITUDE_TARGET
    s(85, 1.5, 51),  // POSITION_TARGET_LOCAL_NED
    s(141, 1.0, 32), // ALTITUDE
    s(24, 1.0, 30),  // GPS_RAW_INT
    s(1, 1.0, 31),   // SYS_STATUS
    s(245, 1.0, 2),  // EXTENDED_SYS_STATE
    s(32, 1.0, 28),  // LOCAL_POSITION_NED
    s(62, 1.0, 26),  // NAV_CONTROLLER_OUTPUT
    s(36, 1.0, 21),  // SERVO_OUTPUT_RAW
    s(147, 0.5, 36), // BATTERY_STATUS
    s(242, 0.5, 52), // HOME_POSITION
    s(230, 0.5, 42), // ESTIMATOR_STATUS
    s(241, 0.1, 32), // VIBRATION
    s(0, 1.0, 9),    // HEARTBEAT
];

#[derive(Debug)]
struct Stream {
    spec: StreamSpec,
    hz: f64,
    next: Instant,
}

#[derive(Debug)]
struct Upload {
    peer: (u8, u8),
    count: u16,
    items: Vec<MISSION_ITEM_INT_DATA>,
    requested_at: Instant,
    last_progress: Instant,
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Px4Stats {
    /// Item requests sent (retries included).
    pub item_requests: u64,
    /// Items received that were already stored (duplicates).
    pub duplicate_items: u64,
    /// Missions accepted.
    pub missions_accepted: u64,
    /// `SET_MESSAGE_INTERVAL` commands obeyed.
    pub intervals_set: u64,
}

/// A simulated PX4 flight controller (system 1, component 1) flying a 200 m circle at
/// 10 m/s.
#[derive(Debug)]
pub struct Px4Fc {
    sender: Sender,
    reader: FrameReader,
    streams: Vec<Stream>,
    out: VecDeque<OwnedFrame>,
    rng: SplitMix64,
    booted: Instant,
    upload: Option<Upload>,
    mission: Vec<MISSION_ITEM_INT_DATA>,
    item_retry: Duration,
    stats: Px4Stats,
}

impl Px4Fc {
    /// A flight controller booted at `now` streaming `profile`.
    pub fn new(profile: &[StreamSpec], now: Instant, seed: u64) -> Self {
        Self {
            sender: Sender::new(1, 1, MavlinkVersion::V2),
            reader: FrameReader::new(),
            streams: profile
                .iter()
                .enumerate()
                .map(|(i, spec)| Stream {
                    spec: *spec,
                    hz: spec.hz,
                    // spread the streams' phases like a real scheduler does
                    next: now + Duration::from_millis(i as u64 * 7),
                })
                .collect(),
            out: VecDeque::new(),
            rng: SplitMix64::new(seed),
            booted: now,
            upload: None,
            mission: Vec::new(),
            item_retry: Duration::from_millis(250),
            stats: Px4Stats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> Px4Stats {
        self.stats
    }

    /// The mission stored by the last accepted upload.
    pub fn mission(&self) -> &[MISSION_ITEM_INT_DATA] {
        &self.mission
    }

    /// Current rate of message `id`.
    pub fn rate(&self, id: u32) -> Option<f64> {
        self.streams.iter().find(|s| s.spec.id == id).map(|s| s.hz)
    }

    /// Bytes written to the flight controller.
    pub fn handle_bytes(&mut self, bytes: &[u8], now: Instant) {
        self.reader.push(bytes);
        while let Some(rx) = self.reader.next_frame() {
            let from = (rx.frame.system_id(), rx.frame.component_id());
            let Ok(msg) = rx.frame.decode::<MavMessage>() else {
                continue;
            };
            self.handle(from, msg, now);
        }
    }

    fn handle(&mut self, from: (u8, u8), msg: MavMessage, now: Instant) {
        match msg {
            MavMessage::COMMAND_LONG(c)
                if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL && c.target_system == 1 =>
            {
                let hz = if c.param2 < 0.0 {
                    0.0
                } else {
                    1e6 / f64::from(c.param2)
                };
                if let Some(st) = self
                    .streams
                    .iter_mut()
                    .find(|s| s.spec.id == c.param1 as u32)
                {
                    st.hz = hz;
                    self.stats.intervals_set += 1;
                }
                self.send(&MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                    command: c.command,
                    result: MavResult::MAV_RESULT_ACCEPTED,
                }));
            }
            MavMessage::MISSION_COUNT(c) if c.target_system == 1 => {
                self.upload = Some(Upload {
                    peer: from,
                    count: c.count,
                    items: Vec::new(),
                    requested_at: now,
                    last_progress: now,
                });
                self.request_next(now);
            }
            // Download and clear: PX4 answers each request once; only the requester retries.
            MavMessage::MISSION_REQUEST_LIST(r) if r.target_system == 1 => {
                self.send(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                    count: self.mission.len() as u16,
                    target_system: from.0,
                    target_component: from.1,
                }));
            }
            MavMessage::MISSION_REQUEST_INT(r) if r.target_system == 1 => {
                if let Some(item) = self.mission.get(usize::from(r.seq)) {
                    let item = MISSION_ITEM_INT_DATA {
                        target_system: from.0,
                        target_component: from.1,
                        ..item.clone()
                    };
                    self.send(&MavMessage::MISSION_ITEM_INT(item));
                }
            }
            MavMessage::MISSION_CLEAR_ALL(c) if c.target_system == 1 => {
                self.mission.clear();
                self.send(&MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                    target_system: from.0,
                    target_component: from.1,
                    mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
                }));
            }
            MavMessage::MISSION_ITEM_INT(item) if item.target_system == 1 => {
                let Some(up) = &mut self.upload else {
                    self.stats.duplicate_items += 1;
                    return;
                };
                if usize::from(item.seq) != up.items.len() {
                    self.stats.duplicate_items += 1;
                    return;
                }
                up.items.push(item);
                up.last_progress = now;
                self.request_next(now);
            }
            _ => {}
        }
    }

    fn request_next(&mut self, now: Instant) {
        let Some(up) = &mut self.upload else { return };
        let peer = up.peer;
        if up.items.len() == usize::from(up.count) {
            self.mission = std::mem::take(&mut up.items);
            self.upload = None;
            self.stats.missions_accepted += 1;
            self.send(&MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                target_system: peer.0,
                target_component: peer.1,
                mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
            }));
            return;
        }
        up.requested_at = now;
        let seq = up.items.len() as u16;
        self.stats.item_requests += 1;
        self.send(&MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: peer.0,
            target_component: peer.1,
        }));
    }

    fn send(&mut self, msg: &MavMessage) {
        let frame = self.sender.frame(msg);
        self.out.push_back(frame);
    }

    /// When the next stream message or item retry is due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        if !self.out.is_empty() {
            // replies wait for nothing
            return Some(Instant::ZERO);
        }
        let streams = self.streams.iter().filter(|s| s.hz > 0.0).map(|s| s.next);
        let retry = self
            .upload
            .as_ref()
            .map(|u| u.requested_at + self.item_retry);
        streams.chain(retry).min()
    }

    /// Emits what is due at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        for i in 0..self.streams.len() {
            let st = &self.streams[i];
            if st.hz <= 0.0 || now < st.next {
                continue;
            }
            let spec = st.spec;
            let interval = Duration::from_secs_f64(1.0 / st.hz);
            self.streams[i].next = (self.streams[i].next + interval).max(now);
            let frame = self.telemetry(spec, now);
            self.out.push_back(frame);
        }
        if let Some(up) = &self.upload {
            if now.saturating_duration_since(up.last_progress) > Duration::from_secs(5) {
                self.upload = None;
            } else if now >= up.requested_at + self.item_retry {
                // PX4: re-request after 250 ms whatever the link.
                self.request_next(now);
            }
        }
    }

    /// The next frame the flight controller writes.
    pub fn poll_transmit(&mut self) -> Option<OwnedFrame> {
        self.out.pop_front()
    }

    fn telemetry(&mut self, spec: StreamSpec, now: Instant) -> OwnedFrame {
        let t = now.saturating_duration_since(self.booted);
        let ms = t.as_millis() as u32;
        let secs = t.as_secs_f64();
        // 200 m circle at 10 m/s around Odense (the paper's test area)
        let w = 10.0 / 200.0;
        let (north, east) = (200.0 * (w * secs).cos(), 200.0 * (w * secs).sin());
        let (vn, ve) = (-10.0 * (w * secs).sin(), 10.0 * (w * secs).cos());
        let lat = 553_700_000 + (north / 0.011_132) as i32;
        let lon = 103_900_000 + (east / (0.011_132 * 0.5664)) as i32;
        let hdg = ((ve.atan2(vn).to_degrees() + 360.0) % 360.0 * 100.0) as u16;
        let msg = match spec.id {
            0 => MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 0x0404_0000, // AUTO.MISSION
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
                base_mode: MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED
                    | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            }),
            1 => MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                voltage_battery: 15_800 - (secs * 2.0) as u16,
                battery_remaining: 80,
                load: 400,
                ..SYS_STATUS_DATA::default()
            }),
            24 => MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                time_usec: t.as_micros() as u64,
                lat,
                lon,
                alt: 60_000,
                eph: 80,
                epv: 120,
                vel: 1000,
                cog: hdg,
                fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
                satellites_visible: 14,
            }),
            30 => MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: ms,
                roll: 0.05,
                pitch: -0.1,
                yaw: 1.0,
                ..ATTITUDE_DATA::default()
            }),
            33 => MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                time_boot_ms: ms,
                lat,
                lon,
                alt: 60_000,
                relative_alt: 50_000,
                vx: (vn * 100.0) as i16,
                vy: (ve * 100.0) as i16,
                vz: 0,
                hdg,
            }),
            74 => MavMessage::VFR_HUD(VFR_HUD_DATA {
                airspeed: 10.0,
                groundspeed: 10.0,
                alt: 60.0,
                climb: 0.0,
                heading: (hdg / 100) as i16,
                throttle: 55,
            }),
            _ => return self.filler(spec),
        };
        self.sender.frame(&msg)
    }

    /// A frame of a message we do not decode, with a full-length non-zero payload (so v2
    /// truncation does not make it look cheaper than PX4's).
    fn filler(&mut self, spec: StreamSpec) -> OwnedFrame {
        let id = spec.id.to_le_bytes();
        let mut bytes = vec![
            0xFD,
            spec.payload_len as u8,
            0,
            0,
            self.sender.take_sequence(),
            1,
            1,
            id[0],
            id[1],
            id[2],
        ];
        bytes.extend((0..spec.payload_len).map(|_| (self.rng.next_u64() as u8) | 1));
        let crc = mavlink::calculate_crc(&bytes[1..], known::crc_extra(spec.id).unwrap_or(0));
        bytes.extend_from_slice(&crc.to_le_bytes());
        OwnedFrame::new_checked(bytes).expect("well-formed filler frame")
    }
}
