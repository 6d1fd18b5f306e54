//! Why a radio description was refused.

/// A preset or link setting the model cannot honour, found when a [`Link`](super::Link)
/// or [`Radio`](super::Radio) is built, so a bad rig file fails before a run starts.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// A preset name that is not built in.
    #[error("unknown radio preset {name:?}; built in: {builtin}")]
    UnknownPreset {
        /// The name given.
        name: String,
        /// The built-in names, comma separated.
        builtin: String,
    },
    /// A number is outside what the radio or the model accepts (a LoRa spreading
    /// factor of 13, a probability above 1, a negative latency, ...).
    #[error("{field} = {value} is out of range: expected {expected}")]
    OutOfRange {
        /// The setting, as named in the rig file.
        field: &'static str,
        /// The value given.
        value: f64,
        /// The accepted range, in words.
        expected: &'static str,
    },
    /// The largest air packet does not fit in one TDM window, so a full buffer
    /// could never be sent.
    #[error(
        "a {payload}-byte packet needs {airtime_ms:.3} ms on air but the TDM window is {window_ms:.3} ms"
    )]
    WindowTooShort {
        /// Largest payload of the preset, bytes.
        payload: usize,
        /// Its time on air, ms.
        airtime_ms: f64,
        /// The TDM transmit window, ms.
        window_ms: f64,
    },
    /// The duty-cycle budget per window is shorter than one full packet, so an
    /// enforcing link would hold that packet forever.
    #[error(
        "duty-cycle budget {budget_ms:.3} ms per window is shorter than one {payload}-byte packet ({airtime_ms:.3} ms)"
    )]
    DutyBudgetTooSmall {
        /// `max_share` × `window_s`, ms.
        budget_ms: f64,
        /// Largest payload of the preset, bytes.
        payload: usize,
        /// Its time on air, ms.
        airtime_ms: f64,
    },
}

/// Checks `lo <= value <= hi` (and finiteness) for a named setting.
pub(crate) fn check_range(
    field: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    expected: &'static str,
) -> Result<(), ConfigError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(ConfigError::OutOfRange {
            field,
            value,
            expected,
        })
    }
}
