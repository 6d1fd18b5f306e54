//! Router side: compact frames in, the standard messages an unmodified ground station
//! expects out, each only once the vehicle reported what it says.

use std::collections::HashMap;

use num_traits::FromPrimitive;

use super::codec::{AirPart, CompactFrame, Positions, Status};
use crate::dialect::{
    GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, GpsFixType, HEARTBEAT_DATA, LINK_QUALITY_DATA,
    MAVLORA_COMPACT_DATA, MISSION_CURRENT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState,
    MavSysStatusSensor, MavSysStatusSensorExtended, MavType, MissionState, SYS_STATUS_DATA,
    VFR_HUD_DATA,
};
use crate::time::{Duration, Instant};

/// The vehicle's HEARTBEAT goes to the ground once a second (the rate MAVLink asks of every
/// component) while compact frames keep coming, also between two frames.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);

/// A heartbeat of our own goes only this long after the last compact frame with positions
/// or a status: one fills a late frame's gap, and none follows a frame that no other follows,
/// so a ground station sees heartbeats stop a second after the link does. A longer hold
/// would hide a short outage, such as a bridge's restart, from the ground station.
pub const HEARTBEAT_HOLD: Duration = Duration::from_millis(1200);

/// Vehicles an expander keeps apart; a frame from one more replaces the one heard least
/// recently (signed frames only reach it, but a key holder must not grow it without bound).
pub const MAX_VEHICLES: usize = 16;

/// What one compact frame stood for.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Expanded {
    /// Standard messages, as the vehicle's autopilot.
    pub messages: Vec<MavMessage>,
    /// The bridge's link-quality report, if the frame carried one (as its own
    /// `LINK_QUALITY` would have said it).
    pub link: Option<LINK_QUALITY_DATA>,
}

/// What the ground was told of one vehicle.
#[derive(Debug, Default)]
struct Vehicle {
    status: Option<Status>,
    /// The autopilot's VFR_HUD airspeed and throttle, as last carried.
    air: Option<AirPart>,
    newest: Option<GLOBAL_POSITION_INT_DATA>,
    /// When the last frame with positions or a status arrived.
    heard: Option<Instant>,
    last_heartbeat: Option<Instant>,
}

impl Vehicle {
    fn heartbeat(&self) -> Option<MavMessage> {
        let h = self.status.as_ref()?.heartbeat?;
        Some(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: h.custom_mode,
            mavtype: MavType::from_u8(h.mavtype)?,
            autopilot: MavAutopilot::from_u8(h.autopilot)?,
            base_mode: MavModeFlag::from_bits_retain(h.base_mode),
            system_status: MavState::from_u8(h.system_status)?,
            mavlink_version: 3,
        }))
    }

    fn heartbeat_due(&self) -> Option<Instant> {
        self.heartbeat()?;
        let heard = self.heard?;
        let due = self.last_heartbeat? + HEARTBEAT_PERIOD;
        (due <= heard + HEARTBEAT_HOLD).then_some(due)
    }
}

/// Sans-IO expander: keeps, per vehicle (system id), the latest status so that every frame
/// can be expanded into full HEARTBEAT / SYS_STATUS / GPS_RAW_INT / MISSION_CURRENT messages
/// too, and keeps each vehicle's HEARTBEAT going between frames
/// ([`poll_heartbeat`](Self::poll_heartbeat)).
#[derive(Debug, Default)]
pub struct Expander {
    vehicles: HashMap<u8, Vehicle>,
    /// Frames that could not be decoded.
    undecodable: u64,
}

impl Expander {
    /// An expander that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Compact frames that could not be decoded (a bridge of another version).
    pub fn undecodable(&self) -> u64 {
        self.undecodable
    }

    /// The standard messages `msg`, a compact frame from vehicle `system` received at `now`,
    /// stands for; empty for messages that are not compact.
    pub fn expand(&mut self, now: Instant, system: u8, msg: &MavMessage) -> Expanded {
        let MavMessage::MAVLORA_COMPACT(data) = msg else {
            return Expanded::default();
        };
        self.expand_data(now, system, data)
    }

    fn expand_data(&mut self, now: Instant, system: u8, data: &MAVLORA_COMPACT_DATA) -> Expanded {
        let Ok(frame) = CompactFrame::decode(data) else {
            self.undecodable += 1;
            return Expanded::default();
        };
        if !self.vehicles.contains_key(&system) && self.vehicles.len() >= MAX_VEHICLES {
            let oldest = self
                .vehicles
                .iter()
                .min_by_key(|(_, v)| v.heard)
                .map(|(id, _)| *id);
            if let Some(id) = oldest {
                self.vehicles.remove(&id);
            }
        }
        let v = self.vehicles.entry(system).or_default();
        let mut out = Vec::new();
        if let Some(status) = frame.status {
            v.status = Some(status);
        }
        if let Some(p) = &frame.positions {
            positions(v, p, &mut out);
        }
        if frame.positions.is_some() || frame.status.is_some() {
            v.heard = Some(now);
            let before = out.len();
            status_messages(v, &mut out);
            if out[before..]
                .iter()
                .any(|m| matches!(m, MavMessage::HEARTBEAT(_)))
            {
                v.last_heartbeat = Some(now);
            }
        }
        Expanded {
            messages: out,
            link: frame.link,
        }
    }

