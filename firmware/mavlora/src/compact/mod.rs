//! Compact telemetry: the bridge packs the periodic messages a ground station needs into
//! `MAVLORA_POSITION_BATCH` (17, one frame every 2 s with six positions) and
//! `MAVLORA_STATUS` (18, on change and every few seconds); the router expands them back into
//! standard messages, and keeps the vehicle's HEARTBEAT at 1 Hz while batches come.
//!
//! # Precision (what `expand(compact(x))` gives back)
//! | field | carried as | exact to |
//! |---|---|---|
//! | `GLOBAL_POSITION_INT.lat/lon` | sample 0 absolute, others i16 deltas | exact (a delta that does not fit starts a new batch) |
//! | `GLOBAL_POSITION_INT.relative_alt` | i16 dm, i8 dm deltas | ±50 mm (range ±3276 m) |
//! | `GLOBAL_POSITION_INT.alt` | `relative_alt` + `alt_offset` (dm) | ±100 mm |
//! | `GLOBAL_POSITION_INT.time_boot_ms` | sample 0 exact, others +10 ms steps | ±5 ms |
//! | `GLOBAL_POSITION_INT.hdg` | newest sample, cdeg | exact |
//! | ground speed (`VFR_HUD`, `GPS_RAW_INT.vel`, `vx/vy`) | u8 dm/s, from `vx, vy` | ±5 cm/s up to 25.5 m/s |
//! | climb (`VFR_HUD.climb`, `vz`) | i8 dm/s | ±5 cm/s within ±12.7 m/s |
//! | `HEARTBEAT` type, autopilot, base_mode, custom_mode, system_status | as is | exact |
//! | `SYS_STATUS` voltage, remaining; `GPS_RAW_INT` fix, satellites; `MISSION_CURRENT.seq` | as is | exact |
//!
//! Not carried (set to "unknown" or zero by the expander): sensor health bits, load and comm
//! counters of `SYS_STATUS`, `eph/epv` of `GPS_RAW_INT`, airspeed and throttle of `VFR_HUD`.
//! `vx/vy` are rebuilt from ground speed and heading (exact in still air only: heading is not
//! course over ground).

mod compactor;
mod expander;

pub use compactor::{CompactConfig, CompactStats, Compactor, MAX_BATCH_SAMPLES, REPLACED_IDS};
pub use expander::{Expander, HEARTBEAT_HOLD, HEARTBEAT_PERIOD};

#[cfg(test)]
mod tests;
