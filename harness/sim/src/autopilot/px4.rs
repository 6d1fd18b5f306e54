//! A flight controller that behaves like PX4 where it matters for the link: the "Normal"
//! stream profile, `SET_MESSAGE_INTERVAL`, and mission upload with 250 ms item retries
//! (PX4 issue #11078).

use mavlora::Duration;
use std::collections::VecDeque;

use mavlink::MavlinkVersion;

use super::kinematics::{Flight, Kinematics};
use super::mission::MissionStore;
use super::params::{ParamServer, ParamTable, SetEcho, param_value_frame};
use crate::rng::SplitMix64;
use mavlora::Instant;
use mavlora::dialect::{
    ATTITUDE_DATA, COMMAND_ACK_DATA, GPS_RAW_INT_DATA, GpsFixType, HEARTBEAT_DATA,
    MISSION_ITEM_INT_DATA, MavAutopilot, MavCmd, MavMessage, MavMissionType, MavModeFlag,
    MavResult, MavState, MavSysStatusSensorExtended, MavType, SYS_STATUS_DATA, VFR_HUD_DATA,
};
use mavlora::wire::{FrameReader, OwnedFrame, Sender, known};

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

/// PX4's USB "Config" MAVLink profile, what a flight controller streams to a ground station
/// on USB or, as in the paper's wired SITL run (Table II, "gcs fc wired"), when nobody limits
/// it. Rates: `Mavlink::configure_streams_to_default`, `case MAVLINK_MODE_CONFIG`, in PX4's
/// `src/modules/mavlink/mavlink_main.cpp`. Kept: the streams of that list whose ids appear in
/// the paper's Fig. 6a (what its SITL actually sent); left out: those needing hardware a SITL
/// quad without RC has not (distance sensor, ESC, EFI, optical flow, camera, ADS-B, RC,
/// gimbal) and the debug streams. `GPS_RAW_INT` is "unlimited" (on every GPS update):
/// 10 Hz assumed, the Gazebo GPS plugin's rate. Payload lengths: common.xml without
/// extensions.
pub const PX4_CONFIG: &[StreamSpec] = &[
    s(30, 50.0, 28),  // ATTITUDE
    s(31, 50.0, 32),  // ATTITUDE_QUATERNION
    s(105, 50.0, 62), // HIGHRES_IMU
    s(140, 30.0, 41), // ACTUATOR_CONTROL_TARGET (group 0)
    s(32, 30.0, 28),  // LOCAL_POSITION_NED
    s(26, 25.0, 22),  // SCALED_IMU
    s(36, 20.0, 21),  // SERVO_OUTPUT_RAW (output group 0)
    s(74, 20.0, 20),  // VFR_HUD
    s(33, 10.0, 28),  // GLOBAL_POSITION_INT
    s(24, 10.0, 30),  // GPS_RAW_INT
    s(87, 10.0, 51),  // POSITION_TARGET_GLOBAL_INT
    s(141, 10.0, 32), // ALTITUDE
    s(111, 10.0, 16), // TIMESYNC
    s(83, 8.0, 37),   // ATTITUDE_TARGET
    s(230, 5.0, 42),  // ESTIMATOR_STATUS
    s(241, 2.5, 32),  // VIBRATION
    s(245, 2.0, 2),   // EXTENDED_SYS_STATE
    s(1, 1.0, 31),    // SYS_STATUS
    s(2, 1.0, 12),    // SYSTEM_TIME
    s(4, 1.0, 14),    // PING
    s(147, 0.5, 36),  // BATTERY_STATUS
    s(242, 0.5, 52),  // HOME_POSITION
    s(0, 1.0, 9),     // HEARTBEAT
];

#[derive(Debug)]
struct Stream {
    spec: StreamSpec,
    hz: f64,
    next: Instant,
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
    /// Other `COMMAND_LONG`s acknowledged (duplicates included, as PX4 acks each).
    pub commands_acked: u64,
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
    missions: MissionStore,
    flight: Flight,
    stats: Px4Stats,
    /// Commands executed (other than `SET_MESSAGE_INTERVAL`), in order.
    executed: Vec<Executed>,
    /// The mode its HEARTBEAT reports: custom mode and armed.
    mode: (u32, bool),
    /// Each change of mode as its HEARTBEATs showed it: when the first with it went out.
    modes_sent: Vec<(Instant, u32, bool)>,
    /// Its parameters (none unless [`with_params`](Px4Fc::with_params)).
    params: ParamServer,
}

/// `PARAM_VALUE`s a second PX4 1.16 SITL streams its list at on a 57600-baud serial port
/// (`data/px4-1.16.0-sih.tsv`: 904 in 6.0 s).
pub const PX4_PARAM_RATE: f64 = 150.0;

