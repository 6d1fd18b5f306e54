//! The rig: runs C2-link scenarios against MultiRX and MavLora on a bench
//! (real serial ports) or emulated (pty pairs), and writes evidence.
//!
//! Shared by every device, and naming none (vocabulary after labgrid and OpenHTF):
//! - [`rigfile`]: the rig description (TOML) naming ports, devices, fixtures and limits;
//! - [`driver`]: binds a resource (a pty, a program, a fixture, the radio emulator) and does
//!   things with it;
//! - [`measurement`]: a value with a unit, limits and an outcome, declared once with its
//!   dimensions (device, mode, radio...) and recorded through its handle;
//! - [`runner`]: the phases devices hand it, run as libtest-mimic trials, and the run record
//!   kept true as they run;
//! - [`record`]: the saved record of a run, from which [`report`]s are rendered;
//! - [`evidence`]: reproducible builds, certification folders, the trace matrix;
//! - [`stats`], [`clock`], [`heap`]: percentiles, the monotonic clock fixtures share, the
//!   allocation meter.
//!
//! One folder per device, each owning its scenarios, sessions, drivers, fixture bindings and
//! report sections: [`multirx`], [`mavlora`]. [`devices`] is the registry that names them.

pub mod clock;
pub mod devices;
pub mod driver;
pub mod evidence;
pub mod heap;
pub mod mavlora;
pub mod measurement;
pub mod multirx;
pub mod record;
pub mod report;
pub mod rigfile;
pub mod runner;
pub mod stats;
