//! What a run's results.json keeps of the attenuator it stepped: enough to name the unit
//! and to judge its settings afterwards.

use serde::{Deserialize, Serialize};

use super::{Attenuator, DbRange};

/// An attenuator as a run used it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttenuatorRecord {
    /// The maker.
    pub vendor: String,
    /// Where the rig reached it.
    pub address: String,
    /// The model it reported.
    pub model: String,
    /// The serial number it reported.
    pub serial: String,
    /// Its firmware version, when it said.
    pub firmware: Option<String>,
    /// The settable range used, dB.
    pub range_db: DbRange,
    /// Its step, dB.
    pub step_db: f64,
    /// The wait after each setting, ms.
    pub settle_ms: f64,
}

impl AttenuatorRecord {
    /// The record of `att`.
    pub fn of<A: Attenuator + ?Sized>(att: &A) -> Self {
        let id = att.identity();
        AttenuatorRecord {
            vendor: id.vendor.clone(),
            address: id.address.clone(),
            model: id.model.clone(),
            serial: id.serial.clone(),
            firmware: id.firmware.clone(),
            range_db: att.range(),
            step_db: att.step_db(),
            settle_ms: att.settle().as_secs_f64() * 1e3,
        }
    }
}
