//! The rig: runs C2-link scenarios against MultiRX and MavLora on a bench
//! (real serial ports) or emulated (pty pairs), and writes evidence.
//!
//! Vocabulary (after labgrid and OpenHTF):
//! - [`rigfile`]: the rig description (TOML) naming ports, devices, fixtures and limits;
//! - [`driver`]: binds a resource (a port, a program) and does things with it;
//! - [`strategy`]: brings devices from files on disk to running and wired;
//! - [`scenario`]: what is done to the devices and measured;
//! - [`measurement`]: a value with a unit, limits and an outcome, declared once with its
//!   dimensions (device, mode, radio...) and recorded through its handle;
//! - [`record`]: the saved record of a run, from which [`report`]s are rendered;
//! - [`px4`]: how the flight controller reads what it is sent;
//! - [`stats`]: percentiles and rates of the raw samples fixtures report;
//! - [`harness_radio`] (its own crate): the model of line-of-sight radios (airtime, loss, duty
//!   cycle) that the radio emulator driver and the simulated worlds run;
//! - [`runner`]: scenarios as libtest-mimic trials, and the run record.

pub mod clock;
pub mod driver;
pub mod evidence;
pub mod heap;
pub mod measurement;
pub mod px4;
pub mod record;
pub mod report;
pub mod rigfile;
pub mod runner;
pub mod scenario;
pub mod stats;
pub mod strategy;
