//! The shared part of the rig file as written: serde shapes that mirror the TOML, with
//! unknown keys rejected and nothing resolved yet (each device's section has its own, in
//! its module). [`super::RigFile::from_str`]
//! checks these and turns them into the public types, so code using a
//! [`super::RigFile`] never sees a relative path or an unchecked value.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::Deserialize;

use crate::measurement::Limits;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawFile {
    pub rig: RawRig,
    #[serde(default)]
    pub fixtures: RawFixtures,
    #[serde(default)]
    pub radios: BTreeMap<String, harness_radio::RadioSetup>,
    #[serde(default)]
    pub autopilots: BTreeMap<String, super::autopilots::RawAutopilot>,
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
