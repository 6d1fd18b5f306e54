//! Which frames must get through (priority) and which are replaceable samples (periodic).

use crate::wire::ids;

/// Scheduling class of a frame, in the order the radio budget serves them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Class {
    /// Commands, acks, mission and parameter requests: sent first, in order, never replaced.
    /// Losing or delaying one stalls a protocol (the paper's mission-upload problem).
    Priority,
    /// `PARAM_VALUE` (and the bridge's `MAVLORA_PARAM_VALUES`, several of them in a frame): a
    /// parameter stream is ~1000 values at once (a ground station loading parameters, an
    /// ArduPilot at boot). It gets its own bounded queue and a guaranteed
    /// share of the budget, so it is paced instead of pushing commands out of a full queue
    /// or starving position for minutes.
    Param,
    /// Periodic telemetry the profile names (a `radio` rate or `pass`): only the newest sample
    /// matters, so a newer one replaces an older queued one; served before anything unnamed.
    Periodic,
    /// Periodic telemetry the profile does not name: replaced like [`Class::Periodic`], but
    /// sent only with what the named messages leave of the budget, so an autopilot that
    /// ignores the stream configuration cannot starve position.
    Unlisted,
}

/// Message ids that are part of a request/response protocol.
const PRIORITY: &[u32] = &[
    ids::SET_MODE,
    ids::PARAM_REQUEST_READ,
    ids::PARAM_REQUEST_LIST,
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

/// Message ids whose frames are parts of a sequence or distinct records, not samples of one
/// state: RTCM corrections in fragments, a serial console's bytes, log entries and log data,
/// extended parameters, events, encapsulated images, tunnels, and compact telemetry (each
/// frame carries its own position samples, and may carry a status change). Each frame
/// counts, so none may replace another; a full queue still drops them (oldest first) as it
/// drops telemetry.
const SEQUENCE: &[u32] = &[
    ids::MAVLORA_COMPACT,
    ids::GPS_RTCM_DATA,
    ids::GPS_INJECT_DATA,
    ids::SERIAL_CONTROL,
    ids::LOG_ENTRY,
    ids::LOG_DATA,
    ids::LOGGING_DATA,
    ids::LOGGING_DATA_ACKED,
    ids::PARAM_EXT_VALUE,
    ids::EVENT,
    ids::RESPONSE_EVENT_ERROR,
    ids::ENCAPSULATED_DATA,
    ids::DATA_TRANSMISSION_HANDSHAKE,
    ids::TUNNEL,
    ids::V2_EXTENSION,
];

/// Whether a newer frame of `message_id` from the same sender may replace a queued one: only
/// samples of periodic state, never a part of a sequence.
pub fn replaceable(message_id: u32) -> bool {
    !SEQUENCE.contains(&message_id)
}

impl Class {
    /// Default class of a message id: [`Class::Priority`] for command, mission, parameter
    /// request and status-text messages, [`Class::Param`] for `PARAM_VALUE` and
    /// `MAVLORA_PARAM_VALUES`,
    /// [`Class::Periodic`] for everything else (the bridge demotes what its profile does not
    /// name to [`Class::Unlisted`]).
    pub fn of(message_id: u32) -> Self {
        if PRIORITY.contains(&message_id) {
            Self::Priority
        } else if matches!(message_id, ids::PARAM_VALUE | ids::MAVLORA_PARAM_VALUES) {
            Self::Param
        } else {
            Self::Periodic
        }
    }

    /// Whether frames of this class belong to a request/response protocol (never replaced by
    /// a newer sample): what the IO queues keep in their priority lane.
    pub fn is_protocol(self) -> bool {
        matches!(self, Self::Priority | Self::Param)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn state_samples_are_replaceable_and_sequence_parts_are_not() {
        assert!(replaceable(ids::GLOBAL_POSITION_INT) && replaceable(ids::ATTITUDE));
        for id in [
            ids::GPS_RTCM_DATA,
            ids::SERIAL_CONTROL,
            ids::LOG_DATA,
            ids::EVENT,
        ] {
            assert!(!replaceable(id), "{id}");
        }
    }

    #[test]
    fn telemetry_is_periodic_and_commands_are_priority() {
        assert_eq!(Class::of(ids::GLOBAL_POSITION_INT), Class::Periodic);
        assert_eq!(Class::of(ids::HEARTBEAT), Class::Periodic);
        assert_eq!(Class::of(ids::COMMAND_LONG), Class::Priority);
        assert_eq!(Class::of(ids::MISSION_ITEM_INT), Class::Priority);
        assert_eq!(Class::of(ids::PARAM_VALUE), Class::Param);
        assert_eq!(Class::of(ids::MAVLORA_PARAM_VALUES), Class::Param);
        assert!(Class::Param.is_protocol() && !Class::Unlisted.is_protocol());
    }
}
