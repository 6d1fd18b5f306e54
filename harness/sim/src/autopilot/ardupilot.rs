//! A flight controller that behaves like ArduPilot where it matters for the link (the brief's
//! "ArduPilot" facts): MAVLink 1 on the serial port (2 on request), streams configured per
//! group with `REQUEST_DATA_STREAM` (the `SRx_*` groups) and no `SET_MESSAGE_INTERVAL`
//! (answered `UNSUPPORTED`, as ArduPilot before 4.0), ardupilotmega-only messages the
//! generated dialect does not know (SIMSTATE, AHRS, AHRS2/3, HWSTATUS, MEMINFO,
//! EKF_STATUS_REPORT, ...), about 30 message types at 4 Hz each, ~3.7 kB/s like a recorded
//! SITL flight, and a `PARAM_VALUE` stream on `PARAM_REQUEST_LIST` (or at boot). It can be
//! told to ignore stream requests ([`ArduPilotConfig::obey_stream_requests`]), as a
//! misconfigured or stubborn autopilot does.
//!
//! Missions are not simulated: uploads are not answered ([`Autopilot::mission`] stays empty).

// REQUEST_DATA_STREAM is deprecated upstream; ArduPilot before 4.0 only has it.
#![allow(deprecated)]

use std::collections::VecDeque;

use mavlink::MavlinkVersion;
use mavlora::dialect::{
    ATTITUDE_DATA, COMMAND_ACK_DATA, GPS_RAW_INT_DATA, GpsFixType, HEARTBEAT_DATA,
    MISSION_CURRENT_DATA, MISSION_ITEM_INT_DATA, MavAutopilot, MavCmd, MavMessage, MavModeFlag,
    MavResult, MavState, MavSysStatusSensorExtended, MavType, SYS_STATUS_DATA, SYSTEM_TIME_DATA,
    VFR_HUD_DATA,
};
use mavlora::wire::{FrameReader, OwnedFrame, Sender, known};
use mavlora::{Duration, Instant};

use super::Autopilot;
use super::kinematics::{Flight, Kinematics};
use super::params::{ParamServer, ParamTable, SetEcho, param_value_frame};
use crate::rng::SplitMix64;

/// `MAV_DATA_STREAM` groups ArduPilot streams by (ids as in common.xml).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Group {
    /// `RAW_SENSORS` (1): IMU and baro raw values.
    RawSensors = 1,
    /// `EXTENDED_STATUS` (2): SYS_STATUS, GPS_RAW_INT, MEMINFO, ...
    ExtendedStatus = 2,
    /// `RC_CHANNELS` (3): RC in, servo out.
    RcChannels = 3,
    /// `POSITION` (6): GLOBAL_POSITION_INT, LOCAL_POSITION_NED.
    Position = 6,
    /// `EXTRA1` (10): ATTITUDE, SIMSTATE, AHRS2.
    Extra1 = 10,
    /// `EXTRA2` (11): VFR_HUD.
    Extra2 = 11,
    /// `EXTRA3` (12): AHRS, HWSTATUS, EKF_STATUS_REPORT, ...
    Extra3 = 12,
}

const GROUPS: [Group; 7] = [
    Group::RawSensors,
    Group::ExtendedStatus,
    Group::RcChannels,
    Group::Position,
    Group::Extra1,
    Group::Extra2,
    Group::Extra3,
];

/// One streamed message: its group, id, base payload length and CRC extra (ardupilotmega.xml,
/// as pymavlink 2.4's `dialects.v10.ardupilotmega` has them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ApStream {
    /// The group that carries it.
    pub group: Group,
    /// Message id.
    pub id: u32,
    /// Payload length without extensions.
    pub payload_len: usize,
    /// CRC extra byte (ardupilotmega.xml).
    pub crc_extra: u8,
}

const fn st(group: Group, id: u32, payload_len: usize, crc_extra: u8) -> ApStream {
    ApStream {
        group,
        id,
        payload_len,
        crc_extra,
    }
}

