//! Measurements: every SLA the rig checks is a named value with a unit and
//! limits, recorded with its outcome whether it passes or not (after OpenHTF
//! `core/measurements.py`).
//!
//! A [`Measurement`] is declared with its [`Limits`] before the phase runs,
//! then [`Measurement::record`]ed (or [`Measurement::skip`]ped). Its
//! [`Outcome`] is computed from the value and the limits at that moment and
//! saved with both, so a reviewer can check the verdict without rerunning.

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

/// A named value with a unit, limits and an outcome.
///
/// Declared before its phase runs so that an SLA that was never measured
/// shows up as [`Outcome::Unset`] instead of being silently absent.
///
/// ```
/// use harness::measurement::{Measurement, Outcome};
/// let mut m = Measurement::new("multirx.parallel.handover_ms", "ms").at_most(50.0);
/// assert_eq!(m.outcome, Outcome::Unset);
/// assert_eq!(m.record(12.5), Outcome::Pass);
/// assert_eq!(m.limits.render(&m.unit), "x <= 50 ms");
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measurement {
    /// Dotted name, e.g. `multirx.scan.handover_ms`; rig files override
    /// limits by this name.
    pub name: String,
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
    /// A measurement without limits and without a value yet.
    pub fn new(name: impl Into<String>, unit: impl Into<String>) -> Self {
        Measurement {
            name: name.into(),
            unit: unit.into(),
            description: String::new(),
            limits: Limits::NONE,
            value: None,
            outcome: Outcome::Unset,
            note: None,
        }
    }

    /// Sets the description.
    pub fn describe(mut self, text: impl Into<String>) -> Self {
        self.description = text.into();
        self
    }

    /// Requires `value <= max`.
    pub fn at_most(mut self, max: f64) -> Self {
        self.limits.max = Some(max);
        self
    }

    /// Requires `value >= min`.
    pub fn at_least(mut self, min: f64) -> Self {
        self.limits.min = Some(min);
        self
    }

    /// Requires `min <= value <= max`.
    pub fn between(self, min: f64, max: f64) -> Self {
        self.at_least(min).at_most(max)
    }

    /// Requires `value == v` (rendered `x == v`).
    pub fn equal_to(self, v: f64) -> Self {
        self.between(v, v)
    }

    /// Flags values at or above `x` (but within limits) as marginal.
    pub fn marginal_above(mut self, x: f64) -> Self {
        self.limits.marginal_max = Some(x);
        self
    }

    /// Flags values at or below `x` (but within limits) as marginal.
    pub fn marginal_below(mut self, x: f64) -> Self {
        self.limits.marginal_min = Some(x);
        self
    }

    /// Replaces the limits, e.g. with a rig file's override.
    pub fn with_limits(mut self, limits: Limits) -> Self {
        self.limits = limits;
        self
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
mod tests {
    use super::*;

    #[test]
    fn values_render_with_at_most_three_decimals() {
        assert_eq!(format_value(0.6998300004852354), "0.7");
        assert_eq!(format_value(63.4919), "63.492");
        assert_eq!(format_value(5.0), "5");
        assert_eq!(format_value(-0.0001), "0");
    }

    #[test]
    fn new_measurement_is_unset() {
        let m = Measurement::new("a", "ms").at_most(50.0);
        assert_eq!(m.outcome, Outcome::Unset);
        assert_eq!(m.value, None);
        assert!(!m.outcome.is_passing());
    }

    #[test]
    fn at_most_passes_at_the_limit_and_fails_above() {
        let mut m = Measurement::new("a", "ms").at_most(50.0);
        assert_eq!(m.record(50.0), Outcome::Pass);
        assert_eq!(m.record(50.001), Outcome::Fail);
        assert_eq!(m.value, Some(50.001), "failing value kept");
        assert_eq!(m.limits.max, Some(50.0), "limit kept");
    }

    #[test]
    fn at_least_fails_below() {
        let mut m = Measurement::new("rate", "Hz").at_least(3.0);
        assert_eq!(m.record(2.9), Outcome::Fail);
        assert_eq!(m.record(3.0), Outcome::Pass);
    }

    #[test]
    fn between_and_equal() {
        let mut m = Measurement::new("a", "").between(10.0, 20.0);
        assert_eq!(m.record(9.0), Outcome::Fail);
        assert_eq!(m.record(15.0), Outcome::Pass);
        assert_eq!(m.record(21.0), Outcome::Fail);
        let mut e = Measurement::new("lost", "").equal_to(0.0);
        assert_eq!(e.record(0.0), Outcome::Pass);
        assert_eq!(e.record(1.0), Outcome::Fail);
    }

    #[test]
    fn marginal_band_is_inclusive_and_passing() {
        let mut m = Measurement::new("h", "ms")
            .at_most(4500.0)
            .marginal_above(4000.0);
        assert_eq!(m.record(3999.0), Outcome::Pass);
        assert_eq!(m.record(4000.0), Outcome::Marginal);
        assert!(Outcome::Marginal.is_passing());
        assert_eq!(m.record(4500.0), Outcome::Marginal);
        assert_eq!(m.record(4500.5), Outcome::Fail);
        let mut lo = Measurement::new("rate", "Hz")
            .at_least(3.0)
            .marginal_below(3.5);
        assert_eq!(lo.record(3.2), Outcome::Marginal);
        assert_eq!(lo.record(4.0), Outcome::Pass);
    }

    #[test]
    fn nan_fails_even_without_limits() {
        let mut m = Measurement::new("a", "ms");
        assert_eq!(m.record(f64::NAN), Outcome::Fail);
        assert!(m.note.as_deref().unwrap().contains("NaN"));
        let mut n = Measurement::new("b", "ms");
        assert_eq!(n.record(1e9), Outcome::Pass, "no limits: any number");
    }

    #[test]
    fn infinity_is_judged_against_limits() {
        let mut m = Measurement::new("a", "ms").at_most(50.0);
        assert_eq!(m.record(f64::INFINITY), Outcome::Fail);
    }

    #[test]
    fn skip_keeps_reason() {
        let mut m = Measurement::new("a", "ms").at_most(50.0);
        m.record(10.0);
        m.skip("scan mode not in this rig");
        assert_eq!(m.outcome, Outcome::Skipped);
        assert_eq!(m.value, None);
        assert_eq!(m.note.as_deref(), Some("scan mode not in this rig"));
        assert!(m.outcome.is_passing());
    }

    #[test]
    fn limits_render() {
        let r = |m: Measurement| m.limits.render(&m.unit);
        assert_eq!(r(Measurement::new("a", "ms").at_most(50.0)), "x <= 50 ms");
        assert_eq!(
            r(Measurement::new("a", "ms").between(10.0, 50.0)),
            "10 <= x <= 50 ms"
        );
        assert_eq!(r(Measurement::new("a", "").equal_to(0.0)), "x == 0");
        assert_eq!(r(Measurement::new("a", "Hz").at_least(3.0)), "x >= 3 Hz");
        assert_eq!(r(Measurement::new("a", "B/s")), "none");
        assert_eq!(
            r(Measurement::new("a", "ms")
                .at_most(4500.0)
                .marginal_above(4000.0)),
            "x <= 4500 ms (marginal: x >= 4000 ms)"
        );
        assert_eq!(
            r(Measurement::new("a", "ms")
                .between(1.0, 9.0)
                .marginal_below(2.0)
                .marginal_above(8.5)),
            "1 <= x <= 9 ms (marginal: x <= 2 or x >= 8.5 ms)"
        );
        assert_eq!(
            Limits {
                max: Some(0.5),
                ..Limits::NONE
            }
            .to_string(),
            "x <= 0.5"
        );
    }

    #[test]
    fn render_value() {
        let mut m = Measurement::new("a", "ms");
        assert_eq!(m.render_value(), "unset");
        m.record(12.5);
        assert_eq!(m.render_value(), "12.5 ms");
        m.skip("why");
        assert_eq!(m.render_value(), "skipped");
    }

    #[test]
    fn validate_rejects_disordered_and_non_finite_limits() {
        let ok = Limits {
            min: Some(1.0),
            max: Some(9.0),
            marginal_min: Some(2.0),
            marginal_max: Some(8.0),
        };
        assert_eq!(ok.validate(), Ok(()));
        let bad = Limits {
            min: Some(50.0),
            max: Some(10.0),
            ..Limits::NONE
        };
        assert!(bad.validate().unwrap_err().contains("min <= max"));
        let band_outside = Limits {
            max: Some(4000.0),
            marginal_max: Some(4500.0),
            ..Limits::NONE
        };
        assert!(
            band_outside
                .validate()
                .unwrap_err()
                .contains("marginal_max < max")
        );
        let nan = Limits {
            max: Some(f64::NAN),
            ..Limits::NONE
        };
        assert!(nan.validate().is_err());
    }

    #[test]
    fn serde_outcome_lowercase_and_round_trip() {
        let mut m = Measurement::new("a", "ms").describe("d").at_most(50.0);
        m.record(60.0);
        let json = serde_json::to_string(&m).unwrap();
        assert!(json.contains(r#""outcome":"fail""#), "{json}");
        assert!(json.contains(r#""value":60.0"#), "{json}");
        let back: Measurement = serde_json::from_str(&json).unwrap();
        assert_eq!(back, m);
    }
}
