//! Router side: compact frames in, the standard messages an unmodified ground station
//! expects out.

use super::MAX_BATCH_SAMPLES;
use crate::dialect::{
    GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, HEARTBEAT_DATA, MAVLORA_POSITION_BATCH_DATA,
    MAVLORA_STATUS_DATA, MISSION_CURRENT_DATA, MavMessage, MavSysStatusSensor,
    MavSysStatusSensorExtended, SYS_STATUS_DATA, VFR_HUD_DATA,
};
use crate::time::{Duration, Instant};

/// The vehicle's HEARTBEAT goes to the ground once a second (the rate MAVLink asks of every
/// component) while compact frames keep coming, although a batch comes only every 2 s: a
/// ground station that misses heartbeats for a few seconds calls the link lost.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);

/// A heartbeat of our own goes only this long after the last compact frame: one fills the
/// second between two batches, and none follows a frame that no other follows, so a ground
/// station sees heartbeats stop a second after the link does, as it would with a batch every
/// second. A longer hold would hide a short outage, such as a bridge's restart, from the
/// ground station.
pub const HEARTBEAT_HOLD: Duration = Duration::from_millis(1200);

/// Sans-IO expander: keeps the latest status so position batches can be expanded into full
/// HEARTBEAT / SYS_STATUS / GPS_RAW_INT messages too, and keeps the vehicle's HEARTBEAT
/// going between batches ([`poll_heartbeat`](Self::poll_heartbeat)).
#[derive(Debug, Default)]
pub struct Expander {
    status: Option<MAVLORA_STATUS_DATA>,
    newest: Option<GLOBAL_POSITION_INT_DATA>,
    groundspeed_cm: u16,
    /// The vehicle whose compact frames were expanded last, and when one arrived.
    heard: Option<(u8, Instant)>,
    last_heartbeat: Option<Instant>,
}

impl Expander {
    /// An expander that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// The standard messages `msg`, a compact frame from vehicle `system` received at `now`,
    /// stands for; empty for messages that are not compact.
    pub fn expand(&mut self, now: Instant, system: u8, msg: &MavMessage) -> Vec<MavMessage> {
        let out = self.expand_message(msg);
        if matches!(
            msg,
            MavMessage::MAVLORA_POSITION_BATCH(_) | MavMessage::MAVLORA_STATUS(_)
        ) {
            self.heard = Some((system, now));
        }
        if out.iter().any(|m| matches!(m, MavMessage::HEARTBEAT(_))) {
            self.last_heartbeat = Some(now);
        }
        out
    }

    /// A HEARTBEAT for the ground (with the vehicle's system id) when one is due at `now`:
    /// a period after the last, as long as a compact frame came within [`HEARTBEAT_HOLD`].
    pub fn poll_heartbeat(&mut self, now: Instant) -> Option<(u8, MavMessage)> {
        let due = self.heartbeat_due()?;
        if now < due {
            return None;
        }
        self.last_heartbeat = Some(now);
        let (system, _) = self.heard?;
        Some((system, heartbeat(self.status.as_ref()?)))
    }