/// What an ArduCopter SITL streams per group (GCS_MAVLink `STREAM_*` tables): 30 message
/// types, 11 of them ardupilotmega-only. At 4 Hz per group: ~120 msg/s, ~3.8 kB/s in
/// MAVLink 1, the brief's recorded SITL flight.
pub const ARDUPILOT_STREAMS: &[ApStream] = &[
    st(Group::RawSensors, 27, 26, 144),     // RAW_IMU
    st(Group::RawSensors, 116, 22, 76),     // SCALED_IMU2
    st(Group::RawSensors, 129, 22, 46),     // SCALED_IMU3
    st(Group::RawSensors, 29, 14, 115),     // SCALED_PRESSURE
    st(Group::RawSensors, 137, 14, 195),    // SCALED_PRESSURE2
    st(Group::RawSensors, 150, 42, 134),    // SENSOR_OFFSETS (apm)
    st(Group::ExtendedStatus, 1, 31, 124),  // SYS_STATUS
    st(Group::ExtendedStatus, 125, 6, 203), // POWER_STATUS
    st(Group::ExtendedStatus, 152, 4, 208), // MEMINFO (apm)
    st(Group::ExtendedStatus, 42, 2, 28),   // MISSION_CURRENT
    st(Group::ExtendedStatus, 24, 30, 24),  // GPS_RAW_INT
    st(Group::ExtendedStatus, 62, 26, 183), // NAV_CONTROLLER_OUTPUT
    st(Group::Position, 33, 28, 104),       // GLOBAL_POSITION_INT
    st(Group::Position, 32, 28, 185),       // LOCAL_POSITION_NED
    st(Group::RcChannels, 36, 21, 222),     // SERVO_OUTPUT_RAW
    st(Group::RcChannels, 65, 42, 118),     // RC_CHANNELS
    st(Group::RcChannels, 35, 22, 244),     // RC_CHANNELS_RAW
    st(Group::Extra1, 30, 28, 39),          // ATTITUDE
    st(Group::Extra1, 164, 44, 154),        // SIMSTATE (apm)
    st(Group::Extra1, 178, 24, 47),         // AHRS2 (apm)
    st(Group::Extra2, 74, 20, 20),          // VFR_HUD
    st(Group::Extra3, 163, 28, 127),        // AHRS (apm)
    st(Group::Extra3, 165, 3, 21),          // HWSTATUS (apm)
    st(Group::Extra3, 2, 12, 137),          // SYSTEM_TIME
    st(Group::Extra3, 168, 12, 1),          // WIND (apm)
    st(Group::Extra3, 136, 22, 1),          // TERRAIN_REPORT
    st(Group::Extra3, 182, 40, 229),        // AHRS3 (apm)
    st(Group::Extra3, 193, 22, 71),         // EKF_STATUS_REPORT (apm)
    st(Group::Extra3, 241, 32, 90),         // VIBRATION
    st(Group::Extra3, 147, 36, 154),        // BATTERY_STATUS
];

/// `PARAM_VALUE`s a second ArduCopter 4.6.3 SITL streams its list at on a 57600-baud serial
/// port (`data/ardupilot-copter-4.6.3.tsv`: 1,396 in 5.2 s).
pub const ARDUPILOT_PARAM_RATE: f64 = 270.0;

/// Parameters ArduCopter 4.6.3 SITL told of unasked after boot, with index 65535 (its
/// calibrations at boot: `router.tlog` of the rig's `sitl` suite).
pub const BOOT_NOTIFIED: &[&str] = &[
    "INS_ACC2_ID",
    "INS_GYR3_ID",
    "EK3_SRC1_POSXY",
    "INS_GYROFFS_X",
    "INS_GYROFFS_Y",
    "INS_GYROFFS_Z",
    "BARO1_GND_PRESS",
    "BARO2_GND_PRESS",
    "INS_GYR2OFFS_X",
];

/// How the simulated ArduPilot behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArduPilotConfig {
    /// Serial protocol: MAVLink 1 (ArduPilot < 4.0 on a telemetry port) or 2.
    pub version: MavlinkVersion,
    /// Rate of every group at boot, Hz (the `SRx_*` parameters).
    pub default_hz: f64,
    /// Whether `REQUEST_DATA_STREAM` changes the rates (false: it is ignored, as by an
    /// autopilot whose `SRx_*` parameters are fixed, or that a second GCS keeps resetting).
    pub obey_stream_requests: bool,
    /// Parameters it holds (ArduCopter has ~1000): made-up ones, `SIM_PARAM_0000`...; a real
    /// list instead with [`ArduPilotFc::with_params`].
    pub params: u16,
    /// Whether it streams all parameters right after boot, unasked (the burst a ground
    /// station's parameter load causes, at the start of a recorded flight).
    pub params_at_boot: bool,
    /// `PARAM_VALUE`s per second while streaming parameters.
    pub param_hz: f64,
}

