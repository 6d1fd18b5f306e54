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
//! rerunning. The flat name readers know (`multirx.parallel.handover_ms`) is
//! made from the dimensions in one place, [`flat_name`]; reports select by
//! dimension ([`Selector`]), never by picking names apart.

use std::collections::BTreeMap;
use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering};

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

/// A key of a measurement's dimensions (after OpenHTF's `with_dimensions`):
/// what a measurement is *of*, beside its base name. Reports, the whole-run
/// aggregates and trace matrices select by these, never by picking names
/// apart. The order of the variants is the order of the flat name's segments
/// (see [`flat_name`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Dimension {
    /// A built thing measured rather than the running device: `firmware`
    /// (the flashed image). Named in the device's place.
    Artifact,
    /// Device under test: `multirx`, `mavlora`.
    Device,
    /// MultiRX mode: `parallel`, `scan`.
    Mode,
    /// How the link is run: [`PTY`] (the real programs on pty pairs, wall
    /// clock) or [`SIMULATED`] (in-process engines, virtual clock).
    Transport,
    /// A radio, by preset (`lora_sf7`) or by the rig file's name for it
    /// (`lora_sf7_bursty`), `-` written `_`.
    Radio,
    /// The flight controller behind the bridge: [`PX4`] (the default, out of the flat name)
    /// or `ardupilot` (the ArduPilot-like one: MAVLink 1, stream groups, ardupilotmega
    /// messages).
    Autopilot,
    /// How MavLora is set up: Table II's `wired`, `limit`, `limit_filter`,
    /// `compact`; a mission's [`RELAY`] or `naive`.
    Variant,
    /// The scenario, where several scenarios take the same measurement
    /// (`b_handover`, `ifs_override`) or it is named for its scenario
    /// (`blind_drone`); otherwise the phase says which scenario it is.
    Scenario,
    /// A ground station's mission timeout per step (`0_5s`, `1_5s`): SDKs wait 0.5 s, the
    /// MAVLink spec 1.5 s.
    GroundTimeout,
}

impl Dimension {
    /// Lower-case name, as serialized.
    pub fn as_str(self) -> &'static str {
        match self {
            Dimension::Artifact => "artifact",
            Dimension::Device => "device",
            Dimension::Mode => "mode",
            Dimension::Transport => "transport",
            Dimension::Radio => "radio",
            Dimension::Autopilot => "autopilot",
            Dimension::Variant => "variant",
            Dimension::Scenario => "scenario",
            Dimension::GroundTimeout => "ground_timeout",
        }
    }
}

impl fmt::Display for Dimension {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// [`Dimension::Transport`] of the real MavLora programs over pty pairs.
pub const PTY: &str = "pty";
/// [`Dimension::Transport`] of the virtual-clock reproductions. They were
/// named before the pty runs existed, so it stays out of the flat name.
pub const SIMULATED: &str = "simulated";
/// [`Dimension::Autopilot`] of the PX4-like flight controller, the one every measurement
/// was taken with before the dimension existed: out of the flat name.
pub const PX4: &str = "px4";
/// [`Dimension::Variant`] of MavLora as designed (bridge and router relaying);
/// out of the flat name, which names only the naive comparison.
pub const RELAY: &str = "relay";

/// A measurement's dimensions, each at most once, in [`Dimension`] order.
/// Serialized as a JSON object (`{"device": "multirx", "mode": "parallel"}`).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Dimensions(BTreeMap<Dimension, String>);

impl Dimensions {
    /// The value of `dim`, if the measurement has that dimension.
    pub fn get(&self, dim: Dimension) -> Option<&str> {
        self.0.get(&dim).map(String::as_str)
    }

    /// Dimensions and values in [`Dimension`] order.
    pub fn iter(&self) -> impl Iterator<Item = (Dimension, &str)> {
        self.0.iter().map(|(d, v)| (*d, v.as_str()))
    }

