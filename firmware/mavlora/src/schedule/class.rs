//! Which frames must get through (priority) and which are replaceable samples (periodic).

use crate::wire::ids;

/// Scheduling class of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Class {
    /// Commands, acks, mission and parameter traffic: sent first, in order, never replaced.
    /// Losing or delaying one stalls a protocol (the paper's mission-upload problem).
    Priority,
    /// Periodic telemetry: only the newest sample matters, so a newer one replaces an older
    /// queued one.
    Periodic,
}

/// Message ids that are part of a request/response protocol.
const PRIORITY: &[u32] = &[
    ids::SET_MODE,
    ids::PARAM_REQUEST_READ,
    ids::PARAM_REQUEST_LIST,
    ids::PARAM_VALUE,
    ids::PARAM_SET,
    ids::MISSION_REQUEST_PARTIAL_LIST,
    ids::MISSION_WRITE_PARTIAL_LIST,
    ids::MISSION_ITEM,
    ids::MISSION_REQUEST,
    ids::MISSION_SET_CURRENT,
    ids::MISSION_REQUEST_LIST,
    ids::MISSION_COUNT,
    ids::MISSION_CLEAR_ALL,
    ids::MISSION_ITEM_REACHED,
    ids::MISSION_ACK,
    ids::MISSION_REQUEST_INT,
    ids::MISSION_ITEM_INT,
    ids::COMMAND_INT,
    ids::COMMAND_LONG,
    ids::COMMAND_ACK,
    ids::COMMAND_CANCEL,
    ids::FILE_TRANSFER_PROTOCOL,
    ids::STATUSTEXT,
    ids::SETUP_SIGNING,
];

impl Class {
    /// Default class of a message id: [`Class::Priority`] for command, mission, parameter and
    /// status-text messages, [`Class::Periodic`] for everything else.
    pub fn of(message_id: u32) -> Self {
        if PRIORITY.contains(&message_id) {
            Self::Priority
        } else {
            Self::Periodic
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn telemetry_is_periodic_and_commands_are_priority() {
        assert_eq!(Class::of(ids::GLOBAL_POSITION_INT), Class::Periodic);
        assert_eq!(Class::of(ids::HEARTBEAT), Class::Periodic);
        assert_eq!(Class::of(ids::COMMAND_LONG), Class::Priority);
        assert_eq!(Class::of(ids::MISSION_ITEM_INT), Class::Priority);
    }
}
