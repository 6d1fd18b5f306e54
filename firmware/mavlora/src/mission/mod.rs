//! The mission relay (the paper's fix for PX4 issue #11078): the ground uploads to the bridge
//! over the radio with timeouts that follow the radio's measured round-trip time, then the
//! bridge uploads to the flight controller over the wire with the standard protocol, whose
//! 250 ms item retries are harmless there.
//!
//! - [`RttEstimator`]: RFC 6298 round-trip estimate and retransmission timeout.
//! - [`MissionRelay`]: the bridge's two legs (radio: receiver; wire: sender).
//! - [`DuplicateSuppressor`]: the router's filter for a ground station's own retransmissions
//!   of mission frames it already forwarded within one radio round trip.
//!
//! Only `MISSION_ITEM_INT` uploads of the default mission type are relayed (our generated
//! dialect has no MAVLink 2 extension fields, so `mission_type` is not carried). Downloads,
//! `MISSION_CLEAR_ALL` and legacy `MISSION_ITEM` pass through unchanged.

mod dedup;
mod relay;
mod rtt;

pub use dedup::DuplicateSuppressor;
pub use relay::{MissionConfig, MissionRelay, MissionStats};
pub use rtt::{MARGIN, RttEstimator};