    /// Whether there are none (a record saved before dimensions existed).
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// The flat, dotted name of a measurement, as readers of `results.json`, the
/// reports and the rig file's `[limits]` keys know it: the dimensions'
/// values in [`Dimension`] order, then the base name
/// (`multirx.parallel.b_handover.max_output_gap_ms`).
///
/// The one place names are made. Three values stay out, so that names read as
/// they did before measurements had dimensions: the device when an artifact
/// stands in its place (`firmware.scan.flash_bytes`), `transport` =
/// [`SIMULATED`], `autopilot` = [`PX4`] and `variant` = [`RELAY`].
pub fn flat_name(dimensions: &Dimensions, base: &str) -> String {
    let mut name = String::new();
    for (dim, value) in dimensions.iter() {
        let unnamed = match dim {
            Dimension::Device => dimensions.get(Dimension::Artifact).is_some(),
            Dimension::Transport => value == SIMULATED,
            Dimension::Variant => value == RELAY,
            Dimension::Autopilot => value == PX4,
            _ => false,
        };
        if !unnamed {
            name.push_str(value);
            name.push('.');
        }
    }
    name.push_str(base);
    name
}

/// What a measurement is, declared once: base name, dimensions, unit,
/// description and built-in limits. Declaring it in a phase
/// ([`Declarations::declare`]) gives the [`Handle`] that records it.
///
/// ```
/// use harness::measurement::{Declarations, Dimension, Outcome, Spec};
/// let mut phase = Declarations::new();
/// let handover = phase.declare(
///     Spec::new("handover_ms", "ms")
///         .dim(Dimension::Device, "multirx")
///         .dim(Dimension::Mode, "parallel")
///         .at_most(50.0),
/// );
/// assert_eq!(phase.get(handover).name, "multirx.parallel.handover_ms");
/// assert_eq!(phase.get(handover).outcome, Outcome::Unset);
/// assert_eq!(phase.record(handover, 12.5).outcome, Outcome::Pass);
/// let m = phase.get(handover);
/// assert_eq!(m.limits.render(&m.unit), "x <= 50 ms");
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Spec {
    base: String,
    dimensions: Dimensions,
    unit: String,
    description: String,
    limits: Limits,
}

impl Spec {
    /// A measurement named `base` (one segment: `handover_ms`), in `unit`
    /// (`ms`, `B/s`, `Hz`, or empty), without dimensions or limits yet.
    ///
    /// # Panics
    /// If `base` is empty or has a dot: what would follow the dot is a
    /// dimension.
    pub fn new(base: impl Into<String>, unit: impl Into<String>) -> Self {
        let base = base.into();
        assert!(
            !base.is_empty() && !base.contains('.'),
            "base name {base:?}: one segment, dimensions carry the rest"
        );
        Spec {
            base,
            dimensions: Dimensions::default(),
            unit: unit.into(),
            description: String::new(),
            limits: Limits::NONE,
        }
    }

    /// Sets dimension `dim` to `value`, replacing an earlier value.
    pub fn dim(mut self, dim: Dimension, value: impl Into<String>) -> Self {
        self.dimensions.0.insert(dim, value.into());
        self
    }

    /// Sets the description: what is measured and why it matters.
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

    /// The base name.
    pub fn base(&self) -> &str {
        &self.base
    }

    /// The dimensions.
    pub fn dimensions(&self) -> &Dimensions {
        &self.dimensions
    }

    /// The flat name ([`flat_name`]).
    pub fn name(&self) -> String {
        flat_name(&self.dimensions, &self.base)
    }

    /// The record entry: no value yet, [`Outcome::Unset`].
    fn unset(self) -> Measurement {
        Measurement {
            name: self.name(),
            dimensions: self.dimensions,
            unit: self.unit,
            description: self.description,
            limits: self.limits,
            value: None,
            outcome: Outcome::Unset,
            note: None,
        }
    }
}

/// Records one measurement a phase declared; only [`Declarations::declare`]
/// makes one, so nothing undeclared can be recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Handle {
    /// Which [`Declarations`] made it.
    owner: u64,
    index: usize,
}

/// The measurements one phase declares, in order, declared before it runs so
/// that an SLA never measured shows as [`Outcome::Unset`] instead of being
/// silently absent.
#[derive(Debug)]
pub struct Declarations {
    /// Tells this phase's handles from another's.
    id: u64,
    measurements: Vec<Measurement>,
}

impl Default for Declarations {
    fn default() -> Self {
        Self::new()
    }
}

impl Declarations {
    /// None yet.
    pub fn new() -> Self {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        Declarations {
            id: NEXT.fetch_add(1, Ordering::Relaxed),
            measurements: Vec::new(),
        }
    }

