//! Drivers of MultiRX's resources: the flight-controller line (SBUS out), the receiver
//! fixtures (SBUS in), the status line (events and the boot line), the emulated device's TX
//! probe, and the debug probe that flashes a board.

pub mod fc;
pub mod probe;
pub mod receiver;
pub mod sbus_receiver;
pub mod status;
pub mod tx_probe;
