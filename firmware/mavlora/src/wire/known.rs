//! Which message ids this library can check: the CRC_EXTRA table of the generated dialect.

use crate::dialect::MavMessage;
use mavlink::Message;

/// CRC_EXTRA of message `id`, `None` if the dialect does not know it (such frames can only be
/// forwarded unchecked).
pub fn crc_extra(id: u32) -> Option<u8> {
    // `all_ids` is sorted (checked by a test), and the generated `extra_crc` answers 0 for
    // unknown ids, which is also a legal CRC_EXTRA: the id list tells them apart.
    MavMessage::all_ids()
        .binary_search(&id)
        .ok()
        .map(|_| MavMessage::extra_crc(id))
}

/// CRC_EXTRA of message `id` for checking or rebuilding its frame: this library's dialect's,
/// else ArduPilot's (`ardupilotmega.xml`); `None` for ids neither defines (forwarded
/// unchecked). Frames of ArduPilot's own ids can be checked but not decoded here.
pub fn checkable_crc_extra(id: u32) -> Option<u8> {
    crc_extra(id).or_else(|| {
        let table = &crate::dialect::ardupilotmega::ARDUPILOTMEGA_CRC_EXTRA;
        table
            .binary_search_by_key(&id, |&(i, _)| i)
            .ok()
            .map(|i| table[i].1)
    })
}

/// Message id for a name such as `"GLOBAL_POSITION_INT"`.
pub fn message_id(name: &str) -> Option<u32> {
    MavMessage::message_id_from_name(name)
}

/// Message name for an id, for logs and reports.
pub fn message_name(id: u32) -> Option<&'static str> {
    MavMessage::default_message_from_id(id).map(|m| m.message_name())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{LINK_QUALITY_DATA, MAVLORA_COMPACT_DATA, MAVLORA_TELEMETRY_DATA};
    use mavlink::MessageData;

    #[test]
    fn ardupilot_messages_are_checkable_with_mavgen_s_values() {
        let table = &crate::dialect::ardupilotmega::ARDUPILOTMEGA_CRC_EXTRA;
        assert!(
            table.windows(2).all(|w| w[0].0 < w[1].0),
            "sorted, no id twice"
        );
        // pymavlink's ardupilotmega dialect (mavgen) gives these.
        for (name, id, extra) in [
            ("SIMSTATE", 164, 154),
            ("AHRS", 163, 127),
            ("AHRS2", 178, 47),
            ("HWSTATUS", 165, 21),
            ("MEMINFO", 152, 208),
            ("EKF_STATUS_REPORT", 193, 71),
        ] {
            assert_eq!(crc_extra(id), None, "{name} is not in our dialect");
            assert_eq!(checkable_crc_extra(id), Some(extra), "{name}");
        }
        // Ours and common's come from our dialect (14, compact telemetry, is no ArduPilot id).
        assert_eq!(checkable_crc_extra(14), crc_extra(14));
        assert_eq!(checkable_crc_extra(15), crc_extra(15));
        assert_eq!(checkable_crc_extra(33), crc_extra(33));
        assert_eq!(checkable_crc_extra(60_000), None);
    }

    #[test]
    fn id_list_is_sorted_for_binary_search() {
        assert!(MavMessage::all_ids().windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn our_messages_are_known_with_their_ids() {
        assert_eq!(message_id("LINK_QUALITY"), Some(15));
        assert_eq!(message_id("MAVLORA_TELEMETRY"), Some(16));
        assert_eq!(crc_extra(15), Some(LINK_QUALITY_DATA::EXTRA_CRC));
        assert_eq!(crc_extra(16), Some(MAVLORA_TELEMETRY_DATA::EXTRA_CRC));
        assert_eq!(message_name(15), Some("LINK_QUALITY"));
    }

    #[test]
    fn our_ids_are_unique_in_the_merged_dialect() {
        // bindgen merges included messages by name, so an id clash with common.xml would not
        // be caught at generation time: it would show as a repeated id here.
        for id in [
            MAVLORA_COMPACT_DATA::ID,
            LINK_QUALITY_DATA::ID,
            MAVLORA_TELEMETRY_DATA::ID,
        ] {
            let clashes = MavMessage::all_ids().iter().filter(|&&i| i == id).count();
            assert_eq!(clashes, 1, "id {id} defined more than once");
            assert!(id < 256, "id {id} must fit MAVLink 1");
        }
    }

    #[test]
    fn common_messages_keep_upstream_crc_extra() {
        // Values from the MAVLink spec's common.xml (mavgen): a drifted vendored XML breaks this.
        for (name, extra) in [
            ("HEARTBEAT", 50),
            ("SYS_STATUS", 124),
            ("GPS_RAW_INT", 24),
            ("ATTITUDE", 39),
            ("GLOBAL_POSITION_INT", 104),
            ("COMMAND_LONG", 152),
            ("MISSION_ITEM_INT", 38),
        ] {
            let id = message_id(name).unwrap();
            assert_eq!(crc_extra(id), Some(extra), "{name}");
        }
        assert_eq!(crc_extra(9999), None);
    }
}