    /// Declares a measurement of this phase and returns the handle that
    /// records it.
    ///
    /// # Panics
    /// If a measurement with the same flat name is already declared: a
    /// scenario bug, and two values under one name would be ambiguous.
    pub fn declare(&mut self, spec: Spec) -> Handle {
        let m = spec.unset();
        assert!(
            self.measurements.iter().all(|d| d.name != m.name),
            "measurement {} declared twice",
            m.name
        );
        self.measurements.push(m);
        Handle {
            owner: self.id,
            index: self.measurements.len() - 1,
        }
    }

    /// The declared measurement `h` records.
    ///
    /// # Panics
    /// If `h` was declared in another phase.
    pub fn get(&self, h: Handle) -> &Measurement {
        &self.measurements[self.index(h)]
    }

    /// Records `value` for `h` and judges it (see [`Measurement::record`]).
    pub fn record(&mut self, h: Handle, value: f64) -> &Measurement {
        let i = self.index(h);
        self.measurements[i].record(value);
        &self.measurements[i]
    }

    /// Adds a remark to `h`'s measurement (e.g. how it was measured).
    pub fn annotate(&mut self, h: Handle, note: impl Into<String>) {
        let i = self.index(h);
        self.measurements[i].annotate(note);
    }

    /// Replaces built-in limits, e.g. with a rig file's `[limits]` by flat
    /// name: `limits(name, builtin)` gives the limits to judge by.
    pub fn override_limits(&mut self, limits: impl Fn(&str, Limits) -> Limits) {
        for m in &mut self.measurements {
            m.limits = limits(&m.name, m.limits);
        }
    }

    /// The declared measurements, recorded or not.
    pub fn measurements(&self) -> &[Measurement] {
        &self.measurements
    }

    /// The declared measurements, for the phase's record.
    pub fn into_measurements(self) -> Vec<Measurement> {
        self.measurements
    }

    fn index(&self, h: Handle) -> usize {
        assert_eq!(
            h.owner, self.id,
            "a measurement handle of another phase (a scenario bug)"
        );
        h.index
    }
}

/// Which measurements a report row, an aggregate or a requirement covers:
/// a base name and dimension values, matched against saved measurements.
/// Dimensions it does not mention may have any value, or be absent.
///
/// ```
/// use harness::measurement::{Declarations, Dimension, Selector, Spec};
/// let mut phase = Declarations::new();
/// phase.declare(Spec::new("bytes_per_s", "B/s").dim(Dimension::Variant, "compact"));
/// let compact = Selector::base("bytes_per_s").dim(Dimension::Variant, "compact");
/// assert!(compact.matches(&phase.measurements()[0]));
/// assert!(!compact.clone().has(Dimension::Radio).matches(&phase.measurements()[0]));
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Selector {
    base: Option<String>,
    equal: Vec<(Dimension, String)>,
    present: Vec<Dimension>,
}

impl Selector {
    /// Every measurement.
    pub fn any() -> Self {
        Selector::default()
    }

    /// Measurements with base name `base`, whatever their dimensions.
    pub fn base(base: impl Into<String>) -> Self {
        Selector {
            base: Some(base.into()),
            ..Selector::default()
        }
    }

    /// Measurements declared as `spec` or as it with more dimensions: its
    /// base name and every dimension it has, at its value.
    pub fn like(spec: &Spec) -> Self {
        spec.dimensions
            .iter()
            .fold(Selector::base(spec.base()), |s, (d, v)| s.dim(d, v))
    }

    /// Only those with dimension `dim` at `value`.
    pub fn dim(mut self, dim: Dimension, value: impl Into<String>) -> Self {
        self.equal.push((dim, value.into()));
        self
    }

    /// Only those that have dimension `dim`, at any value.
    pub fn has(mut self, dim: Dimension) -> Self {
        self.present.push(dim);
        self
    }