    /// A HEARTBEAT for the ground (with its vehicle's system id) when one is due at `now`: a
    /// period after that vehicle's last, as long as a frame with positions or a status came
    /// within [`HEARTBEAT_HOLD`], and only while its status has the autopilot's heartbeat.
    pub fn poll_heartbeat(&mut self, now: Instant) -> Option<(u8, MavMessage)> {
        let (&system, v) = self
            .vehicles
            .iter_mut()
            .filter(|(_, v)| v.heartbeat_due().is_some_and(|due| now >= due))
            .min_by_key(|(id, _)| **id)?;
        v.last_heartbeat = Some(now);
        Some((system, v.heartbeat()?))
    }

    /// When [`poll_heartbeat`](Self::poll_heartbeat) next has something to give.
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.vehicles
            .values()
            .filter_map(Vehicle::heartbeat_due)
            .min()
    }
}

/// `GLOBAL_POSITION_INT` per sample and, if the autopilot sends VFR_HUD, a `VFR_HUD` of the
/// newest.
fn positions(v: &mut Vehicle, p: &Positions, out: &mut Vec<MavMessage>) {
    let hdg = p.hdg;
    if p.air.is_some() {
        v.air = p.air;
    }
    for s in &p.samples {
        let alt_dm = i64::from(s.rel_dm) + i64::from(p.alt_offset_dm);
        let pos = GLOBAL_POSITION_INT_DATA {
            time_boot_ms: s.time_boot_ms,
            lat: s.lat,
            lon: s.lon,
            alt: (alt_dm * 100).clamp(i32::MIN.into(), i32::MAX.into()) as i32,
            relative_alt: (i64::from(s.rel_dm) * 100).clamp(i32::MIN.into(), i32::MAX.into())
                as i32,
            vx: p.vx,
            vy: p.vy,
            vz: p.vz,
            hdg,
        };
        out.push(MavMessage::GLOBAL_POSITION_INT(pos.clone()));
        v.newest = Some(pos);
    }
    let Some(newest) = &v.newest else { return };
    // VFR_HUD's airspeed and throttle come only from the autopilot's own VFR_HUD, and its
    // heading has no "unknown": without either there is no VFR_HUD.
    let (Some(air), true) = (v.air, hdg != u16::MAX) else {
        return;
    };
    out.push(MavMessage::VFR_HUD(VFR_HUD_DATA {
        airspeed: air.airspeed_cms as f32 / 100.0,
        groundspeed: (f64::from(p.vx).hypot(f64::from(p.vy)) / 100.0) as f32,
        alt: newest.alt as f32 / 1000.0,
        climb: -f32::from(p.vz) / 100.0,
        heading: (hdg / 100) as i16,
        throttle: air.throttle,
    }));
}

/// HEARTBEAT, SYS_STATUS, GPS_RAW_INT and MISSION_CURRENT from the latest status, each only
/// if the autopilot sent that message (GPS_RAW_INT also needs a position).
fn status_messages(v: &Vehicle, out: &mut Vec<MavMessage>) {
    let Some(s) = &v.status else {
        return;
    };
    out.extend(v.heartbeat());
    if let Some(y) = s.sys {
        out.push(MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            onboard_control_sensors_present: MavSysStatusSensor::from_bits_retain(
                y.sensors_present,
            ),
            onboard_control_sensors_enabled: MavSysStatusSensor::from_bits_retain(
                y.sensors_enabled,
            ),
            onboard_control_sensors_health: MavSysStatusSensor::from_bits_retain(y.sensors_health),
            load: y.load,
            voltage_battery: y.voltage_battery,
            current_battery: y.current_battery,
            battery_remaining: y.battery_remaining,
            // The generated Default of a bitflags field is its first flag, not empty: the
            // extended sensor sets must be said to be empty.
            onboard_control_sensors_present_extended: MavSysStatusSensorExtended::empty(),
            onboard_control_sensors_enabled_extended: MavSysStatusSensorExtended::empty(),
            onboard_control_sensors_health_extended: MavSysStatusSensorExtended::empty(),
            ..SYS_STATUS_DATA::default()
        }));
    }
    if let (Some(g), Some(pos)) = (s.gps, &v.newest)
        && let Some(fix_type) = GpsFixType::from_u8(g.fix_type)
    {
        let speed = f64::from(pos.vx).hypot(f64::from(pos.vy));
        // Course over ground from the velocity, unknown when barely moving.
        let cog = if speed >= 10.0 {
            let deg = f64::from(pos.vy).atan2(f64::from(pos.vx)).to_degrees();
            ((deg + 360.0) % 360.0 * 100.0).round() as u16 % 36_000
        } else {
            u16::MAX
        };
        out.push(MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
            time_usec: u64::from(pos.time_boot_ms) * 1000,
            lat: pos.lat,
            lon: pos.lon,
            alt: pos.alt,
            eph: g.eph,
            epv: g.epv,
            vel: speed.round().min(f64::from(u16::MAX - 1)) as u16,
            cog,
            fix_type,
            satellites_visible: g.satellites_visible,
            ..Default::default()
        }));
    }
    if let Some(m) = s.mission
        && let Some(mission_state) = MissionState::from_u8(m.state)
    {
        out.push(MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
            seq: m.seq,
            total: m.total,
            mission_state,
            mission_mode: m.mode,
            ..Default::default()
        }));
    }
}
