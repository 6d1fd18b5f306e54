//! Compact telemetry: the bridge packs the periodic messages a ground station needs, and its
//! own link-quality report, into `MAVLORA_COMPACT` frames (id 14): by default one a second
//! with three positions, the status riding along every 10 s and at once (three copies) on a
//! change of mode, arming or state; the router expands them back into standard messages, each
//! only once the vehicle reported what it says, and keeps each vehicle's HEARTBEAT at 1 Hz
//! while frames come. The batching is a profile's `[compact]` table ([`CompactConfig`]).
//!
//! # Precision (what `expand(compact(x))` gives back)
//! | field | carried as | exact to |
//! |---|---|---|
//! | `GLOBAL_POSITION_INT.lat/lon` | sample 0 absolute, the others as predicted differences | exact |
//! | `GLOBAL_POSITION_INT.relative_alt` | dm | ±50 mm, any value |
//! | `GLOBAL_POSITION_INT.alt` | `relative_alt` + the frame's MSL offset (dm, its newest sample's) | ±100 mm, any value, while the autopilot's `alt - relative_alt` is steady (it may move up to 1 m within a frame: more starts a new frame) |
//! | `GLOBAL_POSITION_INT.time_boot_ms` | sample 0 exact, the others in 10 ms steps from it | ±5 ms |
//! | `GLOBAL_POSITION_INT.vx/vy/vz`, `hdg` | the newest sample's, in every sample of its frame | exact (older samples: the newest's) |
//! | `VFR_HUD` airspeed, throttle | the autopilot's latest VFR_HUD, when it moved 0.5 m/s or 5 % since the last sent, and with every status | ±0.5 m/s, ±5 % (exact when sent: cm/s) |
//! | `VFR_HUD` groundspeed, climb, heading, alt | from the newest sample's `vx/vy/vz`, `hdg`, `alt` | exact (heading: whole degrees, as VFR_HUD) |
//! | `HEARTBEAT` type, autopilot, base_mode, custom_mode, system_status | as is | exact; a change at the ground within 0.5 s of the bridge (three copies 150 ms apart, then in every frame for 5 s); else at most `status_period` old |
//! | `SYS_STATUS` sensors present/enabled/health, load, voltage, current, remaining | as is | exact, at most `status_period` old |
//! | `GPS_RAW_INT` fix type, satellites, eph, epv | as is | exact, at most `status_period` old (a change of fix type rides the next frame, at most one such change per 5 s) |
//! | `MISSION_CURRENT` seq, total, mission_state, mission_mode | as is | exact (a change rides the next frame, at most one per 5 s) |
//! | `LINK_QUALITY` (the bridge's) | as is | exact |
//!
//! Remaining limits (not carried; what the ground is given instead):
//! - `VFR_HUD` only while the autopilot sends its own (airspeed and throttle are nowhere
//!   else): its ground speed, climb, heading and altitude are `GLOBAL_POSITION_INT`'s.
//! - `GPS_RAW_INT` lat/lon/alt/time are the newest `GLOBAL_POSITION_INT`'s (the autopilot's
//!   fused position, not the receiver's raw fix), `vel`/`cog` its velocity's (`cog` unknown,
//!   `UINT16_MAX`, under 0.1 m/s); its extension fields (`alt_ellipsoid`, accuracies, `yaw`)
//!   are 0 (unknown / not provided). It is sent only once a position and a GPS status came.
//! - `SYS_STATUS` comm drop rate and error counters are 0; the extended sensor sets empty.
//! - `MISSION_CURRENT` `mission_id`, `fence_id`, `rally_points_id` are 0 ("not supported").
//! - The vehicle's HEARTBEAT between frames repeats its last status; it stops 1.2 s after the
//!   last frame with positions or a status, and 3 s after the autopilot's own stopped (the
//!   status then says it has none).
//!
//! Nothing is sent for a message the vehicle never sent: no SYS_STATUS before its first
//! SYS_STATUS, no GPS_RAW_INT before a fix status and a position, no HEARTBEAT before its
//! HEARTBEAT. Each vehicle (system id) is expanded from its own state.

mod codec;
mod compactor;
mod expander;
mod merge;

pub use codec::{
    AirPart, CompactFrame, DATA_LEN, DecodeError, EncodeError, GpsPart, HeartbeatPart, MAX_SAMPLES,
    MissionPart, Positions, Sample, Status, SysPart,
};
pub use compactor::{
    AIRSPEED_DEADBAND_CMS, CompactConfig, CompactStats, Compactor, HEARTBEAT_STALE,
    MAX_BATCH_SAMPLES, REPLACED_IDS, STATUS_CHANGE_MIN, THROTTLE_DEADBAND, URGENT_COPIES,
    URGENT_FOLLOW, URGENT_SPACING,
};
pub use expander::{Expanded, Expander, HEARTBEAT_HOLD, HEARTBEAT_PERIOD, MAX_VEHICLES};
pub use merge::{MergeLoss, merge};

#[cfg(test)]
mod tests;