impl Default for ArduPilotConfig {
    fn default() -> Self {
        Self {
            version: MavlinkVersion::V1,
            default_hz: 4.0,
            obey_stream_requests: true,
            params: 1000,
            params_at_boot: false,
            param_hz: 200.0,
        }
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ArduPilotStats {
    /// `REQUEST_DATA_STREAM`s applied.
    pub stream_requests_obeyed: u64,
    /// `REQUEST_DATA_STREAM`s received and ignored.
    pub stream_requests_ignored: u64,
    /// `PARAM_VALUE`s sent.
    pub params_sent: u64,
    /// `COMMAND_LONG`s acknowledged.
    pub commands_acked: u64,
}

#[derive(Debug)]
struct GroupState {
    group: Group,
    hz: f64,
    next: Instant,
}

/// A simulated ArduPilot (system 1, component 1).
#[derive(Debug)]
pub struct ArduPilotFc {
    config: ArduPilotConfig,
    sender: Sender,
    reader: FrameReader,
    groups: Vec<GroupState>,
    next_heartbeat: Instant,
    /// Its parameters and their protocol.
    params: ParamServer,
    /// Parameters it will tell about unasked (index 65535), and when.
    notifications: VecDeque<(Instant, usize)>,
    out: VecDeque<OwnedFrame>,
    rng: SplitMix64,
    booted: Instant,
    flight: Flight,
    stats: ArduPilotStats,
}

impl ArduPilotFc {
    /// An autopilot booted at `now`.
    pub fn new(config: ArduPilotConfig, now: Instant, seed: u64) -> Self {
        Self {
            sender: Sender::new(1, 1, config.version),
            reader: FrameReader::new(),
            groups: GROUPS
                .iter()
                .enumerate()
                .map(|(i, &group)| GroupState {
                    group,
                    hz: config.default_hz,
                    // ArduPilot's scheduler spreads the groups over its loop
                    next: now + Duration::from_millis(3 + i as u64 * 11),
                })
                .collect(),
            next_heartbeat: now,
            params: {
                let mut p = ParamServer::new(
                    ParamTable::synthetic(config.params),
                    config.param_hz,
                    SetEcho::NoIndex,
                );
                if config.params_at_boot {
                    p.start_list(now);
                }
                p
            },
            notifications: VecDeque::new(),
            out: VecDeque::new(),
            rng: SplitMix64::new(seed),
            booted: now,
            flight: Flight::Circle,
            stats: ArduPilotStats::default(),
            config,
        }
    }

    /// The same autopilot holding `table` (e.g. [`ParamTable::arducopter`]) instead of
    /// made-up parameters, streaming it at `rate` values a second (ArduCopter 4.6 SITL on a
    /// 57600-baud serial port: [`ARDUPILOT_PARAM_RATE`]; at boot too if its configuration
    /// says so).
    ///
    /// Like ArduCopter 4.6.3 SITL, it also tells of parameters its calibrations change at boot
    /// (gyro and barometer offsets, sensor ids, EKF sources: [`BOOT_NOTIFIED`]), unasked, with
    /// index 65535: one every 1.5 s for the first 45 s (the SITL sent 18 in its first 17 s).
    pub fn with_params(mut self, table: ParamTable, rate: f64) -> Self {
        let streaming = self.params.streaming();
        let notified: Vec<usize> = BOOT_NOTIFIED
            .iter()
            .filter_map(|name| {
                let mut n = [0u8; 16];
                n[..name.len()].copy_from_slice(name.as_bytes());
                table.find(&n)
            })
            .collect();
        self.notifications = (0..30)
            .filter_map(|k| {
                let at = self.booted + Duration::from_millis(900 + 1500 * k as u64);
                notified.get(k % notified.len().max(1)).map(|&i| (at, i))
            })
            .collect();
        self.params = ParamServer::new(table, rate, SetEcho::NoIndex);
        if streaming {
            self.params.start_list(self.booted);
        }
        self
    }

    /// Its parameters now.
    pub fn params(&self) -> &ParamTable {
        self.params.table()
    }

    /// The same autopilot flying `flight` from its boot.
    pub fn with_flight(mut self, flight: Flight) -> Self {
        self.flight = flight;
        self
    }

    /// Counters so far.
    pub fn stats(&self) -> ArduPilotStats {
        self.stats
    }

    /// Current rate of `group`, Hz.
    pub fn group_rate(&self, group: Group) -> f64 {
        self.groups
            .iter()
            .find(|g| g.group == group)
            .map_or(0.0, |g| g.hz)
    }

    /// Whether a parameter stream is running.
    pub fn streaming_params(&self) -> bool {
        self.params.streaming()
    }

    /// Position and velocity at `now`.
    pub fn kinematics(&self, now: Instant) -> Kinematics {
        self.flight.since_boot(self.booted, now)
    }

    fn handle(&mut self, from: (u8, u8), msg: MavMessage, now: Instant) {
        match msg {
            MavMessage::REQUEST_DATA_STREAM(r) if r.target_system == 1 => {
                if !self.config.obey_stream_requests {
                    self.stats.stream_requests_ignored += 1;
                    return;
                }
                self.stats.stream_requests_obeyed += 1;
                let hz = if r.start_stop == 0 {
                    0.0
                } else {
                    f64::from(r.req_message_rate)
                };
                let id = r.req_stream_id as u8;
                for g in &mut self.groups {
                    // MAV_DATA_STREAM_ALL (0) sets every group
                    if id == 0 || g.group as u8 == id {
                        g.hz = hz;
                        g.next = g.next.max(now);
                    }
                }
            }
            MavMessage::COMMAND_LONG(c) if c.target_system == 1 => {
                self.stats.commands_acked += 1;
                // ArduPilot before 4.0 has no SET_MESSAGE_INTERVAL
                let result = if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL {
                    MavResult::MAV_RESULT_UNSUPPORTED
                } else {
                    MavResult::MAV_RESULT_ACCEPTED
                };
                self.send(&MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                    command: c.command,
                    result,
                    ..Default::default()
                }));
            }
            MavMessage::PARAM_REQUEST_LIST(_)
            | MavMessage::PARAM_REQUEST_READ(_)
            | MavMessage::PARAM_SET(_) => {
                let (sender, version) = (&mut self.sender, self.config.version);
                let frames = self.params.handle(now, 1, &msg, |p| {
                    param_value_frame(version, 1, 1, sender.take_sequence(), p)
                });
                self.stats.params_sent += frames.len() as u64;
                self.out.extend(frames);
            }
            _ => {
                let _ = from;
            }
        }
    }

