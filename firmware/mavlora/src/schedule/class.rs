//! Scheduling classes: what goes first (commands and acks), what shares the rest of the
//! budget (transfers, status text, parameters, telemetry), and which frames are replaceable
//! samples.

use crate::wire::ids;

/// Scheduling class of a frame (see [`LinkScheduler`](super::LinkScheduler) for the shares).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Class {
    /// Commands and their acks (and a parameter set's echo, its ack): sent before anything
    /// else, in order. What a pilot does must not wait behind what a ground station reads.
    Command,
    /// Request/response transfers: mission, parameter requests and sets, file transfer
    /// (FTP). A guaranteed share of the budget, fair between origins, so a ground station
    /// downloading files or reading parameters in a loop cannot starve telemetry or the
    /// pilot's own transfers.
    Protocol,
    /// `STATUSTEXT`: a share of its own, fair between origins, and a short queue that drops
    /// the least severe text first, so an autopilot chattering at 20 texts a second delays
    /// neither commands nor position.
    Status,
    /// `PARAM_VALUE` (and the bridge's `MAVLORA_PARAM_VALUES`, several of them in a frame): a
    /// parameter stream is ~1000 values at once (a ground station loading parameters, an
    /// ArduPilot at boot). It gets its own bounded queue and a share of the budget, so it is
    /// paced instead of pushing commands out of a full queue or starving position for minutes.
    Param,
    /// Periodic telemetry the profile names (a `radio` rate or `pass`): only the newest sample
    /// matters, so a newer one replaces an older queued one. The largest share: a position
    /// that arrives while the other classes are busy leaves after at most one frame of each.
    Periodic,
    /// Periodic telemetry the profile does not name: replaced like [`Class::Periodic`], but
    /// sent only with what every other class leaves of the budget, so an autopilot that
    /// ignores the stream configuration cannot starve position.
    Unlisted,
}

/// Commands and their acks.
const COMMAND: &[u32] = &[
    ids::COMMAND_INT,
    ids::COMMAND_LONG,
    ids::COMMAND_ACK,
    ids::COMMAND_CANCEL,
    ids::SET_MODE,
    // "go to item n" is the pilot's, not a transfer's
    ids::MISSION_SET_CURRENT,
    ids::SETUP_SIGNING,
];

/// Message ids that are part of a request/response transfer.
const PROTOCOL: &[u32] = &[
    ids::PARAM_REQUEST_READ,
    ids::PARAM_REQUEST_LIST,
    ids::PARAM_SET,
    ids::MISSION_REQUEST_PARTIAL_LIST,
    ids::MISSION_WRITE_PARTIAL_LIST,
    ids::MISSION_ITEM,
    ids::MISSION_REQUEST,
    ids::MISSION_REQUEST_LIST,
    ids::MISSION_COUNT,
    ids::MISSION_CLEAR_ALL,
    ids::MISSION_ITEM_REACHED,
    // a transfer's last word: it must not overtake the transfer's items
    ids::MISSION_ACK,
    ids::MISSION_REQUEST_INT,
    ids::MISSION_ITEM_INT,
    ids::MAVLORA_MISSION_ITEMS,
    ids::FILE_TRANSFER_PROTOCOL,
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
    /// Default class of a message id: [`Class::Command`] for commands and acks,
    /// [`Class::Protocol`] for mission, parameter-request and file transfers,
    /// [`Class::Status`] for `STATUSTEXT`, [`Class::Param`] for `PARAM_VALUE` and
    /// `MAVLORA_PARAM_VALUES`, [`Class::Periodic`] for everything else (the bridge demotes
    /// what its profile does not name to [`Class::Unlisted`]).
    pub fn of(message_id: u32) -> Self {
        if COMMAND.contains(&message_id) {
            Self::Command
        } else if PROTOCOL.contains(&message_id) {
            Self::Protocol
        } else if message_id == ids::STATUSTEXT {
            Self::Status
        } else if matches!(message_id, ids::PARAM_VALUE | ids::MAVLORA_PARAM_VALUES) {
            Self::Param
        } else {
            Self::Periodic
        }
    }

    /// Whether frames of this class are messages, not samples of a state (never replaced by
    /// a newer one): what the IO queues keep in their priority lane.
    pub fn is_protocol(self) -> bool {
        !matches!(self, Self::Periodic | Self::Unlisted)
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
    fn telemetry_is_periodic_and_commands_go_apart_from_transfers() {
        assert_eq!(Class::of(ids::GLOBAL_POSITION_INT), Class::Periodic);
        assert_eq!(Class::of(ids::HEARTBEAT), Class::Periodic);
        assert_eq!(Class::of(ids::COMMAND_LONG), Class::Command);
        assert_eq!(Class::of(ids::COMMAND_ACK), Class::Command);
        assert_eq!(Class::of(ids::MISSION_ITEM_INT), Class::Protocol);
        assert_eq!(Class::of(ids::MISSION_ACK), Class::Protocol);
        assert_eq!(Class::of(ids::FILE_TRANSFER_PROTOCOL), Class::Protocol);
        assert_eq!(Class::of(ids::STATUSTEXT), Class::Status);
        assert_eq!(Class::of(ids::PARAM_VALUE), Class::Param);
        assert_eq!(Class::of(ids::MAVLORA_PARAM_VALUES), Class::Param);
        assert!(Class::Param.is_protocol() && Class::Status.is_protocol());
        assert!(!Class::Unlisted.is_protocol() && !Class::Periodic.is_protocol());
    }
}
