//! The MavLora rig: everything the rig knows about MavLora and nothing else needs to.
//!
//! - [`simulated`]: full-length reproductions of the paper's flights on the virtual clock
//!   (the engines in-process, `harness-sim`'s world, the radio model);
//! - [`realtime`]: short runs of the real `mavlora-bridge` and `mavlora-router` over ptys,
//!   a radio emulator between them and pymavlink fixtures at both ends;
//! - [`sitl`]: the same real programs behind real autopilots (ArduPilot, PX4 SITL), each
//!   judged against the autopilot's own truth connection;
//! - [`session`]: brings one such chain up and down (FC fixture, bridge, radio, router,
//!   GCS fixture) and collects what it leaves;
//! - [`fixture`]: the typed event lines of the MavLora fixtures (`mavlora_fc.py`,
//!   `mavlora_gcs.py`, `mavlora_intruder.py`, `sitl_gcs.py`, `sitl_truth.py`);
//! - [`rigfile`]: the rig file's `[mavlora]` (and `[radios]`) sections;
//! - [`table_ii`]: the paper's Table II next to the run's figures, for the summary;
//! - `phases`: the phases a rig file's `[mavlora]` asks for.

pub mod bench;
pub mod evidence;
pub mod fixture;
mod phases;
pub mod realtime;
pub mod rigfile;
pub mod session;
pub mod simulated;
pub mod sitl;
pub mod table_ii;

pub use phases::{Mavlora, REALTIME};

use crate::driver::program::Program;

/// MavLora's bridge, on the drone's companion computer.
pub const MAVLORA_BRIDGE: Program = Program {
    name: "mavlora-bridge",
    build: "cargo build -p mavlora --bins",
};
/// MavLora's router, at the ground station.
pub const MAVLORA_ROUTER: Program = Program {
    name: "mavlora-router",
    build: "cargo build -p mavlora --bins",
};
