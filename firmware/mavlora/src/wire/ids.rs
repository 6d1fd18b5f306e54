//! Message ids by name, for `match` arms and id tables: each is the generated dialect's
//! `<NAME>_DATA::ID`, so the numbers are written only in the XML the dialect is generated from.
//! Plain `u32` constants, so callers need neither the dialect's types nor `mavlink`'s
//! `MessageData` trait in scope.

// Some are deprecated messages (MISSION_REQUEST, SET_MODE, ...) that older autopilots and
// tools still send, so the engines still have to recognise them.
#![allow(deprecated)]

use mavlink::MessageData;

use crate::dialect::*;

macro_rules! ids {
    ($($name:ident = $data:ident),* $(,)?) => {
        $(
            #[doc = concat!("`", stringify!($name), "`")]
            pub const $name: u32 = $data::ID;
        )*
        /// Every id above with its name, to check them against the dialect's names.
        #[cfg(test)]
        const NAMED: &[(u32, &str)] = &[$(($name, stringify!($name))),*];
    };
}

ids! {
    HEARTBEAT = HEARTBEAT_DATA,
    CURRENT_MODE = CURRENT_MODE_DATA,
    SYS_STATUS = SYS_STATUS_DATA,
    SYSTEM_TIME = SYSTEM_TIME_DATA,
    SET_MODE = SET_MODE_DATA,
    LINK_QUALITY = LINK_QUALITY_DATA,
    MAVLORA_TELEMETRY = MAVLORA_TELEMETRY_DATA,
    MAVLORA_POSITION_BATCH = MAVLORA_POSITION_BATCH_DATA,
    MAVLORA_STATUS = MAVLORA_STATUS_DATA,
    MAVLORA_MISSION_ITEMS = MAVLORA_MISSION_ITEMS_DATA,
    MAVLORA_PARAM_VALUES = MAVLORA_PARAM_VALUES_DATA,
    MAVLORA_COMPACT = MAVLORA_COMPACT_DATA,
    PARAM_REQUEST_READ = PARAM_REQUEST_READ_DATA,
    PARAM_REQUEST_LIST = PARAM_REQUEST_LIST_DATA,
    PARAM_VALUE = PARAM_VALUE_DATA,
    PARAM_SET = PARAM_SET_DATA,
    GPS_RAW_INT = GPS_RAW_INT_DATA,
    ATTITUDE = ATTITUDE_DATA,
    GLOBAL_POSITION_INT = GLOBAL_POSITION_INT_DATA,
    MISSION_REQUEST_PARTIAL_LIST = MISSION_REQUEST_PARTIAL_LIST_DATA,
    MISSION_WRITE_PARTIAL_LIST = MISSION_WRITE_PARTIAL_LIST_DATA,
    MISSION_ITEM = MISSION_ITEM_DATA,
    MISSION_REQUEST = MISSION_REQUEST_DATA,
    MISSION_SET_CURRENT = MISSION_SET_CURRENT_DATA,
    MISSION_CURRENT = MISSION_CURRENT_DATA,
    MISSION_REQUEST_LIST = MISSION_REQUEST_LIST_DATA,
    MISSION_COUNT = MISSION_COUNT_DATA,
    MISSION_CLEAR_ALL = MISSION_CLEAR_ALL_DATA,
    MISSION_ITEM_REACHED = MISSION_ITEM_REACHED_DATA,
    MISSION_ACK = MISSION_ACK_DATA,
    MISSION_REQUEST_INT = MISSION_REQUEST_INT_DATA,
    MISSION_ITEM_INT = MISSION_ITEM_INT_DATA,
    VFR_HUD = VFR_HUD_DATA,
    COMMAND_INT = COMMAND_INT_DATA,
    TIMESYNC = TIMESYNC_DATA,
    COMMAND_LONG = COMMAND_LONG_DATA,
    COMMAND_ACK = COMMAND_ACK_DATA,
    COMMAND_CANCEL = COMMAND_CANCEL_DATA,
    RADIO_STATUS = RADIO_STATUS_DATA,
    FILE_TRANSFER_PROTOCOL = FILE_TRANSFER_PROTOCOL_DATA,
    GPS_RTCM_DATA = GPS_RTCM_DATA_DATA,
    GPS_INJECT_DATA = GPS_INJECT_DATA_DATA,
    SERIAL_CONTROL = SERIAL_CONTROL_DATA,
    LOG_ENTRY = LOG_ENTRY_DATA,
    LOG_DATA = LOG_DATA_DATA,
    LOGGING_DATA = LOGGING_DATA_DATA,
    LOGGING_DATA_ACKED = LOGGING_DATA_ACKED_DATA,
    PARAM_EXT_VALUE = PARAM_EXT_VALUE_DATA,
    EVENT = EVENT_DATA,
    RESPONSE_EVENT_ERROR = RESPONSE_EVENT_ERROR_DATA,
    ENCAPSULATED_DATA = ENCAPSULATED_DATA_DATA,
    DATA_TRANSMISSION_HANDSHAKE = DATA_TRANSMISSION_HANDSHAKE_DATA,
    TUNNEL = TUNNEL_DATA,
    V2_EXTENSION = V2_EXTENSION_DATA,
    STATUSTEXT = STATUSTEXT_DATA,
    SETUP_SIGNING = SETUP_SIGNING_DATA,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::known;

    #[test]
    fn each_name_is_the_dialects_name_of_its_id() {
        for &(id, name) in NAMED {
            assert_eq!(known::message_name(id), Some(name), "id {id}");
        }
    }
}
