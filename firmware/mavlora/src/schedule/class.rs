//! Which frames must get through (priority) and which are replaceable samples (periodic).

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

/// Message ids that are part of a request/response protocol, by name for review.
const PRIORITY: &[(u32, &str)] = &[
    (11, "SET_MODE"),
    (20, "PARAM_REQUEST_READ"),
    (21, "PARAM_REQUEST_LIST"),
    (22, "PARAM_VALUE"),
    (23, "PARAM_SET"),
    (37, "MISSION_REQUEST_PARTIAL_LIST"),
    (38, "MISSION_WRITE_PARTIAL_LIST"),
    (39, "MISSION_ITEM"),
    (40, "MISSION_REQUEST"),
    (41, "MISSION_SET_CURRENT"),
    (43, "MISSION_REQUEST_LIST"),
    (44, "MISSION_COUNT"),
    (45, "MISSION_CLEAR_ALL"),
    (46, "MISSION_ITEM_REACHED"),
    (47, "MISSION_ACK"),
    (51, "MISSION_REQUEST_INT"),
    (73, "MISSION_ITEM_INT"),
    (75, "COMMAND_INT"),
    (76, "COMMAND_LONG"),
    (77, "COMMAND_ACK"),
    (80, "COMMAND_CANCEL"),
    (110, "FILE_TRANSFER_PROTOCOL"),
    (253, "STATUSTEXT"),
    (256, "SETUP_SIGNING"),
];

impl Class {
    /// Default class of a message id: [`Class::Priority`] for command, mission, parameter and
    /// status-text messages, [`Class::Periodic`] for everything else.
    pub fn of(message_id: u32) -> Self {
        if PRIORITY.iter().any(|&(id, _)| id == message_id) {
            Self::Priority
        } else {
            Self::Periodic
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::known;

    #[test]
    fn priority_table_names_match_the_dialect() {
        for &(id, name) in PRIORITY {
            assert_eq!(known::message_name(id), Some(name), "id {id}");
        }
    }

    #[test]
    fn telemetry_is_periodic_and_commands_are_priority() {
        assert_eq!(Class::of(33), Class::Periodic); // GLOBAL_POSITION_INT
        assert_eq!(Class::of(0), Class::Periodic); // HEARTBEAT
        assert_eq!(Class::of(76), Class::Priority); // COMMAND_LONG
        assert_eq!(Class::of(73), Class::Priority); // MISSION_ITEM_INT
    }
}
