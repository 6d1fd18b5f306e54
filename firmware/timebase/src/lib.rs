//! One idea of time for the sans-IO engines (after smoltcp `time.rs`): [`Instant`], a point
//! in time in microseconds since an epoch the caller chooses, and [`Duration`], a span in
//! microseconds.
//!
//! Engines never read a clock: the firmware maps a hardware timer, the IO drivers
//! `std::time::Instant`, tests and simulations a virtual clock to [`Instant::from_micros`].
//! Both types are a `u64` of microseconds so the Cortex-M0 firmware loop needs no 128-bit
//! maths (`core::time::Duration` is seconds + nanoseconds), and so points in time can start
//! at zero and print readably. All arithmetic saturates: a clock that steps back or an
//! absurd setting must not panic an engine.
//!
//! IO drivers convert at the edge: `Duration::from(core::time::Duration)` (truncated to whole
//! microseconds) and `core::time::Duration::from(Duration)`.

#![no_std]
#![deny(unsafe_code)]
#![warn(missing_docs)]

mod duration;
mod instant;

pub use duration::Duration;
pub use instant::Instant;
