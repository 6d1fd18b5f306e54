//! Declaring a phase's measurements before it runs, and recording them through handles.

use std::sync::atomic::{AtomicU64, Ordering};

use super::{Dimension, Dimensions, Limits, Measurement, Outcome, flat_name};

/// What a measurement is, declared once: base name, dimensions, unit,
/// description and built-in limits. Declaring it in a phase
/// ([`Declarations::declare`]) gives the [`Handle`] that records it.
///
/// ```
/// use harness::measurement::{Declarations, Dimension, Outcome, Spec};
/// let mut phase = Declarations::new();
/// let handover = phase.declare(
///     Spec::new("handover_ms", "ms")
///         .dim(Dimension::Device, "dut")
///         .dim(Dimension::Mode, "parallel")
///         .at_most(50.0),
/// );
/// assert_eq!(phase.get(handover).name, "dut.parallel.handover_ms");
/// assert_eq!(phase.get(handover).outcome, Outcome::Unset);
/// assert_eq!(phase.record(handover, 12.5).outcome, Outcome::Pass);
/// let m = phase.get(handover);
/// assert_eq!(m.limits.render(&m.unit), "x <= 50 ms");
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Spec {
    pub(super) base: String,
    pub(super) dimensions: Dimensions,
    pub(super) unit: String,
    pub(super) description: String,
    pub(super) limits: Limits,
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
        self.dimensions.insert(dim, value.into());
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
    pub(super) fn unset(self) -> Measurement {
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
