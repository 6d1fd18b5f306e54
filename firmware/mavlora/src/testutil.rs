//! Frame builders shared by unit tests.

use mavlink::{MavHeader, MavlinkVersion, Message};

use crate::dialect::MavMessage;
use crate::wire::{OwnedFrame, encode, known};

/// Encodes the default message of `id` from (sysid, compid) with sequence `seq`, MAVLink 2.
pub fn frame(id: u32, sysid: u8, compid: u8, seq: u8) -> OwnedFrame {
    let msg = MavMessage::default_message_from_id(id).expect("known message id");
    encode(MavlinkVersion::V2, header(sysid, compid, seq), &msg)
}

/// A header for tests.
pub fn header(sysid: u8, compid: u8, seq: u8) -> MavHeader {
    MavHeader {
        system_id: sysid.into(),
        component_id: compid,
        sequence: seq,
    }
}

/// Builds a frame from raw parts with a correct checksum for known ids (any checksum bytes
/// for unknown ones): lets tests make arbitrary payloads and message ids.
pub fn raw_frame(
    version: MavlinkVersion,
    sysid: u8,
    compid: u8,
    seq: u8,
    msgid: u32,
    payload: &[u8],
) -> OwnedFrame {
    assert!(payload.len() <= 255);
    let mut bytes = match version {
        MavlinkVersion::V1 => {
            let id = u8::try_from(msgid).expect("v1 ids fit a byte");
            vec![0xFE, payload.len() as u8, seq, sysid, compid, id]
        }
        MavlinkVersion::V2 => {
            let id = msgid.to_le_bytes();
            vec![
                0xFD,
                payload.len() as u8,
                0,
                0,
                seq,
                sysid,
                compid,
                id[0],
                id[1],
                id[2],
            ]
        }
    };
    bytes.extend_from_slice(payload);
    let crc = mavlink::calculate_crc(&bytes[1..], known::checkable_crc_extra(msgid).unwrap_or(0));
    bytes.extend_from_slice(&crc.to_le_bytes());
    OwnedFrame::new_checked(bytes).expect("well-formed test frame")
}

/// A ground station's ARM (`COMMAND_LONG`) for vehicle 1, component 1.
pub fn arm_command() -> MavMessage {
    use crate::dialect::{COMMAND_LONG_DATA, MavCmd};
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        ..Default::default()
    })
}
