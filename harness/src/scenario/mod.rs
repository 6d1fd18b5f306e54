//! Scenarios: what the rig does to the devices and what it measures. The same
//! scenarios run on every rig; only the rig file changes.

pub mod context;
pub mod mavlora;
pub mod multirx;

pub use context::PhaseContext;