    /// Whether `m` is one of them.
    pub fn matches(&self, m: &Measurement) -> bool {
        self.base.as_deref().is_none_or(|b| m.base() == Some(b))
            && self
                .equal
                .iter()
                .all(|(d, v)| m.dimensions.get(*d) == Some(v.as_str()))
            && self.present.iter().all(|d| m.dimensions.get(*d).is_some())
    }
}

/// A declared measurement in a phase's record: flat name and dimensions,
/// unit, limits, and the value and outcome once recorded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measurement {
    /// Dotted name made from the dimensions and base name by [`flat_name`],
    /// e.g. `multirx.scan.handover_ms`; rig files override limits by this
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
        let m = Spec::new("a", "ms").at_most(50.0).unset();
        assert_eq!(m.outcome, Outcome::Unset);
        assert_eq!(m.value, None);
        assert!(!m.outcome.is_passing());
    }

    #[test]
    fn at_most_passes_at_the_limit_and_fails_above() {
        let mut m = Spec::new("a", "ms").at_most(50.0).unset();
        assert_eq!(m.record(50.0), Outcome::Pass);
        assert_eq!(m.record(50.001), Outcome::Fail);
        assert_eq!(m.value, Some(50.001), "failing value kept");
        assert_eq!(m.limits.max, Some(50.0), "limit kept");
    }

    #[test]
    fn at_least_fails_below() {
        let mut m = Spec::new("rate", "Hz").at_least(3.0).unset();
        assert_eq!(m.record(2.9), Outcome::Fail);
        assert_eq!(m.record(3.0), Outcome::Pass);
    }

    #[test]
    fn between_and_equal() {
        let mut m = Spec::new("a", "").between(10.0, 20.0).unset();
        assert_eq!(m.record(9.0), Outcome::Fail);
        assert_eq!(m.record(15.0), Outcome::Pass);
        assert_eq!(m.record(21.0), Outcome::Fail);
        let mut e = Spec::new("lost", "").equal_to(0.0).unset();
        assert_eq!(e.record(0.0), Outcome::Pass);
        assert_eq!(e.record(1.0), Outcome::Fail);
    }

    #[test]
    fn marginal_band_is_inclusive_and_passing() {
        let mut m = Spec::new("h", "ms")
            .at_most(4500.0)
            .marginal_above(4000.0)
            .unset();
        assert_eq!(m.record(3999.0), Outcome::Pass);
        assert_eq!(m.record(4000.0), Outcome::Marginal);
        assert!(Outcome::Marginal.is_passing());
        assert_eq!(m.record(4500.0), Outcome::Marginal);
        assert_eq!(m.record(4500.5), Outcome::Fail);
        let mut lo = Spec::new("rate", "Hz")
            .at_least(3.0)
            .marginal_below(3.5)
            .unset();
        assert_eq!(lo.record(3.2), Outcome::Marginal);
        assert_eq!(lo.record(4.0), Outcome::Pass);
    }

    #[test]
    fn nan_fails_even_without_limits() {
        let mut m = Spec::new("a", "ms").unset();
        assert_eq!(m.record(f64::NAN), Outcome::Fail);
        assert!(m.note.as_deref().unwrap().contains("NaN"));
        let mut n = Spec::new("b", "ms").unset();
        assert_eq!(n.record(1e9), Outcome::Pass, "no limits: any number");
    }

    #[test]
    fn infinity_is_judged_against_limits() {
        let mut m = Spec::new("a", "ms").at_most(50.0).unset();
        assert_eq!(m.record(f64::INFINITY), Outcome::Fail);
    }

    #[test]
    fn skip_keeps_reason() {
        let mut m = Spec::new("a", "ms").at_most(50.0).unset();
        m.record(10.0);
        m.skip("scan mode not in this rig");
        assert_eq!(m.outcome, Outcome::Skipped);
        assert_eq!(m.value, None);
        assert_eq!(m.note.as_deref(), Some("scan mode not in this rig"));
        assert!(m.outcome.is_passing());
    }

    #[test]
    fn limits_render() {
        let r = |s: Spec| s.limits.render(&s.unit);
        assert_eq!(r(Spec::new("a", "ms").at_most(50.0)), "x <= 50 ms");
        assert_eq!(
            r(Spec::new("a", "ms").between(10.0, 50.0)),
            "10 <= x <= 50 ms"
        );
        assert_eq!(r(Spec::new("a", "").equal_to(0.0)), "x == 0");
        assert_eq!(r(Spec::new("a", "Hz").at_least(3.0)), "x >= 3 Hz");
        assert_eq!(r(Spec::new("a", "B/s")), "none");
        assert_eq!(
            r(Spec::new("a", "ms").at_most(4500.0).marginal_above(4000.0)),
            "x <= 4500 ms (marginal: x >= 4000 ms)"
        );
        assert_eq!(
            r(Spec::new("a", "ms")
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
        let mut m = Spec::new("a", "ms").unset();
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
        let mut m = Spec::new("a", "ms").describe("d").at_most(50.0).unset();
        m.record(60.0);
        let json = serde_json::to_string(&m).unwrap();
        assert!(json.contains(r#""outcome":"fail""#), "{json}");
        assert!(json.contains(r#""value":60.0"#), "{json}");
        let back: Measurement = serde_json::from_str(&json).unwrap();
        assert_eq!(back, m);
    }

    fn multirx(mode: &str) -> Spec {
        Spec::new("max_output_gap_ms", "ms")
            .dim(Dimension::Device, "multirx")
            .dim(Dimension::Mode, mode)
    }

    #[test]
    fn declared_handle_records_and_annotates_its_measurement() {
        let mut phase = Declarations::new();
        let gap = phase.declare(multirx("parallel").at_most(10.5));
        let losses = phase.declare(Spec::new("rc_losses", "").equal_to(0.0));
        assert_eq!(phase.get(gap).outcome, Outcome::Unset);
        assert_eq!(phase.record(gap, 11.0).outcome, Outcome::Fail);
        phase.annotate(gap, "measured at the adapter");
        assert_eq!(phase.record(losses, 0.0).outcome, Outcome::Pass);
        let ms = phase.into_measurements();
        assert_eq!(ms.len(), 2);
        assert_eq!(ms[0].name, "multirx.parallel.max_output_gap_ms");
        assert_eq!(ms[0].value, Some(11.0));
        assert_eq!(ms[0].note.as_deref(), Some("measured at the adapter"));
        assert_eq!(ms[1].name, "rc_losses");
    }

    #[test]
    #[should_panic(expected = "another phase")]
    fn a_handle_records_only_in_the_phase_that_declared_it() {
        let mut a = Declarations::new();
        let mut b = Declarations::new();
        let h = a.declare(multirx("parallel"));
        b.declare(multirx("parallel"));
        b.record(h, 1.0);
    }

    #[test]
    #[should_panic(expected = "declared twice")]
    fn one_name_is_declared_once_per_phase() {
        let mut phase = Declarations::new();
        phase.declare(multirx("scan"));
        phase.declare(multirx("scan").at_most(1.0));
    }

    #[test]
    #[should_panic(expected = "one segment")]
    fn a_base_name_has_no_dots() {
        Spec::new("naive.mission_upload_s", "s");
    }

    #[test]
    fn flat_names_are_made_from_the_dimensions() {
        let name = |spec: Spec| spec.name();
        assert_eq!(
            name(multirx("scan").dim(Dimension::Scenario, "b_handover")),
            "multirx.scan.b_handover.max_output_gap_ms"
        );
        // the order is the dimensions', not the order they were given in
        assert_eq!(
            name(
                Spec::new("handover_ms", "ms")
                    .dim(Dimension::Mode, "parallel")
                    .dim(Dimension::Device, "multirx")
            ),
            "multirx.parallel.handover_ms"
        );
        assert_eq!(
            name(
                Spec::new("flash_bytes", "B")
                    .dim(Dimension::Device, "multirx")
                    .dim(Dimension::Mode, "scan")
                    .dim(Dimension::Artifact, "firmware")
            ),
            "firmware.scan.flash_bytes"
        );
        let mavlora = |base: &str| Spec::new(base, "").dim(Dimension::Device, "mavlora");
        assert_eq!(
            name(
                mavlora("bytes_per_s")
                    .dim(Dimension::Transport, "pty")
                    .dim(Dimension::Variant, "compact")
            ),
            "mavlora.pty.compact.bytes_per_s"
        );
        assert_eq!(
            name(
                mavlora("bytes_per_s")
                    .dim(Dimension::Transport, SIMULATED)
                    .dim(Dimension::Variant, "limit_filter")
            ),
            "mavlora.limit_filter.bytes_per_s"
        );
        let mission = |variant: &str| {
            name(
                mavlora("mission_upload_s")
                    .dim(Dimension::Transport, SIMULATED)
                    .dim(Dimension::Radio, "lora_sf7")
                    .dim(Dimension::Variant, variant),
            )
        };
        assert_eq!(mission(RELAY), "mavlora.lora_sf7.mission_upload_s");
        assert_eq!(mission("naive"), "mavlora.lora_sf7.naive.mission_upload_s");
        assert_eq!(
            name(mavlora("detect_s").dim(Dimension::Scenario, "blind_drone")),
            "mavlora.blind_drone.detect_s"
        );
    }

    #[test]
    fn base_name_is_the_flat_name_without_the_dimensions() {
        let mut phase = Declarations::new();
        let h = phase.declare(
            Spec::new("mission_upload_s", "s")
                .dim(Dimension::Device, "mavlora")
                .dim(Dimension::Transport, SIMULATED)
                .dim(Dimension::Radio, "sik_64k")
                .dim(Dimension::Variant, "naive"),
        );
        assert_eq!(phase.get(h).base(), Some("mission_upload_s"));
        let old = Measurement {
            dimensions: Dimensions::default(),
            ..phase.get(h).clone()
        };
        assert_eq!(old.base(), None, "no dimensions, no base name");
    }

    #[test]
    fn selector_matches_base_and_dimensions() {
        let mut phase = Declarations::new();
        let session = |mode: &str, scenario: &str| {
            multirx(mode).dim(Dimension::Scenario, scenario.to_owned())
        };
        phase.declare(session("parallel", "a_idle_takeover"));
        phase.declare(session("parallel", "b_handover"));
        phase.declare(session("scan", "b_handover"));
        phase.declare(multirx("parallel"));
        phase.declare(Spec::new("rc_losses", "").dim(Dimension::Device, "multirx"));
        let names = |s: &Selector| -> Vec<String> {
            phase
                .measurements()
                .iter()
                .filter(|m| s.matches(m))
                .map(|m| m.name.clone())
                .collect()
        };
        assert_eq!(names(&Selector::any()).len(), 5);
        assert_eq!(names(&Selector::base("max_output_gap_ms")).len(), 4);
        assert_eq!(
            names(&Selector::like(&multirx("parallel")).has(Dimension::Scenario)),
            [
                "multirx.parallel.a_idle_takeover.max_output_gap_ms",
                "multirx.parallel.b_handover.max_output_gap_ms"
            ]
        );
        assert_eq!(
            names(&Selector::any().dim(Dimension::Scenario, "b_handover")),
            [
                "multirx.parallel.b_handover.max_output_gap_ms",
                "multirx.scan.b_handover.max_output_gap_ms"
            ]
        );
        assert_eq!(
            names(&Selector::base("rc_losses").dim(Dimension::Device, "multirx")),
            ["multirx.rc_losses"]
        );
        assert!(names(&Selector::base("rc_losses").dim(Dimension::Mode, "scan")).is_empty());
    }

    #[test]
    fn dimensions_are_saved_as_an_object_and_read_back() {
        let mut m = multirx("scan").dim(Dimension::Scenario, "c_loiter").unset();
        m.record(7.0);
        let json = serde_json::to_string(&m).unwrap();
        assert!(
            json.contains(
                r#""dimensions":{"device":"multirx","mode":"scan","scenario":"c_loiter"}"#
            ),
            "{json}"
        );
        let back: Measurement = serde_json::from_str(&json).unwrap();
        assert_eq!(back, m);
        assert_eq!(back.base(), Some("max_output_gap_ms"));
    }

    #[test]
    fn a_measurement_saved_without_dimensions_loads() {
        let old = r#"{"name": "multirx.scan.handover_ms", "unit": "ms", "description": "",
            "limits": {"max": 4500.0}, "value": 12.0, "outcome": "pass"}"#;
        let m: Measurement = serde_json::from_str(old).unwrap();
        assert!(m.dimensions.is_empty());
        assert_eq!(m.name, "multirx.scan.handover_ms");
        assert!(!Selector::base("handover_ms").matches(&m));
        assert!(Selector::any().matches(&m));
    }
}
