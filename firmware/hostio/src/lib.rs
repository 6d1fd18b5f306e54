//! What the programs that run on a host share, the device programs (`multirx-emu`,
//! `mavlora-bridge`, `mavlora-router`) and the rig alike, so each is written once:
//!
//! - [`logging::init`]: `tracing` to stderr, filtered by `RUST_LOG`, with a default level per
//!   program;
//! - [`realtime::request`]: SCHED_FIFO for a thread whose timing is measured;
//! - [`sbus::port`] (feature `sbus`): a serial port with SBUS's UART settings;
//! - [`device`]: which device a port name leads to, checked before a port is reopened
//!   (USB serial numbers with feature `serial`).
//!
//! The devices link this crate, never the rig.

#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod device;
pub mod logging;
pub mod realtime;
#[cfg(feature = "sbus")]
pub mod sbus;
