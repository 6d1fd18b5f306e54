//! Changing a frame's MAVLink version without decoding it, so MAVLink 1 traffic can cross a
//! link where every frame must be MAVLink 2 (signing, one sequence per sender) and leave it
//! in the version the peer on the far side speaks.
//!
//! A frame's checksum covers its header and payload plus the message's CRC_EXTRA, so
//! rebuilding a frame needs the CRC_EXTRA. Ids the dialect or ArduPilot's knows take it from
//! their tables ([`known::checkable_crc_extra`]); for other ids it is recovered from the
//! frame's own checksum: the X.25 CRC's last step is injective in the CRC_EXTRA byte for a given state,
//! so at most one of the 256 values reproduces a carried checksum. A corrupted frame matches
//! none of them, except with probability 1/256, and then the value is wrong, so its rebuilt
//! checksum stays wrong for a receiver that knows the message.

use mavlink::{MavlinkVersion, calculate_crc};

use super::frame::{Frame, OwnedFrame, STX_V1, STX_V2};
use super::known;
use crate::dialect::MavMessage;

/// The CRC_EXTRA to rebuild `frame`'s checksum with: the dialects' tables', or for an unknown
/// id the one its carried checksum was made with; `None` if no value reproduces it
/// (corrupted).
pub fn crc_extra_of<T: AsRef<[u8]>>(frame: &Frame<T>) -> Option<u8> {
    if let Some(extra) = known::checkable_crc_extra(frame.message_id()) {
        return Some(extra);
    }
    let bytes = frame.as_bytes();
    let end = header_len(frame) + frame.payload_len();
    let carried = frame.checksum();
    (0..=u8::MAX).find(|&e| calculate_crc(&bytes[1..end], e) == carried)
}

fn header_len<T: AsRef<[u8]>>(frame: &Frame<T>) -> usize {
    if frame.version() == MavlinkVersion::V1 {
        6
    } else {
        10
    }
}

/// `frame` as MAVLink 2: unchanged if it already is; a MAVLink 1 frame gets the same sender,
/// sequence, message id and payload in a MAVLink 2 header (no flags) and its checksum
/// rebuilt. Payloads are not truncated, so the frame can be turned back exactly.
pub fn to_v2(frame: OwnedFrame) -> Option<OwnedFrame> {
    if frame.version() == MavlinkVersion::V2 {
        return Some(frame);
    }
    let extra = crc_extra_of(&frame)?;
    let payload = frame.payload();
    let id = frame.message_id().to_le_bytes();
    let mut bytes = Vec::with_capacity(12 + payload.len());
    bytes.extend_from_slice(&[
        STX_V2,
        payload.len() as u8,
        0,
        0,
        frame.sequence(),
        frame.system_id(),
        frame.component_id(),
        id[0],
        id[1],
        id[2],
    ]);
    bytes.extend_from_slice(payload);
    bytes.extend_from_slice(&[0, 0]);
    let mut out = Frame::new_unchecked(bytes);
    out.fill_checksum(extra);
    Some(out)
}

