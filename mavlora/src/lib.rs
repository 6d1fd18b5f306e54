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
//! - [`dialect`]: the generated MavLora dialect, `common.xml` plus `LINK_QUALITY` (15) and
//!   `MAVLORA_TELEMETRY` (16).
//!
//! # Contract
//! The engines do no IO and read no clock: callers pass bytes and the current [`Instant`] in
//! and take bytes and deadlines out, so the same code runs over serial ports, UDP or a virtual
//! clock in tests, deterministically.

#![deny(unsafe_code)]
#![warn(missing_docs)]

pub use mavlora_dialect as dialect;

pub mod filter;
pub mod quality;
pub mod schedule;
pub mod time;
pub mod wire;

pub use time::Instant;

#[cfg(test)]
mod testutil;
