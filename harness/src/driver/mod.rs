//! Drivers bind resources (ports, programs) and do things with them
//! (labgrid's vocabulary): read the flight-controller line, play receivers,
//! run the emulated device.

pub mod fc;
pub mod probe;
pub mod process;
pub mod program;
pub mod pty;
pub mod radio_emulator;
pub mod receiver;
pub mod status;
