//! MavLora scenarios: full-length reproductions under a virtual clock (`simulated`) and
//! short runs of the real binaries over ptys (`realtime`).

pub mod realtime;
pub mod simulated;
