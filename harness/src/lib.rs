//! The rig: runs C2-link scenarios against MultiRX and MavLora on a bench
//! (real serial ports) or emulated (pty pairs), and writes evidence.
//!
//! Vocabulary (after labgrid and OpenHTF):
//! - [`rigfile`]: the rig description (TOML) naming ports, devices, fixtures and limits;
//! - [`measurement`]: a named value with a unit, limits and an outcome;
//! - [`record`]: the saved record of a run, from which [`report`]s are rendered.

pub mod measurement;
pub mod record;
pub mod report;
pub mod rigfile;