    fn send(&mut self, msg: &MavMessage) {
        let frame = self.sender.frame(msg);
        self.out.push_back(frame);
    }

    fn group_due(&mut self, i: usize, now: Instant) {
        let group = self.groups[i].group;
        for spec in ARDUPILOT_STREAMS.iter().filter(|s| s.group == group) {
            let frame = self.telemetry(*spec, now);
            self.out.push_back(frame);
        }
    }

    fn telemetry(&mut self, spec: ApStream, now: Instant) -> OwnedFrame {
        let t = now.saturating_duration_since(self.booted);
        let ms = t.as_millis() as u32;
        let k = self.kinematics(now);
        let (lat, lon) = k.lat_lon();
        let hdg = k.heading_cdeg(90.0);
        let rel_mm = k.rel_alt_mm();
        let msg = match spec.id {
            1 => MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                voltage_battery: 12_600 - (t.as_secs_f64() * 1.5) as u16,
                battery_remaining: 85,
                load: 250,
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
                eph: 70,
                epv: 110,
                vel: (k.vn.hypot(k.ve) * 100.0) as u16,
                cog: hdg,
                fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
                satellites_visible: 12,
                ..Default::default()
            }),
            // Its clock, as ArduPilot sends it: a random time_boot_ms went back every few
            // frames and the bridge took each for a reboot (and configured it again).
            2 => MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
                time_unix_usec: 1_700_000_000_000_000 + t.as_micros(),
                time_boot_ms: ms,
            }),
            30 => MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: ms,
                roll: 0.04,
                pitch: -0.09,
                yaw: 1.1,
                rollspeed: 0.011,
                pitchspeed: -0.007,
                yawspeed: 0.002,
            }),
            33 => MavMessage::GLOBAL_POSITION_INT(k.global_position_int(ms, hdg)),
            42 => MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
                seq: 1,
                ..Default::default()
            }),
            74 => MavMessage::VFR_HUD(VFR_HUD_DATA {
                airspeed: k.vn.hypot(k.ve) as f32,
                groundspeed: k.vn.hypot(k.ve) as f32,
                alt: (10.0 + k.up) as f32,
                climb: k.vu as f32,
                heading: (hdg / 100) as i16,
                throttle: 48,
            }),
            _ => return self.raw(spec),
        };
        self.sender.frame(&msg)
    }

    /// A frame of a message the dialect may not know (ardupilotmega ids), with a full-length
    /// non-zero payload and the right CRC extra, in the configured MAVLink version.
    fn raw(&mut self, spec: ApStream) -> OwnedFrame {
        let seq = self.sender.take_sequence();
        let len = spec.payload_len as u8;
        let id = spec.id.to_le_bytes();
        let mut bytes = match self.config.version {
            MavlinkVersion::V1 => vec![0xFE, len, seq, 1, 1, id[0]],
            MavlinkVersion::V2 => vec![0xFD, len, 0, 0, seq, 1, 1, id[0], id[1], id[2]],
        };
        bytes.extend((0..spec.payload_len).map(|_| (self.rng.next_u64() as u8) | 1));
        let extra = known::crc_extra(spec.id).unwrap_or(spec.crc_extra);
        let crc = mavlink::calculate_crc(&bytes[1..], extra);
        bytes.extend_from_slice(&crc.to_le_bytes());
        OwnedFrame::new_checked(bytes).expect("well-formed raw frame")
    }
}

