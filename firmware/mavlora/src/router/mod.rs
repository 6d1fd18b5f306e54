//! The router engine (ground station): radio serial ↔ ground-station endpoints (UDP).
//!
//! [`Router`] is sans-IO like the bridge: bytes and `now` in from each side, frames and a
//! deadline out. Towards the ground station it expands compact telemetry into standard
//! messages (re-numbering the vehicle's stream so sequence-gap loss counters stay right);
//! towards the radio it thins the ground's heartbeats, drops a ground station's premature
//! mission retransmissions and budgets bytes with the same scheduler as the bridge. What it
//! takes from the ground passes [`trust`]'s gate first: allowed addresses and system ids, a
//! command budget per source.

mod engine;
pub mod trust;

pub use engine::{
    GCS_HEARTBEAT_LONGEST, GCS_HEARTBEAT_SHARE, Router, RouterConfig, RouterStats,
    gcs_heartbeat_period_for,
};
pub use trust::{GroundInput, GroundPolicy, GroundRejection, IpNet, TrustStats};

#[cfg(test)]
mod tests;
