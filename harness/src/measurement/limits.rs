//! Limits and the outcome they give a value.

use std::fmt;

use serde::{Deserialize, Serialize};

/// Accepted range of a measurement, with an optional marginal band inside it.
///
/// Bounds are inclusive: `max = 50` accepts 50. The marginal band is also
/// inclusive, as in OpenHTF: with `max = 4500, marginal_max = 4000`, 4000 is
/// marginal and 4501 fails. A value in the marginal band still passes; the
/// band flags values that are close enough to a limit to deserve attention.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Lowest passing value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min: Option<f64>,
    /// Highest passing value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max: Option<f64>,
    /// Values at or below this (and at or above `min`) are marginal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub marginal_min: Option<f64>,
    /// Values at or above this (and at or below `max`) are marginal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub marginal_max: Option<f64>,
}

impl Limits {
    /// No limits: any recorded number passes (an informational measurement).
    pub const NONE: Limits = Limits {
        min: None,
        max: None,
        marginal_min: None,
        marginal_max: None,
    };

    /// Whether no bound at all is set.
    pub fn is_empty(&self) -> bool {
        *self == Self::NONE
    }

    /// Checks that the limits can be met and are ordered, so that a typo in a
    /// rig file cannot turn an SLA into one that always fails or never does.
    ///
    /// Requires every bound finite, `min <= max`, `marginal_min <=
    /// marginal_max`, and a marginal band strictly inside the limit it
    /// shadows (`min < marginal_min`, `marginal_max < max`).
    pub fn validate(&self) -> Result<(), String> {
        let named = [
            ("min", self.min),
            ("max", self.max),
            ("marginal_min", self.marginal_min),
            ("marginal_max", self.marginal_max),
        ];
        for (name, v) in named {
            if let Some(v) = v
                && !v.is_finite()
            {
                return Err(format!("{name} = {v} is not a finite number"));
            }
        }
        let ordered = [
            ("min", self.min, "max", self.max, false),
            (
                "marginal_min",
                self.marginal_min,
                "marginal_max",
                self.marginal_max,
                false,
            ),
            ("min", self.min, "marginal_min", self.marginal_min, true),
            ("marginal_max", self.marginal_max, "max", self.max, true),
            ("min", self.min, "marginal_max", self.marginal_max, true),
            ("marginal_min", self.marginal_min, "max", self.max, true),
        ];
        for (ln, lo, hn, hi, strict) in ordered {
            if let (Some(lo), Some(hi)) = (lo, hi) {
                let bad = if strict { lo >= hi } else { lo > hi };
                if bad {
                    let op = if strict { "<" } else { "<=" };
                    return Err(format!("{ln} = {lo} and {hn} = {hi}: need {ln} {op} {hn}"));
                }
            }
        }
        Ok(())
    }

    /// Judges a value against these limits. NaN always fails, because a
    /// computation that produced no number has not shown the SLA is met.
    pub fn judge(&self, value: f64) -> Outcome {
        if value.is_nan() {
            return Outcome::Fail;
        }
        if self.min.is_some_and(|min| value < min) || self.max.is_some_and(|max| value > max) {
            return Outcome::Fail;
        }
        if self.marginal_min.is_some_and(|m| value <= m)
            || self.marginal_max.is_some_and(|m| value >= m)
        {
            return Outcome::Marginal;
        }
        Outcome::Pass
    }

    /// Renders the limits with a unit, e.g. `10 <= x <= 50 ms`, `x >= 3 Hz`,
    /// `x == 0`, with the marginal band after it in parentheses, or `none`.
    pub fn render(&self, unit: &str) -> String {
        WithUnit { limits: self, unit }.to_string()
    }
}

/// Display of [`Limits`] without a unit; see [`Limits::render`].
impl fmt::Display for Limits {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        WithUnit {
            limits: self,
            unit: "",
        }
        .fmt(f)
    }
}

/// Limits paired with the unit they are rendered in.
struct WithUnit<'a> {
    limits: &'a Limits,
    unit: &'a str,
}

impl fmt::Display for WithUnit<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let l = self.limits;
        let unit = |f: &mut fmt::Formatter<'_>| {
            if self.unit.is_empty() {
                Ok(())
            } else {
                write!(f, " {}", self.unit)
            }
        };
        match (l.min, l.max) {
            (Some(min), Some(max)) if min == max => write!(f, "x == {min}")?,
            (Some(min), Some(max)) => write!(f, "{min} <= x <= {max}")?,
            (Some(min), None) => write!(f, "x >= {min}")?,
            (None, Some(max)) => write!(f, "x <= {max}")?,
            (None, None) if l.marginal_min.is_none() && l.marginal_max.is_none() => {
                return f.write_str("none");
            }
            (None, None) => f.write_str("any x")?,
        }
        unit(f)?;
        match (l.marginal_min, l.marginal_max) {
            (Some(lo), Some(hi)) => {
                write!(f, " (marginal: x <= {lo} or x >= {hi}")?;
                unit(f)?;
                f.write_str(")")
            }
            (Some(lo), None) => {
                write!(f, " (marginal: x <= {lo}")?;
                unit(f)?;
                f.write_str(")")
            }
            (None, Some(hi)) => {
                write!(f, " (marginal: x >= {hi}")?;
                unit(f)?;
                f.write_str(")")
            }
            (None, None) => Ok(()),
        }
    }
}

/// Verdict on one measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    /// Within limits and outside the marginal band.
    Pass,
    /// Within limits but inside the marginal band; counts as passing.
    Marginal,
    /// Outside limits, or not a number.
    Fail,
    /// No value was recorded: the phase did not show the SLA is met, so its
    /// phase fails.
    Unset,
    /// Deliberately not measured, with the reason in [`Measurement::note`];
    /// does not fail the phase.
    Skipped,
}

impl Outcome {
    /// Whether this outcome lets its phase pass (pass, marginal, skipped).
    pub fn is_passing(self) -> bool {
        matches!(self, Outcome::Pass | Outcome::Marginal | Outcome::Skipped)
    }

    /// Lower-case name, as serialized.
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Pass => "pass",
            Outcome::Marginal => "marginal",
            Outcome::Fail => "fail",
            Outcome::Unset => "unset",
            Outcome::Skipped => "skipped",
        }
    }
}

impl fmt::Display for Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}