/// A command the simulated PX4 executed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Executed {
    /// Command id.
    pub command: MavCmd,
    /// The target component it was addressed to (0: all).
    pub target_component: u8,
    /// Its seven parameters.
    pub params: [f32; 7],
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
            // PX4: an item re-requested after 250 ms whatever the link; 5 s without progress
            // ends the upload.
            missions: MissionStore::new(1, Duration::from_millis(250), Duration::from_secs(5)),
            flight: Flight::Circle,
            stats: Px4Stats::default(),
            executed: Vec::new(),
            // AUTO.MISSION, armed
            mode: (0x0404_0000, true),
            modes_sent: Vec::new(),
            params: ParamServer::new(ParamTable::synthetic(0), PX4_PARAM_RATE, SetEcho::Index),
        }
    }

    /// The same flight controller holding `table` (e.g. [`ParamTable::px4`]), streaming it
    /// at `rate` values a second on `PARAM_REQUEST_LIST` (PX4: [`PX4_PARAM_RATE`]) and
    /// echoing a set with the parameter's index, as PX4 does.
    pub fn with_params(mut self, table: ParamTable, rate: f64) -> Self {
        self.params = ParamServer::new(table, rate, SetEcho::Index);
        self
    }

    /// Its parameters now.
    pub fn params(&self) -> &ParamTable {
        self.params.table()
    }

    /// Changes the mode its HEARTBEATs report from now on (as a pilot's switch or a failsafe
    /// would); the next heartbeat of its 1 Hz stream shows it, as PX4's does.
    pub fn set_mode(&mut self, custom_mode: u32, armed: bool) {
        self.mode = (custom_mode, armed);
    }

    /// Each change of mode as its HEARTBEATs showed it: when the first heartbeat with the new
    /// (custom mode, armed) left, the first one at boot included.
    pub fn modes_sent(&self) -> &[(Instant, u32, bool)] {
        &self.modes_sent
    }

    /// The same flight controller flying `flight` from its boot.
    pub fn with_flight(mut self, flight: Flight) -> Self {
        self.flight = flight;
        self
    }

    /// Sets the stream rates `profile` asks for, as if a companion computer had sent its
    /// `SET_MESSAGE_INTERVAL`s (or the operator had set PX4's parameters): for runs without a
    /// bridge that should still stream what the profile wants. The acks are not sent.
    pub fn apply_profile_rates(&mut self, profile: &mavlora::filter::Profile, now: Instant) {
        let queued = self.out.len();
        for msg in mavlora::filter::set_message_interval_requests(profile, 1, 1) {
            self.handle((1, 191), msg, now);
        }
        self.out.truncate(queued);
    }

    /// Position and velocity at `now`.
    pub fn kinematics(&self, now: Instant) -> Kinematics {
        self.flight.since_boot(self.booted, now)
    }

    /// Counters so far.
    pub fn stats(&self) -> Px4Stats {
        let m = self.missions.stats();
        Px4Stats {
            item_requests: m.item_requests,
            duplicate_items: m.duplicate_items,
            missions_accepted: m.accepted,
            ..self.stats
        }
    }

    /// Every command executed so far (each copy that reached it counts), in order.
    /// Makes room up front for `n` executions in its record, so a long run's record does not
    /// grow the heap while it is being measured (a soak).
    pub fn reserve_executed(&mut self, n: usize) {
        self.executed.reserve(n);
    }

    /// Every command it executed, in order (retries it recognised as such excluded).
    pub fn executed(&self) -> &[Executed] {
        &self.executed
    }

    /// The mission stored by the last accepted upload.
    pub fn mission(&self) -> &[MISSION_ITEM_INT_DATA] {
        self.missions.plan(MavMissionType::MAV_MISSION_TYPE_MISSION)
    }

    /// The stored plan of `mission_type` (mission, fence, rally).
    pub fn plan(&self, mission_type: MavMissionType) -> &[MISSION_ITEM_INT_DATA] {
        self.missions.plan(mission_type)
    }

    /// The mission protocol side (counters, upload in progress).
    pub fn missions(&self) -> &MissionStore {
        &self.missions
    }

    /// Reboots at `now`: `time_boot_ms` starts again from 0 (what the bridge's reboot
    /// detection watches), an upload in progress is lost, stored plans survive.
    pub fn reboot(&mut self, now: Instant) {
        self.booted = now;
        self.missions.reboot();
        self.out.clear();
    }

    /// Current rate of message `id`.
    pub fn rate(&self, id: u32) -> Option<f64> {
        self.streams.iter().find(|s| s.spec.id == id).map(|s| s.hz)
    }

    /// Bytes written to the flight controller.
    pub fn handle_bytes(&mut self, now: Instant, bytes: &[u8]) {
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
                    ..Default::default()
                }));
            }
            // Any other command (mode changes, speed changes): accepted at once. PX4 acks
            // every copy it receives, retries included.
            MavMessage::COMMAND_LONG(c)
                if c.target_system == 1 && matches!(c.target_component, 0 | 1) =>
            {
                self.stats.commands_acked += 1;
                self.executed.push(Executed {
                    command: c.command,
                    target_component: c.target_component,
                    params: [
                        c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                    ],
                });
                self.send(&MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                    command: c.command,
                    result: MavResult::MAV_RESULT_ACCEPTED,
                    ..Default::default()
                }));
            }
            ref msg if self.missions.handle(from, msg, now) => {
                while let Some(reply) = self.missions.poll_message() {
                    self.send(&reply);
                }
            }
            MavMessage::PARAM_REQUEST_LIST(_)
            | MavMessage::PARAM_REQUEST_READ(_)
            | MavMessage::PARAM_SET(_) => {
                let sender = &mut self.sender;
                let frames = self.params.handle(now, 1, &msg, |p| {
                    param_value_frame(MavlinkVersion::V2, 1, 1, sender.take_sequence(), p)
                });
                self.out.extend(frames);
            }
            _ => {}
        }
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
        streams
            .chain(self.missions.poll_timeout())
            .chain(self.params.poll_timeout())
            .min()
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
        self.missions.handle_timeout(now);
        while let Some(msg) = self.missions.poll_message() {
            self.send(&msg);
        }
        let sender = &mut self.sender;
        let frames = self.params.handle_timeout(now, |p| {
            param_value_frame(MavlinkVersion::V2, 1, 1, sender.take_sequence(), p)
        });
        self.out.extend(frames);
    }

    /// The next frame the flight controller writes.
    pub fn poll_transmit(&mut self) -> Option<OwnedFrame> {
        self.out.pop_front()
    }

    fn telemetry(&mut self, spec: StreamSpec, now: Instant) -> OwnedFrame {
        let t = now.saturating_duration_since(self.booted);
        let ms = t.as_millis() as u32;
        let secs = t.as_secs_f64();
        let k = self.kinematics(now);
        let (vn, ve) = (k.vn, k.ve);
        let (lat, lon) = k.lat_lon();
        // Hovering (climb, descent) keeps the route's heading: PX4 reports yaw, never "none",
        // and a zero heading would be truncated off the v2 payload.
        let hdg = k.heading_cdeg(match self.flight {
            Flight::Route(r) => r.bearing_deg,
            Flight::Circle => 90.0,
        });
        let rel_mm = k.rel_alt_mm();
        let msg = match spec.id {
            0 => {
                let (custom_mode, armed) = self.mode;
                if self
                    .modes_sent
                    .last()
                    .is_none_or(|&(_, m, a)| (m, a) != self.mode)
                {
                    self.modes_sent.push((now, custom_mode, armed));
                }
                MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                    custom_mode,
                    mavtype: MavType::MAV_TYPE_QUADROTOR,
                    autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
                    base_mode: if armed {
                        MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED
                            | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                    } else {
                        MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                    },
                    system_status: MavState::MAV_STATE_ACTIVE,
                    mavlink_version: 3,
                })
            }
            1 => MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                voltage_battery: 15_800 - (secs * 2.0) as u16,
                battery_remaining: 80,
                load: 400,
                // The generated Default of a bitflags field is its first flag, not empty: the
                // extended sensor sets must be said to be empty.
                onboard_control_sensors_present_extended: MavSysStatusSensorExtended::empty(),
                onboard_control_sensors_enabled_extended: MavSysStatusSensorExtended::empty(),
                onboard_control_sensors_health_extended: MavSysStatusSensorExtended::empty(),
                ..SYS_STATUS_DATA::default()
            }),
            24 => MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                time_usec: t.as_micros(),
                lat,
                lon,
                alt: 10_000 + rel_mm,
                eph: 80,
                epv: 120,
                vel: (vn.hypot(ve) * 100.0) as u16,
                cog: hdg,
                fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
                satellites_visible: 14,
                ..Default::default()
            }),
            30 => MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: ms,
                roll: 0.05,
                pitch: -0.1,
                yaw: 1.0,
                // a flying multicopter never has exactly zero body rates (and zeros at the
                // end would be truncated off the v2 payload, making it look cheaper)
                rollspeed: 0.012,
                pitchspeed: -0.008,
                yawspeed: 0.003,
            }),
            33 => MavMessage::GLOBAL_POSITION_INT(k.global_position_int(ms, hdg)),
            74 => MavMessage::VFR_HUD(VFR_HUD_DATA {
                airspeed: vn.hypot(ve) as f32,
                groundspeed: vn.hypot(ve) as f32,
                alt: (10.0 + k.up) as f32,
                climb: k.vu as f32,
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
