//! The rig file as written: serde shapes that mirror the TOML, with unknown
//! keys rejected and nothing resolved yet. [`super::RigFile::from_str`]
//! checks these and turns them into the public types, so code using a
//! [`super::RigFile`] never sees a relative path or an unchecked value.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::Deserialize;

use super::{DeviceKind, Mode, PortSpec};
use crate::measurement::Limits;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawFile {
    pub rig: RawRig,
    #[serde(default)]
    pub fixtures: RawFixtures,
    pub multirx: Option<RawMultirx>,
    #[serde(default)]
    pub radios: BTreeMap<String, harness_radio::RadioSetup>,
    pub mavlora: Option<crate::mavlora::rigfile::RawMavlora>,
    #[serde(default)]
    pub limits: BTreeMap<String, Limits>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRig {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub output: Option<PathBuf>,
    pub lock: Option<PathBuf>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawFixtures {
    pub python: Option<String>,
    pub dir: Option<PathBuf>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMultirx {
    pub modes: Option<Vec<Mode>>,
    pub device: RawDevice,
    pub ports: RawPorts,
    #[serde(default)]
    pub receivers: RawReceivers,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawDevice {
    pub kind: DeviceKind,
    pub program: Option<String>,
    #[serde(default)]
    pub configs: RawConfigs,
    pub probe: Option<String>,
    pub chip: Option<String>,
    pub flash: Option<bool>,
    pub firmware: Option<PathBuf>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawConfigs {
    pub parallel: Option<PathBuf>,
    pub scan: Option<PathBuf>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPorts {
    pub fc: PortSpec,
    pub status: PortSpec,
    pub ifs: Option<PortSpec>,
    pub receivers: Vec<PortSpec>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawReceivers {
    pub period_ms: Option<u32>,
    pub boot_ms: Option<u32>,
}
