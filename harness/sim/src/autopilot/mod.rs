//! Simulated flight controllers. The [`World`](crate::World) drives any [`Autopilot`]; the
//! PX4-like one is [`Px4Fc`], the ArduPilot-like one (MAVLink 1, `REQUEST_DATA_STREAM` groups,
//! ardupilotmega messages, parameter streams) is [`ArduPilotFc`]. Scenarios that need one's
//! specifics use `World<ArduPilotFc>` as they use `World<Px4Fc>` (the default) for PX4's.

mod ardupilot;
mod kinematics;
mod mission;
mod params;
mod px4;

pub use ardupilot::{
    ARDUPILOT_PARAM_RATE, ARDUPILOT_STREAMS, ApStream, ArduPilotConfig, ArduPilotFc,
    ArduPilotStats, BOOT_NOTIFIED, Group,
};
pub use kinematics::{Flight, Kinematics, Route};
pub use mission::{MissionStore, MissionStoreStats};
pub use params::{ParamEntry, ParamServer, ParamTable, SetEcho, param_value_frame};
pub use px4::{Executed, PX4_CONFIG, PX4_NORMAL, PX4_PARAM_RATE, Px4Fc, Px4Stats, StreamSpec};

use mavlora::Instant;
use mavlora::dialect::{MISSION_ITEM_INT_DATA, MavMissionType};
use mavlora::wire::OwnedFrame;

/// What the world needs of a simulated flight controller: a sans-IO engine on one serial
/// port (time first, deadlines out, `poll_*` only dequeue), and the mission it stored, which
/// is what every upload is judged by.
pub trait Autopilot {
    /// Bytes read from its serial port at `now`.
    fn handle_bytes(&mut self, now: Instant, bytes: &[u8]);
    /// Does what is due at `now` (streams, retries).
    fn handle_timeout(&mut self, now: Instant);
    /// When [`handle_timeout`](Self::handle_timeout) is next needed.
    fn poll_timeout(&self) -> Option<Instant>;
    /// The next frame it writes to its serial port.
    fn poll_transmit(&mut self) -> Option<OwnedFrame>;
    /// The mission it holds.
    fn mission(&self) -> &[MISSION_ITEM_INT_DATA];
    /// The plan of `mission_type` it holds (fence and rally: none unless it keeps them).
    fn plan(&self, mission_type: MavMissionType) -> &[MISSION_ITEM_INT_DATA] {
        match mission_type {
            MavMissionType::MAV_MISSION_TYPE_MISSION => self.mission(),
            _ => &[],
        }
    }
}

impl Autopilot for Px4Fc {
    fn handle_bytes(&mut self, now: Instant, bytes: &[u8]) {
        Px4Fc::handle_bytes(self, now, bytes);
    }

    fn handle_timeout(&mut self, now: Instant) {
        Px4Fc::handle_timeout(self, now);
    }

    fn poll_timeout(&self) -> Option<Instant> {
        Px4Fc::poll_timeout(self)
    }

    fn poll_transmit(&mut self) -> Option<OwnedFrame> {
        Px4Fc::poll_transmit(self)
    }

    fn mission(&self) -> &[MISSION_ITEM_INT_DATA] {
        Px4Fc::mission(self)
    }

    fn plan(&self, mission_type: MavMissionType) -> &[MISSION_ITEM_INT_DATA] {
        Px4Fc::plan(self, mission_type)
    }
}
