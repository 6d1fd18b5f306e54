//! Measurements: every SLA the rig checks is a named value with a unit and
//! limits, recorded with its outcome whether it passes or not (after OpenHTF
//! `core/measurements.py`).
//!
//! A measurement is declared once, as a [`Spec`]: base name, [`Dimensions`]
//! (device, mode, radio...), unit, description and [`Limits`]. A phase
//! declares its specs before it runs ([`Declarations::declare`]) and records
//! each through the [`Handle`] that gives. Its [`Outcome`] is computed from
//! the value and the limits at that moment and saved with both in the
//! record's [`Measurement`], so a reviewer can check the verdict without
//! rerunning. The flat name readers know (`dut.fast.handover_ms`) is
//! made from the dimensions in one place, [`flat_name`]; reports select by
//! dimension ([`Selector`]), never by picking names apart.

mod declare;
mod dimension;
mod limits;

pub use declare::{Declarations, Handle, Spec};
pub use dimension::{Dimension, Dimensions, PTY, PX4, RELAY, SIMULATED, Selector, flat_name};
pub use limits::{Limits, Outcome};

use serde::{Deserialize, Serialize};

/// A declared measurement in a phase's record: flat name and dimensions,
/// unit, limits, and the value and outcome once recorded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measurement {
    /// Dotted name made from the dimensions and base name by [`flat_name`],
    /// e.g. `dut.fast.handover_ms`; rig files override limits by this
    /// name.
    pub name: String,
    /// What the measurement is of (device, mode, radio...); empty in
    /// records saved before dimensions existed.
    #[serde(default)]
    pub dimensions: Dimensions,
    /// Unit the value and limits are in (`ms`, `B/s`, `Hz`, or empty).
    pub unit: String,
    /// What is measured and why it matters, for the reviewer.
    #[serde(default)]
    pub description: String,
    /// Accepted range.
    pub limits: Limits,
    /// Recorded value; `None` until recorded, or when skipped. Serialized as
    /// `null` when not finite (JSON has no NaN), with a note saying so.
    pub value: Option<f64>,
    /// Verdict computed when the value was recorded.
    pub outcome: Outcome,
    /// Why the measurement was skipped, or a remark on the value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

impl Measurement {
    /// The base name: the flat name without what [`flat_name`] made of the
    /// dimensions. `None` when the name was not made from them (a record
    /// saved before dimensions existed has none, and no base name).
    pub fn base(&self) -> Option<&str> {
        if self.dimensions.is_empty() {
            return None;
        }
        self.name
            .strip_prefix(flat_name(&self.dimensions, "").as_str())
            .filter(|b| !b.is_empty())
    }

    /// Records a value and judges it against the limits. Recording again
    /// replaces the earlier value.
    pub fn record(&mut self, value: f64) -> Outcome {
        self.value = Some(value);
        self.outcome = self.limits.judge(value);
        if !value.is_finite() && self.note.is_none() {
            self.note = Some(format!("recorded value was {value}"));
        }
        self.outcome
    }

    /// Marks the measurement as deliberately not taken, with the reason.
    pub fn skip(&mut self, why: impl Into<String>) {
        self.value = None;
        self.outcome = Outcome::Skipped;
        self.note = Some(why.into());
    }

    /// Adds a remark kept with the value (e.g. how it was derived).
    pub fn annotate(&mut self, note: impl Into<String>) {
        self.note = Some(note.into());
    }

    /// The value with its unit (`12.5 ms`), or `unset`/`skipped`.
    pub fn render_value(&self) -> String {
        match (self.value, self.outcome) {
            (Some(v), _) if self.unit.is_empty() => format_value(v),
            (Some(v), _) => format!("{} {}", format_value(v), self.unit),
            (None, Outcome::Skipped) => "skipped".to_owned(),
            (None, Outcome::Fail) => "not a number".to_owned(),
            (None, _) => "unset".to_owned(),
        }
    }
}

/// At most three decimals, trailing zeros trimmed: `0.7`, `63.492`, `5`.
/// The full value stays in results.json.
fn format_value(v: f64) -> String {
    let text = format!("{v:.3}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

#[cfg(test)]
mod tests;
