//! Commands over a lossy radio. A ground station retries a command after 1.5 s without an ack
//! (the MAVLink command protocol's default); at 10 % loss each way one command in five needs
//! that retry and one in a hundred needs two, so the 99th-percentile command-to-ack time sits
//! above 3 s, SORA's medium TMPR bound. The relay closes that gap on the radio leg itself:
//!
//! - [`CommandRetransmitter`] (router): resends a command over the radio after a timeout that
//!   follows the measured command round trip (RFC 6298's estimate, as the mission relay, but
//!   without its backoff: loss on a radio is not congestion), until the
//!   vehicle's `COMMAND_ACK` comes back; the ground station's own retries of a command still
//!   in flight are dropped (the router is already retrying).
//! - [`AckCache`] (bridge): a command the flight controller has already acknowledged, seen
//!   again because the ack was lost on the radio, is answered with the same ack instead of
//!   being executed twice; a copy that arrives while the first is still being executed is
//!   dropped.
//!
//! Commands are matched by (vehicle system id, command id): `COMMAND_ACK` in our generated
//! dialect carries no target fields (MAVLink 2 extensions), so that is all an ack names.

mod ack_cache;
mod retransmit;

pub use ack_cache::{AckCache, AckCacheStats, CacheVerdict};
pub use retransmit::{Admission, CommandRetransmitter, RetransmitStats};

use crate::dialect::MavMessage;

/// (target system, command id) of a `COMMAND_LONG` or `COMMAND_INT`.
pub fn command_key(msg: &MavMessage) -> Option<(u8, u32)> {
    match msg {
        MavMessage::COMMAND_LONG(c) => Some((c.target_system, c.command as u32)),
        MavMessage::COMMAND_INT(c) => Some((c.target_system, c.command as u32)),
        _ => None,
    }
}
