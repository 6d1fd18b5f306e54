//! The one virtual-clock world for MavLora: tests, benchmarks and the rig's simulated
//! scenarios all run [`World`].
//!
//! - [`World`]: a simulated flight controller ([`Autopilot`]; [`Px4Fc`], PX4-like, by
//!   default), the ground station ([`GcsMock`]), the real bridge and router engines or
//!   nothing ([`Relay`]), and the radio model (`harness_radio::Radio`) or an ideal wire
//!   ([`Carrier`]) between them. Directions are `harness_radio::Direction`: uplink is
//!   ground → air, downlink air → ground.
//! - [`autopilot`]: the [`Autopilot`] trait and the PX4-like flight controller (stream
//!   profiles [`PX4_NORMAL`], [`PX4_CONFIG`]; the paper's route, [`Route::PAPER`]; 250 ms
//!   item retries).
//! - [`GcsMock`]: mission upload, download and clear, a command loop with 1.5 s retries, a
//!   parameter download as QGroundControl does it ([`gcs_params`]).
//! - [`profiles`]: MavLora's shipped profiles, built in.
//! - [`scheduler_for`]: the engines' byte budget for a radio preset.
//! - [`freshness`]: compact telemetry's bytes against its freshness, per batching and radio.
//! - [`params`]: a whole parameter list downloaded through the engines (ArduCopter's 1,396
//!   and PX4's 904, as the real autopilots send them), its time and the position rate meanwhile.
//! - [`SplitMix64`]: seeded randomness for the simulated parts.
//!
//! Contract: no IO and no clock; the clock jumps to the earliest deadline of any part and
//! every random draw is seeded, so a run is the same for the same seed and settings.
//! Test support, kept out of MavLora's library so its public API is the engines only.

#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod autopilot;
mod budget;
pub mod freshness;
mod gcs;
pub mod gcs_params;
pub mod params;
pub mod profiles;
mod rng;
mod world;

pub use autopilot::{
    ARDUPILOT_PARAM_RATE, ArduPilotConfig, ArduPilotFc, Autopilot, Executed, Flight, Kinematics,
    MissionStore, MissionStoreStats, PX4_CONFIG, PX4_NORMAL, PX4_PARAM_RATE, ParamTable, Px4Fc,
    Px4Stats, Route, StreamSpec,
};
pub use budget::{direction_capacity, scheduler_for};
pub use gcs::{CommandPlan, CommandStats, GcsMock};
pub use harness_radio::Direction;
pub use rng::SplitMix64;
pub use world::{Carrier, Counts, Relay, World, WorldError, secs};

#[cfg(test)]
mod pacing_tests;
#[cfg(test)]
mod tests;
