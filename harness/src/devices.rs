//! The device registry: the one place in the rig that names every device it can test.
//! Everything else is either shared (rig file, drivers, runner, record, reports, evidence)
//! and names no device, or lives in one device's folder. Adding a device means adding its
//! folder and its lines here.

use std::collections::BTreeMap;
use std::sync::Arc;

use harness_radio::RadioSetup;
use serde::Deserialize;

use crate::mavlora::rigfile::{MavloraSection, RawMavlora};
use crate::mavlora::{self, Mavlora};
use crate::multirx::Multirx;
use crate::multirx::rigfile::{MultirxSection, RawMultirx};
use crate::record::RunRecord;
use crate::rigfile::{Checker, RigFile, RigFileError};
use crate::runner::Device;

/// The rig file's top-level tables that describe a device.
pub const SECTIONS: [&str; 2] = ["multirx", "mavlora"];

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
    ) -> Result<Sections, RigFileError> {
        Ok(Sections {
            multirx: self.multirx.map(|m| checker.multirx(m)).transpose()?,
            mavlora: self
                .mavlora
                .map(|m| checker.mavlora(m, radios))
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
