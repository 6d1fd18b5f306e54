//! MavLora: a MAVLink library that fits command-and-control traffic through slow
//! line-of-sight radios (Andersen et al., ICUAS 2021, section IV).
//!
//! - [`wire`]: raw frames ([`wire::Frame`]) and a sans-IO stream reader
//!   ([`wire::FrameReader`]) that resynchronises after garbage and counts bad checksums and
//!   sequence gaps per stream.
//! - [`filter`]: a [`filter::Profile`] file drives both the flight controller's stream rates
//!   and the radio filter ([`filter::RadioFilter`]): drop, pass or limit each message.
//! - [`schedule`]: the link budget scheduler ([`schedule::LinkScheduler`]): a token bucket
//!   in bytes per second, priority traffic first, newest periodic sample replaces older.
//! - [`quality`]: the link-quality engine ([`quality::LinkQuality`]): reports what this side
//!   hears in `LINK_QUALITY` (id 15) and tracks what the other side reports.
//! - [`bridge`]: the companion computer's engine ([`bridge::Bridge`]): flight controller ↔
//!   radio, stream-rate configuration (again after a reboot), filter and scheduler, compact
//!   telemetry, mission relay, link quality.
//! - [`router`]: the ground station's engine ([`router::Router`]): radio ↔ ground stations,
//!   compact telemetry expanded back into standard messages.
//! - [`compact`]: [`compact::Compactor`] and [`compact::Expander`] (`MAVLORA_COMPACT`, id 14:
//!   positions, the status and the bridge's link report packed in one frame a second), with
//!   their precision.
//! - [`mission`]: the mission relay with radio round-trip-time timeouts.
//! - [`param`]: parameter lists packed several values to a frame on the radio
//!   (`MAVLORA_PARAM_VALUES`, id 13), given back to the ground as the standard `PARAM_VALUE`s.
//! - [`command`]: the command relay: the router resends commands over the radio on a
//!   measured round-trip timeout, the bridge answers copies from its ack cache.
//! - [`signing`]: MAVLink 2 signing of the radio link, replay rejection.
//! - `io` (feature `cli`): the binaries' serial, UDP and `.tlog` driver — the only code here
//!   that does IO or reads a clock.
//! - [`dialect`]: the generated MavLora dialect, `common.xml` plus `MAVLORA_PARAM_VALUES` (13,
//!   packed parameter values), `MAVLORA_COMPACT` (14, compact telemetry), `LINK_QUALITY` (15),
//!   `MAVLORA_MISSION_ITEMS` (19, the mission radio leg's packed items) and, unused by the engines, `MAVLORA_TELEMETRY` (16),
//!   `MAVLORA_POSITION_BATCH` (17) and `MAVLORA_STATUS` (18).
//!
//! # Contract
//! The engines do no IO and read no clock: callers pass bytes and the current [`Instant`] in
//! and take bytes and deadlines out, so the same code runs over serial ports, UDP or a virtual
//! clock in tests, deterministically.

#![deny(unsafe_code)]
#![warn(missing_docs)]

pub use mavlora_dialect as dialect;

pub mod bridge;
pub mod command;
pub mod compact;
pub mod filter;
mod input_file;
#[cfg(feature = "cli")]
pub mod io;
pub mod mission;
pub mod param;
pub mod quality;
pub mod router;
pub mod schedule;
pub mod signing;
/// Time as plain values: the house's one [`Instant`] and [`Duration`] (crate `timebase`,
/// shared with MultiRX and the radio model); the IO driver converts at the edge.
pub use timebase as time;
pub mod wire;

pub use time::{Duration, Instant};

#[cfg(test)]
mod testutil;
