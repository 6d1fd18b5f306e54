//! Programmable step attenuators: the bench's RF path between two radios' antenna ports,
//! stepped through an attenuation sweep.
//!
//! [`Attenuator`] is what the rig asks of one, whatever its make: who it is
//! ([`Identity`]), what it can do ([`DbRange`], step), [`Attenuator::set_db`] (round to
//! the step, check the range, command, read back, settle) and [`Attenuator::db`].
//! [`minicircuits::MiniCircuits`] drives Mini-Circuits RUDAT/RCDAT units over Ethernet
//! (Telnet or HTTP); [`emulated::EmulatedMiniCircuits`] is a device on 127.0.0.1 that
//! speaks the same protocol, for CI. [`sweep`] steps one through a list of points and
//! keeps the points done when one fails. [`AttenuatorRecord`] is what results.json
//! keeps; [`config::AttenuatorConfig`] is the rig file's `[attenuator]` table.

pub mod config;
pub mod emulated;
mod http;
pub mod minicircuits;
#[cfg(test)]
mod over_tcp;
mod record;
pub mod telnet;

use std::fmt;
use std::time::{Duration, Instant};

pub use record::AttenuatorRecord;

/// An attenuator the rig can step. Each call is one exchange with the device; a failed
/// call leaves the settings made before it standing (see [`sweep`]).
pub trait Attenuator {
    /// Who the device is, as it said when the driver connected.
    fn identity(&self) -> &Identity;

    /// The settable range, inclusive.
    fn range(&self) -> DbRange;

    /// The smallest step the device sets, in dB; requests are rounded to it.
    fn step_db(&self) -> f64;

    /// How long [`Attenuator::set_db`] waits after the readback before it returns.
    fn settle(&self) -> Duration;

    /// Sets the attenuation: rounds `db` to the step, refuses it outside the range
    /// without commanding the device, commands it, reads it back (an error if the
    /// device reports another value), then waits [`Attenuator::settle`].
    fn set_db(&mut self, db: f64) -> Result<Setting, AttenuatorError>;

    /// The attenuation the device reports now.
    fn db(&mut self) -> Result<f64, AttenuatorError>;

    /// The record results.json keeps of this attenuator.
    fn record(&self) -> AttenuatorRecord {
        AttenuatorRecord::of(self)
    }
}

/// Who an attenuator is: where it is reached and what it says of itself.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity {
    /// The maker, e.g. `Mini-Circuits`.
    pub vendor: String,
    /// Where the rig reaches it, e.g. `192.168.1.10:23 (telnet)`.
    pub address: String,
    /// The model name the device reports, e.g. `RCDAT-6000-90`.
    pub model: String,
    /// The serial number the device reports.
    pub serial: String,
    /// The firmware version, when the device says.
    pub firmware: Option<String>,
}

/// An inclusive attenuation range in dB.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DbRange {
    /// Least attenuation, dB.
    pub min: f64,
    /// Most attenuation, dB.
    pub max: f64,
}

impl DbRange {
    /// Whether `db` lies in the range (NaN does not).
    pub fn contains(&self, db: f64) -> bool {
        self.min <= db && db <= self.max
    }
}

impl fmt::Display for DbRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ..= {} dB", self.min, self.max)
    }
}

/// One setting the device confirmed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setting {
    /// What the caller asked for, dB.
    pub requested_db: f64,
    /// What the device was commanded and read back, dB (the request rounded to the step).
    pub db: f64,
    /// When the settle time ended: the path is at `db` from here on.
    pub settled_at: Instant,
}

/// The device an error is about, as far as the driver knows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceName {
    /// Where the device is reached.
    pub address: String,
    /// Model, once the device said.
    pub model: Option<String>,
    /// Serial number, once the device said.
    pub serial: Option<String>,
}

impl DeviceName {
    /// A device known only by its address (before it answered `MN?`).
    pub fn at(address: impl Into<String>) -> Self {
        DeviceName {
            address: address.into(),
            model: None,
            serial: None,
        }
    }
}

impl From<&Identity> for DeviceName {
    fn from(id: &Identity) -> Self {
        DeviceName {
            address: id.address.clone(),
            model: Some(id.model.clone()),
            serial: Some(id.serial.clone()),
        }
    }
}

impl fmt::Display for DeviceName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "attenuator at {}", self.address)?;
        match (&self.model, &self.serial) {
            (Some(m), Some(s)) => write!(f, " ({m}, SN {s})"),
            (Some(m), None) => write!(f, " ({m})"),
            (None, Some(s)) => write!(f, " (SN {s})"),
            (None, None) => Ok(()),
        }
    }
}

/// Bytes as the device sent them, printable in an error message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bytes(pub Vec<u8>);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "\"{}\"", self.0.escape_ascii())
    }
}

