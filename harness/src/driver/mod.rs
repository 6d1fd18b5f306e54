//! Drivers bind resources (ports, programs) and do things with them
//! (labgrid's vocabulary): read the flight-controller line, play receivers,
//! run the emulated device. Every fixture program goes through one driver,
//! [`fixture`].

pub mod fc;
pub mod fixture;
pub mod probe;
pub mod process;
pub mod program;
pub mod pty;
pub mod radio_emulator;
pub mod receiver;
pub mod status;
pub mod tx_probe;
