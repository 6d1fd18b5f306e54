//! The `bench` suite: MavLora's radios on an RF path the rig controls — two radios (real, on
//! two serial ports, or the radio emulator playing both) and a programmable step attenuator
//! between their antenna ports, driven through its real driver in CI too.
//!
//! - [`rigfile`]: `[mavlora.bench]`, the path and the sweep;
//! - [`path`]: the path's resources, up and connected;
//! - [`probe`]: numbered HEARTBEATs into the drone's radio, counted at the ground's, and the
//!   radios' own `RADIO_STATUS`;
//! - [`sweep`]: the attenuation sweep phase (the paper's Fig. 1);
//! - [`session`]: the real bridge and router over the path at one attenuation;
//! - [`flow`]: the same with ECC turned on in the radios (half the throughput the programs
//!   are budgeted for): paced by the radios' `txbuf`.

pub mod flow;
pub mod path;
pub mod probe;
pub mod rigfile;
pub mod session;
pub mod sweep;

use std::sync::Arc;

use crate::mavlora::session::SessionDefaults;
use crate::runner::Phase;
use rigfile::BenchPlan;

/// The suite's phases for `plan`, the real-time ones side by side with the realtime suite.
pub fn phases(plan: &Arc<BenchPlan>, defaults: &Arc<SessionDefaults>) -> Vec<Phase> {
    let group = super::phases::REALTIME;
    vec![
        sweep::phase(plan.clone()).side_by_side(group),
        session::phase(plan.clone(), defaults.clone()).side_by_side(group),
        flow::phase(plan.clone(), defaults.clone()).side_by_side(group),
    ]
}
