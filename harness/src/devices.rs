//! The device registry: the one place in the rig that names every device it can test.
//! Everything else is either shared (rig file, drivers, runner, record, reports, evidence)
//! and names no device, or lives in one device's folder. Adding a device means adding its
//! folder and its lines here.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use harness_radio::RadioSetup;
use serde::Deserialize;

use crate::driver::autopilot::AutopilotSpec;
use crate::evidence::build::FirmwareCrate;
use crate::mavlora::rigfile::{MavloraSection, RawMavlora};
use crate::mavlora::{self, Mavlora};
use crate::multirx::Multirx;
use crate::multirx::rigfile::{MultirxSection, RawMultirx};
use crate::record::RunRecord;
use crate::rigfile::{Checker, RigFile, RigFileError};
use crate::runner::Device;

/// The rig file's top-level tables that describe a device.
pub const SECTIONS: [&str; 2] = ["multirx", "mavlora"];

/// The device programs the rig starts, with the package each is in (`rig build` builds them
/// beside the rig).
pub const PROGRAMS: [(&str, &str); 3] = [
    ("mavlora", "mavlora-bridge"),
    ("mavlora", "mavlora-router"),
    ("multirx-emulator", "multirx-emu"),
];

/// The firmware `rig build` builds reproducibly.
pub const FIRMWARE: FirmwareCrate = crate::multirx::firmware::CRATE;

/// The configs `rig build` compiles into [`FIRMWARE`] for this rig, labelled; none: its default.
pub fn firmware_configs(rig: &RigFile) -> Vec<(String, PathBuf)> {
    rig.devices
        .multirx
        .as_ref()
        .map(crate::multirx::firmware::build_configs)
        .unwrap_or_default()
}

/// The files a rig file's device sections name (device configs), kept with the evidence as
/// inputs: the name to keep each under, and where it is.
pub fn input_files(rig: &RigFile) -> Vec<(String, PathBuf)> {
    rig.devices
        .multirx
        .as_ref()
        .map(MultirxSection::input_files)
        .unwrap_or_default()
}

/// Each device's section of a rig file, checked; `None`: the rig does not test that device.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Sections {
    /// `[multirx]`.
    pub multirx: Option<MultirxSection>,
    /// `[mavlora]`.
    pub mavlora: Option<MavloraSection>,
}

/// The device sections as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSections {
    multirx: Option<RawMultirx>,
    mavlora: Option<RawMavlora>,
}

impl RawSections {
    /// Each device's module checks its own section.
    pub(crate) fn check(
        self,
        checker: &Checker,
        radios: &BTreeMap<String, RadioSetup>,
        autopilots: &BTreeMap<String, AutopilotSpec>,
    ) -> Result<Sections, RigFileError> {
        Ok(Sections {
            multirx: self.multirx.map(|m| checker.multirx(m)).transpose()?,
            mavlora: self
                .mavlora
                .map(|m| checker.mavlora(m, radios, autopilots))
                .transpose()?,
        })
    }
}

/// The devices a rig file describes, in the order their phases run.
pub fn of_rig(rig: &Arc<RigFile>) -> Vec<Box<dyn Device>> {
    let mut devices: Vec<Box<dyn Device>> = Vec::new();
    if rig.devices.multirx.is_some() {
        devices.push(Box::new(Multirx::new(rig.clone())));
    }
    if rig.devices.mavlora.is_some() {
        devices.push(Box::new(Mavlora::new(rig.clone())));
    }
    devices
}

/// The devices' own sections of the text summary, rendered from a saved record alone.
pub fn summary_sections(record: &RunRecord) -> Vec<String> {
    mavlora::table_ii::render(record).into_iter().collect()
}

/// The devices' figures in the certification page, drawn from a saved run (and the files it
/// attached, in `dir`) alone.
pub fn html_figures(h: &mut String, dir: &Path, run: &RunRecord) {
    crate::multirx::evidence::html_figures(h, dir, run);
    mavlora::evidence::html_figures(h, dir, run);
}
