//! Models of how PX4, as the flight controller, reads what MultiRX sends it.
//! Written from PX4's documented behaviour, independently of `multirx-core`,
//! so the rig checks the device's output with a second implementation.

pub mod rc_input;

pub use rc_input::{FcFrame, Px4RcInput, RcReport, SbusStream};
