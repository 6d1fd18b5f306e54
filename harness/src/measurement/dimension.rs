//! What a measurement is of (device, mode, radio...), the flat name made from it, and
//! selection by dimension.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

use super::{Measurement, Spec};

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
    /// Device under test: its folder's name in the rig.
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
/// [`Dimension::Transport`] of the virtual-clock reproductions of the paper, the default
/// transport: out of the flat name (see [`flat_name`]).
pub const SIMULATED: &str = "simulated";
/// [`Dimension::Autopilot`] of the PX4-like flight controller, the paper's autopilot and the
/// default: out of the flat name (see [`flat_name`]).
pub const PX4: &str = "px4";
/// [`Dimension::Variant`] of MavLora as designed (bridge and router relaying);
/// out of the flat name, which names only the naive comparison.
pub const RELAY: &str = "relay";

/// A measurement's dimensions, each at most once, in [`Dimension`] order.
/// Serialized as a JSON object (`{"device": "dut", "mode": "fast"}`).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Dimensions(BTreeMap<Dimension, String>);

impl Dimensions {
    /// Sets `dim` (a spec's builder adds its dimensions one by one).
    pub(super) fn insert(&mut self, dim: Dimension, value: String) {
        self.0.insert(dim, value);
    }

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
/// (`dut.fast.handover.max_gap_ms`).
///
/// The one place names are made. Defaults stay out, so the names that saved records, trace
/// matrices and `harness/requirements.toml` use are short and do not change when a
/// dimension gains a value: the device when an artifact stands in its place
/// (`firmware.scan.flash_bytes`), `transport` = [`SIMULATED`], `autopilot` = [`PX4`] and
/// `variant` = [`RELAY`].
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
    absent: Vec<Dimension>,
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

    /// Only those without dimension `dim`.
    pub fn lacks(mut self, dim: Dimension) -> Self {
        self.absent.push(dim);
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
            && self.absent.iter().all(|d| m.dimensions.get(*d).is_none())
    }
}
