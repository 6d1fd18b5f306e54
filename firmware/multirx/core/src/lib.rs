//! MultiRX core: lets several RC receivers, each bound to a different pilot's
//! transmitter, share one flight controller (Andersen et al., ICUAS 2021, §V).
//!
//! - [`wire::SbusFrame`] / [`wire::SbusRepr`]: the SBUS frame as a view and a representation;
//! - [`decoder::SbusDecoder`]: finds frames in a byte stream, resynchronising after garbage;
//! - [`config::Config`]: receivers, channels, timeouts, mode; read from TOML with feature `toml`;
//! - [`mux::Multiplexer`]: the engine deciding who is in control and what the flight controller gets;
//! - [`event::TimedEvent`]: power, link and control changes, and their status-line form;
//! - [`boot::BootReport`]: the boot line (build id, config hash, reset cause, boot-to-first-frame);
//! - `provenance` (feature `std`): the commit and input files a build id names;
//! - [`power::PowerSequencer`]: receiver switch-ons staggered against inrush;
//! - [`counter::Counter32`]: a wrapping 32-bit µs counter extended to an [`Instant`];
//! - [`watchdog::FeedGate`]: whether the board may feed its watchdog (engine on time, FC bytes leaving);
//! - [`clock_switch::quiet_window`]: whether the board may move its 48 MHz clock onto the crystal now (between frames);
//! - [`board`]: how many UART inputs the board has ([`board::SAMD21_UARTS`]) and whether a config fits.
//!
//! The contract: no IO, no clock, no allocation, deterministic. Callers pass
//! [`time::Instant`]s (crate `timebase`, shared with MavLora and the radio model) and move bytes; the same code runs in the SAMD21 firmware,
//! the emulated device on a host, and tests under a virtual clock.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]
#![warn(missing_debug_implementations)]

pub mod board;
pub mod boot;
pub mod clock_switch;
pub mod config;
pub mod counter;
pub mod decoder;
pub mod event;
pub mod mux;
pub mod power;
#[cfg(any(test, feature = "std"))]
pub mod provenance;
/// Time as plain numbers: the house's one [`Instant`] and [`Duration`] (crate `timebase`).
pub use timebase as time;
pub mod watchdog;
pub mod wire;

pub use boot::BootReport;
pub use config::{Config, Mode};
pub use event::{Event, StatusLine, TimedEvent};
pub use mux::Multiplexer;
pub use time::{Duration, Instant};
