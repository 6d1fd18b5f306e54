//! Deterministic virtual-clock simulation of the whole C2 chain, for tests and benchmarks:
//! a PX4-like flight controller ([`Px4Fc`]), a ground station uploading missions
//! ([`GcsMock`]), a lossy radio ([`Link`]) and a driver ([`World`]) that jumps the clock to
//! the earliest deadline (after quinn-proto's test pair). No IO, no clock reads, seeded
//! randomness: a run is reproducible from its seed.

mod gcs;
mod link;
pub mod profiles;
mod px4;
mod rng;
mod world;

pub use gcs::{CommandPlan, CommandStats, GcsMock};
pub use link::{Link, LinkConfig, LinkStats};
pub use px4::{Flight, Kinematics, PX4_CONFIG, PX4_NORMAL, Px4Fc, Px4Stats, Route, StreamSpec};
pub use rng::SplitMix64;
pub use world::{Path, World};

#[cfg(test)]
mod tests;