/// What went wrong with an attenuator; each names the device.
#[derive(Debug, thiserror::Error)]
pub enum AttenuatorError {
    /// The device answered a setting with a failure code.
    #[error("{device}: refused {db} dB, answering {answer:?} ({meaning})")]
    Refused {
        device: DeviceName,
        db: f64,
        /// The device's answer, verbatim.
        answer: String,
        /// What the answer means in the device's protocol.
        meaning: &'static str,
    },
    /// The request (after rounding to the step) lies outside the device's range; the
    /// device was not commanded.
    #[error("{device}: {db} dB is outside its range {range}")]
    OutOfRange {
        device: DeviceName,
        db: f64,
        range: DbRange,
    },
    /// The device did not answer a command within the timeout.
    #[error("{device}: no answer to {command:?} within {timeout:?}")]
    Timeout {
        device: DeviceName,
        command: String,
        timeout: Duration,
    },
    /// The connection could not be made, closed, or failed.
    #[error("{device}: connection lost at {command:?}: {source}")]
    ConnectionLost {
        device: DeviceName,
        /// The command in flight (`connect` while connecting).
        command: String,
        source: std::io::Error,
    },
    /// The device answered something the protocol does not allow there.
    #[error("{device}: garbage answer to {command:?}: {bytes}")]
    Garbage {
        device: DeviceName,
        command: String,
        bytes: Bytes,
    },
    /// The device accepted a setting but reports another value.
    #[error("{device}: set {set_db} dB but it reads back {read_db} dB")]
    Readback {
        device: DeviceName,
        set_db: f64,
        read_db: f64,
    },
    /// The device's model is not in the model table and the rig file gives no range and
    /// step for it.
    #[error(
        "{device}: model {model:?} is not in the model table; give range_db and step_db \
         in the rig file's [attenuator] table"
    )]
    UnknownModel { device: DeviceName, model: String },
}

impl AttenuatorError {
    /// The device the error is about.
    pub fn device(&self) -> &DeviceName {
        match self {
            AttenuatorError::Refused { device, .. }
            | AttenuatorError::OutOfRange { device, .. }
            | AttenuatorError::Timeout { device, .. }
            | AttenuatorError::ConnectionLost { device, .. }
            | AttenuatorError::Garbage { device, .. }
            | AttenuatorError::Readback { device, .. }
            | AttenuatorError::UnknownModel { device, .. } => device,
        }
    }
}

/// Rounds `db` to the nearest multiple of `step` above `range.min`, then checks the
/// range: the value every driver commands. NaN and infinities are out of range.
pub fn round_to_step(db: f64, range: DbRange, step: f64) -> Option<f64> {
    if !db.is_finite() {
        return None;
    }
    let steps = ((db - range.min) / step).round();
    let rounded = range.min + steps * step;
    // The multiply can land a hair off the grid (0.1 steps); the grid's own decimals are
    // what the device prints, so snap to a micro-dB.
    let rounded = (rounded * 1e6).round() / 1e6;
    range.contains(rounded).then_some(rounded)
}

/// The outcome of a [`sweep`]: the points the device confirmed, in order, and the error
/// that stopped it, if any.
#[derive(Debug)]
pub struct Sweep {
    /// Confirmed settings, in the order set.
    pub done: Vec<Setting>,
    /// What stopped the sweep before its last point.
    pub error: Option<AttenuatorError>,
}

/// Steps `att` through `points`, calling `at_each` after each confirmed setting (where
/// the caller measures). Stops at the first error; the points done before it stay in
/// [`Sweep::done`], so a run records what it measured before the device went away.
pub fn sweep(att: &mut dyn Attenuator, points: &[f64], mut at_each: impl FnMut(&Setting)) -> Sweep {
    let mut done = Vec::with_capacity(points.len());
    for &db in points {
        match att.set_db(db) {
            Ok(setting) => {
                at_each(&setting);
                done.push(setting);
            }
            Err(error) => {
                tracing::warn!(%error, done = done.len(), "attenuator sweep stopped");
                return Sweep {
                    done,
                    error: Some(error),
                };
            }
        }
    }
    Sweep { done, error: None }
}

#[cfg(test)]
mod tests {
    use super::*;

    const R90: DbRange = DbRange {
        min: 0.0,
        max: 90.0,
    };

    #[test]
    fn rounds_to_the_nearest_step() {
        assert_eq!(round_to_step(30.1, R90, 0.25), Some(30.0));
        assert_eq!(round_to_step(30.13, R90, 0.25), Some(30.25));
        assert_eq!(round_to_step(0.0, R90, 0.25), Some(0.0));
        assert_eq!(round_to_step(90.1, R90, 0.25), Some(90.0));
        assert_eq!(round_to_step(0.3, R90, 0.1), Some(0.3));
    }

    #[test]
    fn refuses_what_rounds_outside_the_range() {
        assert_eq!(round_to_step(90.2, R90, 0.25), None);
        assert_eq!(round_to_step(-0.2, R90, 0.25), None);
        assert_eq!(round_to_step(f64::NAN, R90, 0.25), None);
        assert_eq!(round_to_step(f64::INFINITY, R90, 0.25), None);
    }

    #[test]
    fn device_name_says_what_is_known() {
        let mut d = DeviceName::at("10.0.0.5:23 (telnet)");
        assert_eq!(d.to_string(), "attenuator at 10.0.0.5:23 (telnet)");
        d.model = Some("RCDAT-6000-90".into());
        d.serial = Some("12345".into());
        assert_eq!(
            d.to_string(),
            "attenuator at 10.0.0.5:23 (telnet) (RCDAT-6000-90, SN 12345)"
        );
    }

    proptest::proptest! {
        /// Every rounded value is on the step grid, in range, and within half a step of
        /// the request.
        #[test]
        fn rounding_lands_on_the_grid(db in -10.0f64..100.0, quarter in proptest::bool::ANY) {
            let step = if quarter { 0.25 } else { 0.5 };
            if let Some(r) = round_to_step(db, R90, step) {
                proptest::prop_assert!(R90.contains(r));
                proptest::prop_assert!((r - db).abs() <= step / 2.0 + 1e-9);
                let k = r / step;
                proptest::prop_assert!((k - k.round()).abs() < 1e-6);
            } else {
                proptest::prop_assert!(db < -step / 2.0 || db > 90.0 + step / 2.0 - 1e-9);
            }
        }
    }
}
