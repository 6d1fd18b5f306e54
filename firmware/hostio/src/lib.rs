//! What the programs that run on a host share, so each is written once: the programs under
//! test (`multirx-emu`, `mavlora-bridge`, `mavlora-router`) and the rig (`harness/`) alike.
//!
//! - [`logging::init`]: `tracing` to stderr, filtered by `RUST_LOG`, with a default level per
//!   program;
//! - [`realtime::request`]: SCHED_FIFO for a thread whose timing is measured;
//! - [`sbus::port`] (feature `sbus`): a serial port with SBUS's UART settings;
//! - [`device`]: which device a port name leads to, checked before a port is reopened
//!   (USB serial numbers with feature `serial`);
//! - [`status`] (feature `status`): the versioned JSON-lines status stream the programs under
//!   test write (`--status-json`) and the rig reads, schema in `STATUS-JSON.md`.
//!
//! The host programs and the rig both link this crate; it depends on no rig code, so what the
//! programs under test run never depends on the rig that judges them.

#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod device;
pub mod logging;
pub mod realtime;
#[cfg(feature = "sbus")]
pub mod sbus;
#[cfg(feature = "status")]
pub mod status;
