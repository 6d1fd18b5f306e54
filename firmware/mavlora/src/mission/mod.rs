//! Mission uploads over a slow radio (the paper's fix for PX4 issue #11078), faithful to any
//! ground station: the ground's transfer ends at the router, so its timeouts (0.5 s in many
//! SDKs) never meet the radio; the radio leg streams the plan and repairs losses
//! selectively; the bridge uploads to the flight controller with the standard protocol; the
//! ground hears ACCEPTED only when the autopilot accepted exactly the plan it sent.
//!
//! - [`MissionTerminator`] (router): ground leg and radio sender.
//! - [`MissionRelay`] (bridge): radio receiver and wire leg.
//! - [`plan`]: the transfer id (`opaque_id`) that ties an ack to one plan.
//! - [`RttEstimator`]: RFC 6298 round-trip estimate and retransmission timeout.
//!
//! `mission_type` (mission, fence, rally) is carried on every message of both legs: an upload
//! of one type never touches another (a MAVLink 1 autopilot, which cannot be told the type,
//! gets missions only: the rest is refused with `MAV_MISSION_UNSUPPORTED`). One upload at a
//! time: a new `MISSION_COUNT` from the same ground station replaces the transfer in
//! progress, one from another ground station is refused (`MAV_MISSION_DENIED`). Downloads
//! (`MISSION_REQUEST_LIST`), `MISSION_CLEAR_ALL` and partial writes pass through unchanged,
//! end to end, and the autopilot's answers to them reach the ground; its other acks never do.
//!
//! The invariant both ends keep: **the ground is told ACCEPTED only for the plan the vehicle
//! holds**, i.e. only for the bridge's ack naming the transfer, which it sends only for an
//! ACCEPTED the autopilot gave after asking for every item of exactly that plan.

pub mod pack;
pub mod plan;
mod relay;
mod rtt;
mod terminator;

pub use relay::{MissionConfig, MissionRelay, MissionStats};
pub use rtt::{MARGIN, RttEstimator, unmeasured_timeout};
pub use terminator::{MissionTerminator, TerminatorConfig, TerminatorStats};