impl Autopilot for ArduPilotFc {
    fn handle_bytes(&mut self, now: Instant, bytes: &[u8]) {
        self.reader.push(bytes);
        while let Some(rx) = self.reader.next_frame() {
            let from = (rx.frame.system_id(), rx.frame.component_id());
            if let Ok(msg) = rx.frame.decode::<MavMessage>() {
                self.handle(from, msg, now);
            }
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        if now >= self.next_heartbeat {
            self.next_heartbeat = now + Duration::from_secs(1);
            self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 3, // AUTO
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                base_mode: MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED
                    | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            }));
        }
        for i in 0..self.groups.len() {
            let g = &self.groups[i];
            if g.hz <= 0.0 || now < g.next {
                continue;
            }
            let interval = Duration::from_secs_f64(1.0 / g.hz);
            self.groups[i].next = (g.next + interval).max(now);
            self.group_due(i, now);
        }
        let (sender, version) = (&mut self.sender, self.config.version);
        let frames = self.params.handle_timeout(now, |p| {
            param_value_frame(version, 1, 1, sender.take_sequence(), p)
        });
        self.stats.params_sent += frames.len() as u64;
        self.out.extend(frames);
        while let Some(&(at, index)) = self.notifications.front()
            && now >= at
        {
            self.notifications.pop_front();
            let sender = &mut self.sender;
            if let Some(f) = self.params.notify(index, |p| {
                param_value_frame(version, 1, 1, sender.take_sequence(), p)
            }) {
                self.stats.params_sent += 1;
                self.out.push_back(f);
            }
        }
    }

    fn poll_timeout(&self) -> Option<Instant> {
        if !self.out.is_empty() {
            return Some(Instant::ZERO);
        }
        let groups = self.groups.iter().filter(|g| g.hz > 0.0).map(|g| g.next);
        groups
            .chain(
                [
                    Some(self.next_heartbeat),
                    self.params.poll_timeout(),
                    self.notifications.front().map(|n| n.0),
                ]
                .into_iter()
                .flatten(),
            )
            .min()
    }

    fn poll_transmit(&mut self) -> Option<OwnedFrame> {
        self.out.pop_front()
    }

    fn mission(&self) -> &[MISSION_ITEM_INT_DATA] {
        &[]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{World, secs};
    use harness_radio::Direction;

    #[test]
    fn a_sitl_like_stream_is_30_types_at_4_hz_about_3_7_kb_per_s_in_mavlink_1() {
        let fc = ArduPilotFc::new(ArduPilotConfig::default(), Instant::ZERO, 1);
        let mut w = World::new(fc, None, None).unwrap();
        w.run_until(secs(60.0));
        let c = w.sent(Direction::Downlink);
        let types = c.frames.len();
        let bps = c.total_bytes() as f64 / 60.0;
        assert_eq!(types, 31, "30 streamed + HEARTBEAT: {:?}", c.frames.keys());
        assert!((3_500.0..=4_000.0).contains(&bps), "{bps} B/s");
        for id in [164, 163, 178, 182, 165, 152, 193] {
            let hz = c.frames[&id] as f64 / 60.0;
            assert!((3.9..=4.1).contains(&hz), "id {id}: {hz} Hz");
        }
        // MAVLink 1: every frame is payload + 8
        let payloads: u64 = ARDUPILOT_STREAMS
            .iter()
            .map(|s| (s.payload_len as u64 + 8) * c.frames[&s.id])
            .sum();
        assert_eq!(payloads + 17 * c.frames[&0], c.total_bytes());
    }

    #[test]
    fn request_data_stream_sets_groups_unless_told_to_ignore_it() {
        use mavlora::dialect::MavDataStream;
        use mavlora::dialect::REQUEST_DATA_STREAM_DATA;
        let req = |id: MavDataStream, hz: u16| {
            let mut s = Sender::new(255, 190, MavlinkVersion::V1);
            s.frame(&MavMessage::REQUEST_DATA_STREAM(REQUEST_DATA_STREAM_DATA {
                target_system: 1,
                target_component: 1,
                req_stream_id: id,
                req_message_rate: hz,
                start_stop: u8::from(hz > 0),
            }))
        };
        let mut fc = ArduPilotFc::new(ArduPilotConfig::default(), Instant::ZERO, 1);
        fc.handle_bytes(
            Instant::ZERO,
            req(MavDataStream::MAV_DATA_STREAM_ALL, 0).as_bytes(),
        );
        fc.handle_bytes(
            Instant::ZERO,
            req(MavDataStream::MAV_DATA_STREAM_POSITION, 3).as_bytes(),
        );
        assert_eq!(fc.group_rate(Group::Extra3), 0.0);
        assert_eq!(fc.group_rate(Group::Position), 3.0);
        let stubborn = ArduPilotConfig {
            obey_stream_requests: false,
            ..Default::default()
        };
        let mut fc = ArduPilotFc::new(stubborn, Instant::ZERO, 1);
        fc.handle_bytes(
            Instant::ZERO,
            req(MavDataStream::MAV_DATA_STREAM_ALL, 0).as_bytes(),
        );
        assert_eq!(fc.group_rate(Group::Extra3), 4.0);
        assert_eq!(fc.stats().stream_requests_ignored, 1);
    }

    #[test]
    fn param_request_list_streams_every_parameter_once() {
        use mavlora::dialect::PARAM_REQUEST_LIST_DATA;
        let config = ArduPilotConfig {
            default_hz: 0.0,
            params: 50,
            ..Default::default()
        };
        let mut fc = ArduPilotFc::new(config, Instant::ZERO, 1);
        let mut s = Sender::new(255, 190, MavlinkVersion::V2);
        let f = s.frame(&MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
            target_system: 1,
            target_component: 1,
        }));
        fc.handle_bytes(Instant::ZERO, f.as_bytes());
        let mut seen = Vec::new();
        let mut now = Instant::ZERO;
        while let Some(t) = fc.poll_timeout() {
            if now > secs(2.0) {
                break;
            }
            now = t.max(now);
            fc.handle_timeout(now);
            while let Some(f) = fc.poll_transmit() {
                if let Ok(MavMessage::PARAM_VALUE(p)) = f.decode::<MavMessage>() {
                    seen.push(p.param_index);
                }
            }
            now += Duration::from_micros(1);
        }
        assert_eq!(seen, (0..50).collect::<Vec<_>>());
    }
}