    /// When [`poll_heartbeat`](Self::poll_heartbeat) next has something to give.
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.heartbeat_due()
    }

    fn heartbeat_due(&self) -> Option<Instant> {
        self.status.as_ref()?;
        let (_, heard) = self.heard?;
        let due = self.last_heartbeat? + HEARTBEAT_PERIOD;
        (due <= heard + HEARTBEAT_HOLD).then_some(due)
    }

    fn expand_message(&mut self, msg: &MavMessage) -> Vec<MavMessage> {
        match msg {
            MavMessage::MAVLORA_POSITION_BATCH(batch) => self.batch(batch),
            MavMessage::MAVLORA_STATUS(status) => {
                self.status = Some(status.clone());
                let mut out = self.status_messages();
                out.push(MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
                    seq: status.mission_seq,
                    ..Default::default()
                }));
                out
            }
            _ => Vec::new(),
        }
    }

    fn batch(&mut self, b: &MAVLORA_POSITION_BATCH_DATA) -> Vec<MavMessage> {
        let offset = self.status.as_ref().map_or(0, |s| i32::from(s.alt_offset));
        let speed_cm = i32::from(b.groundspeed) * 10;
        let (vx, vy) = if b.hdg == u16::MAX {
            (0, 0)
        } else {
            let rad = (f64::from(b.hdg) / 100.0).to_radians();
            let v = f64::from(speed_cm);
            (
                (v * rad.cos()).round() as i16,
                (v * rad.sin()).round() as i16,
            )
        };
        let vz = -i16::from(b.climb) * 10;
        let count = usize::from(b.count).clamp(1, MAX_BATCH_SAMPLES);
        let mut out = Vec::with_capacity(count + 4);
        for i in 0..count {
            let (dlat, dlon, drel, dt) = if i == 0 {
                (0, 0, 0, 0)
            } else {
                (
                    i32::from(b.dlat[i - 1]),
                    i32::from(b.dlon[i - 1]),
                    i32::from(b.drelative_alt[i - 1]),
                    u32::from(b.dt[i - 1]) * 10,
                )
            };
            let rel_dm = i32::from(b.relative_alt) + drel;
            let pos = GLOBAL_POSITION_INT_DATA {
                time_boot_ms: b.time_boot_ms.wrapping_add(dt),
                lat: b.lat.wrapping_add(dlat),
                lon: b.lon.wrapping_add(dlon),
                alt: (rel_dm + offset) * 100,
                relative_alt: rel_dm * 100,
                vx,
                vy,
                vz,
                hdg: b.hdg,
            };
            out.push(MavMessage::GLOBAL_POSITION_INT(pos.clone()));
            self.newest = Some(pos);
        }
        self.groundspeed_cm = speed_cm as u16;
        let newest = self.newest.clone().unwrap_or_default();
        out.push(MavMessage::VFR_HUD(VFR_HUD_DATA {
            airspeed: 0.0,
            groundspeed: speed_cm as f32 / 100.0,
            alt: newest.alt as f32 / 1000.0,
            climb: f32::from(b.climb) / 10.0,
            heading: if b.hdg == u16::MAX {
                0
            } else {
                (b.hdg / 100) as i16
            },
            throttle: 0,
        }));
        out.extend(self.status_messages());
        out
    }

    /// HEARTBEAT, SYS_STATUS and GPS_RAW_INT from the latest status and position (nothing
    /// before the first status: a heartbeat with an unknown vehicle type would mislead).
    fn status_messages(&self) -> Vec<MavMessage> {
        let Some(s) = &self.status else {
            return Vec::new();
        };
        let pos = self.newest.clone().unwrap_or_default();
        vec![
            heartbeat(s),
            MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                onboard_control_sensors_present: MavSysStatusSensor::empty(),
                onboard_control_sensors_enabled: MavSysStatusSensor::empty(),
                onboard_control_sensors_health: MavSysStatusSensor::empty(),
                load: 0,
                voltage_battery: s.voltage_battery,
                current_battery: -1,
                battery_remaining: s.battery_remaining,
                // The generated Default of a bitflags field is its first flag, not empty: the
                // extended sensor sets must be said to be empty.
                onboard_control_sensors_present_extended: MavSysStatusSensorExtended::empty(),
                onboard_control_sensors_enabled_extended: MavSysStatusSensorExtended::empty(),
                onboard_control_sensors_health_extended: MavSysStatusSensorExtended::empty(),
                ..SYS_STATUS_DATA::default()
            }),
            MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                time_usec: u64::from(pos.time_boot_ms) * 1000,
                lat: pos.lat,
                lon: pos.lon,
                alt: pos.alt,
                eph: u16::MAX,
                epv: u16::MAX,
                vel: self.groundspeed_cm,
                cog: pos.hdg,
                fix_type: s.fix_type,
                satellites_visible: s.satellites_visible,
                ..Default::default()
            }),
        ]
    }
}

/// The vehicle's HEARTBEAT as its latest status describes it.
fn heartbeat(s: &MAVLORA_STATUS_DATA) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: s.custom_mode,
        mavtype: s.mavtype,
        autopilot: s.autopilot,
        base_mode: s.base_mode,
        system_status: s.system_status,
        mavlink_version: 3,
    })
}
