//! The device registry: the one place in the rig that names every device it can test.
//! Everything else is either shared (rig file, drivers, runner, record, reports, evidence)
//! and names no device, or lives in one device's folder. Adding a device means adding its
//! folder and its lines here.

use std::sync::Arc;

use crate::mavlora::{self, Mavlora};
use crate::multirx::Multirx;
use crate::record::RunRecord;
use crate::rigfile::RigFile;
use crate::runner::Device;

/// The devices a rig file describes, in the order their phases run.
pub fn of_rig(rig: &Arc<RigFile>) -> Vec<Box<dyn Device>> {
    let mut devices: Vec<Box<dyn Device>> = Vec::new();
    if rig.multirx.is_some() {
        devices.push(Box::new(Multirx::new(rig.clone())));
    }
    if rig.mavlora.is_some() {
        devices.push(Box::new(Mavlora::new(rig.clone())));
    }
    devices
}

/// The devices' own sections of the text summary, rendered from a saved record alone.
pub fn summary_sections(record: &RunRecord) -> Vec<String> {
    mavlora::table_ii::render(record).into_iter().collect()
}
