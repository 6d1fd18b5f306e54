//! The MultiRX rig: everything the rig knows about MultiRX and nothing else needs to.
//!
//! - [`scenario`]: what is done to the device and measured (the paper's A–D, handover
//!   variants, a six-pilot route, the fail-safe override, line faults);
//! - [`session`]: brings one device up (emulated program or flashed board) with its receiver
//!   fixtures, flight-controller line and status line, and down again;
//! - [`boot_check`]: the device's boot line against the rig file's config;
//! - [`firmware`]: building the SAMD21 image with a mode's config, and flashing it;
//! - [`driver`]: the flight-controller line, receiver fixtures, the status line, the emulated
//!   device's TX probe, the debug probe;
//! - [`px4_rc_input`]: how PX4 reads what MultiRX sends it (an independent SBUS decoder);
//! - [`rigfile`]: the rig file's `[multirx]` section;
//! - `phases`: the phases a rig file's `[multirx]` asks for.

pub mod boot_check;
pub mod driver;
pub mod evidence;
pub mod firmware;
mod phases;
pub mod px4_rc_input;
pub mod rigfile;
pub mod scenario;
pub mod session;

pub use phases::Multirx;

use crate::driver::program::Program;

/// The emulated MultiRX, started when the rig file names no program.
pub const MULTIRX_EMU: Program = Program {
    name: "multirx-emu",
    build: "cargo build -p multirx-emulator",
};