/// `frame` as MAVLink 1, for a peer that speaks only that: unchanged if it already is;
/// `None` for what MAVLink 1 cannot carry (a signed frame, a message id above 255). A known
/// message is re-encoded from its fields (a truncated payload regains its zeros, extension
/// fields are left out as MAVLink 1 has none); an unknown one keeps its payload bytes.
pub fn to_v1(frame: OwnedFrame) -> Option<OwnedFrame> {
    if frame.version() == MavlinkVersion::V1 {
        return Some(frame);
    }
    if frame.is_signed() || frame.message_id() > 255 {
        return None;
    }
    if known::crc_extra(frame.message_id()).is_some() {
        let msg = frame.decode::<MavMessage>().ok()?;
        return Some(super::encode(MavlinkVersion::V1, frame.header(), &msg));
    }
    let extra = crc_extra_of(&frame)?;
    let payload = frame.payload();
    let mut bytes = Vec::with_capacity(8 + payload.len());
    bytes.extend_from_slice(&[
        STX_V1,
        payload.len() as u8,
        frame.sequence(),
        frame.system_id(),
        frame.component_id(),
        frame.message_id() as u8,
    ]);
    bytes.extend_from_slice(payload);
    bytes.extend_from_slice(&[0, 0]);
    let mut out = Frame::new_unchecked(bytes);
    out.fill_checksum(extra);
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{ATTITUDE_DATA, COMMAND_ACK_DATA};
    use crate::testutil::{header, raw_frame};
    use crate::wire::encode;
    use crate::wire::ids::ATTITUDE;

    /// SIMSTATE (ArduPilot, id 164, CRC_EXTRA 154 in ardupilotmega.xml): not in our dialect.
    /// A MAVLink 1 frame of an id no dialect here defines (197), made with CRC_EXTRA 154.
    fn unknown_v1(seq: u8) -> OwnedFrame {
        assert_eq!(known::checkable_crc_extra(197), None);
        let payload: Vec<u8> = (0..44).map(|i| i as u8 ^ 0x5a).collect();
        let mut f = raw_frame(MavlinkVersion::V1, 1, 1, seq, 197, &payload);
        f.fill_checksum(154);
        f
    }

    #[test]
    fn known_v1_frame_becomes_the_same_message_in_v2() {
        let msg = MavMessage::ATTITUDE(ATTITUDE_DATA {
            roll: 0.5,
            yaw: -1.0,
            ..Default::default()
        });
        let v1 = encode(MavlinkVersion::V1, header(1, 1, 42), &msg);
        let v2 = to_v2(v1.clone()).unwrap();
        assert_eq!(v2.version(), MavlinkVersion::V2);
        assert_eq!(
            (v2.system_id(), v2.component_id(), v2.sequence()),
            (1, 1, 42)
        );
        assert_eq!(v2.message_id(), ATTITUDE);
        assert_eq!(v2.payload(), v1.payload());
        assert!(v2.crc_matches(known::crc_extra(ATTITUDE).unwrap()));
        assert_eq!(v2.decode::<MavMessage>().unwrap(), msg);
        // and back, byte for byte
        assert_eq!(to_v1(v2).unwrap(), v1);
    }

    #[test]
    fn unknown_v1_frame_keeps_its_crc_extra_both_ways() {
        let v1 = unknown_v1(9);
        assert_eq!(crc_extra_of(&v1), Some(154));
        let v2 = to_v2(v1.clone()).unwrap();
        assert!(
            v2.crc_matches(154),
            "v2 checksum made with the CRC_EXTRA the v1 frame carried"
        );
        assert_eq!(v2.payload(), v1.payload());
        assert_eq!(to_v1(v2).unwrap(), v1);
    }

    /// Every single-bit error in an unknown frame is refused or stays an error.
    #[test]
    fn corrupted_unknown_frame_is_refused_or_stays_corrupted() {
        let good = unknown_v1(3).into_inner();
        let mut refused = 0;
        // from the sequence byte on (a changed length byte is a different frame)
        for bit in 16..(good.len() - 2) * 8 {
            let mut bytes = good.clone();
            bytes[bit / 8] ^= 1 << (bit % 8);
            match to_v2(Frame::new_unchecked(bytes)) {
                None => refused += 1,
                Some(v2) => assert!(!v2.crc_matches(154), "bit {bit}"),
            }
        }
        assert!(refused > 330, "{refused} of 384 refused outright");
    }

    #[test]
    fn truncated_v2_payload_regains_its_zeros_in_v1() {
        let msg = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA::default());
        let v2 = encode(MavlinkVersion::V2, header(1, 1, 0), &msg);
        assert!(v2.payload_len() < 3, "all-zero ack truncated in v2");
        let v1 = to_v1(v2).unwrap();
        assert_eq!(v1.payload_len(), 3);
        assert_eq!(v1.decode::<MavMessage>().unwrap(), msg);
    }

    #[test]
    fn large_ids_do_not_fit_v1() {
        let f = raw_frame(MavlinkVersion::V2, 1, 1, 0, 12_900, &[1, 2, 3]);
        assert_eq!(to_v1(f), None);
    }
}
