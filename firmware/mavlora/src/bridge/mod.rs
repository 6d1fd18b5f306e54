//! The bridge engine (companion computer): flight-controller serial ↔ radio serial.
//!
//! [`Bridge`] is sans-IO: the driver feeds it bytes from each side with `now`
//! ([`Bridge::handle_fc_bytes`], [`Bridge::handle_radio_bytes`]), takes frames for each side
//! ([`Bridge::poll_fc_transmit`], [`Bridge::poll_radio_transmit`]) and wakes it at
//! [`Bridge::poll_timeout`] with [`Bridge::handle_timeout`].

mod config;
mod engine;
mod fc_watch;
mod gcs_heartbeat;
mod param_answers;

pub use config::BridgeConfig;
pub use engine::{
    Bridge, BridgeStats, PACED_ANSWERS_KEPT, READ_ANSWER_SHARE_DIVISOR, UNLISTED_IDS_KEPT,
};
pub use fc_watch::{FcEvent, FcWatch};
pub use gcs_heartbeat::GcsHeartbeat;

#[cfg(test)]
mod tests;
