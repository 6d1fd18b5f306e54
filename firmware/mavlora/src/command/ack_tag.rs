//! Which command an ack answers, on the radio leg between bridge and router.
//!
//! `COMMAND_ACK` names only the command id, so after a command was sent more than once the
//! router cannot tell a late copy's ack from the next command's (same id) by the ack alone:
//! it would have to hold the next one back until no such ack could arrive. The bridge knows which generation
//! it forwarded (the radio confirmation, see [`radio_confirmation`](super::radio_confirmation))
//! and writes it into the ack's `result_param2` (a MAVLink 2 extension field) on the way to
//! the radio; the router reads it, matches the ack to exactly that command, and gives the
//! ground station the ack as the autopilot sent it.
//!
//! The bridge also writes which copy of the command the ack answers (its attempt): the copy
//! it forwarded to the autopilot, or the copy it answered from its cache. The router then
//! measures the round trip from that copy's send, so a command sent several times (the
//! redundant copies of a lossy link) still gives an unambiguous sample, as QUIC's packet
//! numbers make Karn's rule unnecessary. A repeat of an ack the bridge sends of its own
//! accord answers no copy: it names none, and gives no sample.
//!
//! # Layout of a tagged `result_param2`
//!
//! | bits | meaning |
//! |---|---|
//! | 31..30 | `0b10`: tagged |
//! | 29 | the autopilot sent the ack as MAVLink 1 (the router sends it on so) |
//! | 28..24 | generation (5 bits) |
//! | 23..21 | attempt of the copy answered, 0..=6; 7: none (a repeat, or a later copy) |
//! | 20..0 | the autopilot's own `result_param2`, 21-bit two's complement |
//!
//! A value the autopilot put there that fits 21 bits (every command-specific enum does) has
//! its top 12 bits alike, so it never reads as tagged. One that does not fit is sent
//! untagged, and the router falls back to holding the next command back (see
//! [`CommandRetransmitter`](super::CommandRetransmitter)).

use mavlink::MavlinkVersion;

use crate::dialect::{COMMAND_ACK_DATA, MavMessage};
use crate::wire::{OwnedFrame, encode};

const MARK: u32 = 0b10 << 30;
const MARK_MASK: u32 = 0b11 << 30;
const WAS_V1: u32 = 1 << 29;
const GENERATION_SHIFT: u32 = 24;
const ATTEMPT_SHIFT: u32 = 21;
/// The attempt field's value for "no copy named".
const NO_ATTEMPT: u32 = 7;
const VALUE_BITS: u32 = 21;
const VALUE_MASK: u32 = (1 << VALUE_BITS) - 1;
/// The autopilot's own values that fit beside the tag.
const VALUE_RANGE: std::ops::Range<i32> = -(1 << (VALUE_BITS - 1))..(1 << (VALUE_BITS - 1));

/// What the bridge wrote into an ack it sends on the radio.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AckTag {
    /// Generation of the command answered (0..32).
    pub generation: u8,
    /// Attempt (the radio confirmation's, 0..=6) of the copy answered; `None` for a repeat
    /// the bridge sent of its own accord, or a copy past attempt 6.
    pub attempt: Option<u8>,
}

impl AckTag {
    /// The tag of an ack for `generation` answering the copy `attempt` (7 and more: none).
    pub fn new(generation: u8, attempt: Option<u8>) -> Self {
        Self {
            generation: generation & 0x1f,
            attempt: attempt.filter(|&a| u32::from(a) < NO_ATTEMPT),
        }
    }
}

/// The ack `frame` (decoded: `ack`) as it goes on the radio, tagged with `tag` (always
/// MAVLink 2: MAVLink 1 has no extension fields); `None` if the autopilot's own
/// `result_param2` does not fit beside the tag (the frame then goes as it is).
pub fn tag_ack(frame: &OwnedFrame, ack: &COMMAND_ACK_DATA, tag: AckTag) -> Option<OwnedFrame> {
    if !VALUE_RANGE.contains(&ack.result_param2) {
        return None;
    }
    let tag = AckTag::new(tag.generation, tag.attempt);
    let v1 = if frame.version() == MavlinkVersion::V1 {
        WAS_V1
    } else {
        0
    };
    let attempt = tag.attempt.map_or(NO_ATTEMPT, u32::from);
    let raw = MARK
        | v1
        | (u32::from(tag.generation) << GENERATION_SHIFT)
        | (attempt << ATTEMPT_SHIFT)
        | (ack.result_param2 as u32 & VALUE_MASK);
    let tagged = COMMAND_ACK_DATA {
        result_param2: raw as i32,
        ..ack.clone()
    };
    Some(encode(
        MavlinkVersion::V2,
        frame.header(),
        &MavMessage::COMMAND_ACK(tagged),
    ))
}

/// An ack from the radio: if tagged, its tag and the ack as the autopilot sent it (its
/// `result_param2` and MAVLink version restored), frame and message; `None` for an untagged
/// ack.
pub fn untag_ack(
    frame: &OwnedFrame,
    ack: &COMMAND_ACK_DATA,
) -> Option<(AckTag, OwnedFrame, COMMAND_ACK_DATA)> {
    let raw = ack.result_param2 as u32;
    if raw & MARK_MASK != MARK {
        return None;
    }
    let generation = ((raw >> GENERATION_SHIFT) & 0x1f) as u8;
    let attempt = (raw >> ATTEMPT_SHIFT) & NO_ATTEMPT;
    let tag = AckTag::new(generation, (attempt != NO_ATTEMPT).then_some(attempt as u8));
    // Sign-extend the value.
    let value = (((raw & VALUE_MASK) << (32 - VALUE_BITS)) as i32) >> (32 - VALUE_BITS);
    let plain = COMMAND_ACK_DATA {
        result_param2: value,
        ..ack.clone()
    };
    let version = if raw & WAS_V1 != 0 {
        MavlinkVersion::V1
    } else {
        MavlinkVersion::V2
    };
    let out = encode(
        version,
        frame.header(),
        &MavMessage::COMMAND_ACK(plain.clone()),
    );
    Some((tag, out, plain))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{MavCmd, MavResult};
    use crate::wire::Sender;

    fn ack(result_param2: i32) -> COMMAND_ACK_DATA {
        COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_DO_SET_MODE,
            result: MavResult::MAV_RESULT_DENIED,
            progress: 7,
            result_param2,
            target_system: 255,
            target_component: 190,
        }
    }

    fn decoded(f: &OwnedFrame) -> COMMAND_ACK_DATA {
        match f.decode::<MavMessage>() {
            Ok(MavMessage::COMMAND_ACK(a)) => a,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_autopilots_ack_comes_back_byte_for_byte() {
        for version in [MavlinkVersion::V2, MavlinkVersion::V1] {
            let mut fc = Sender::new(1, 1, version);
            for v in [0, 1, -1, 42, (1 << 20) - 1, -(1 << 20)] {
                let a = if version == MavlinkVersion::V1 {
                    // MAVLink 1 carries no extension fields
                    COMMAND_ACK_DATA {
                        command: MavCmd::MAV_CMD_DO_SET_MODE,
                        ..Default::default()
                    }
                } else {
                    ack(v)
                };
                let f = fc.frame(&MavMessage::COMMAND_ACK(a.clone()));
                for generation in [0, 1, 17, 31] {
                    for attempt in [Some(0), Some(3), Some(6), None] {
                        let tag = AckTag::new(generation, attempt);
                        let tagged = tag_ack(&f, &a, tag).expect("fits");
                        assert_eq!(tagged.version(), MavlinkVersion::V2);
                        let (t, back, plain) = untag_ack(&tagged, &decoded(&tagged)).unwrap();
                        assert_eq!(t, tag);
                        assert_eq!(plain, a);
                        assert_eq!(back.as_bytes(), f.as_bytes(), "{version:?} {v} {t:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn an_untagged_ack_is_not_read_as_tagged() {
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        for v in [0, 1, -1, 1 << 20, -(1 << 23), (1 << 23) - 1, i32::MAX] {
            let f = fc.frame(&MavMessage::COMMAND_ACK(ack(v)));
            assert!(untag_ack(&f, &ack(v)).is_none(), "{v}");
        }
    }

    #[test]
    fn attempts_past_six_name_no_copy() {
        assert_eq!(AckTag::new(33, Some(7)), AckTag::new(1, None));
        assert_eq!(AckTag::new(2, Some(200)).attempt, None);
        assert_eq!(AckTag::new(2, Some(6)).attempt, Some(6));
    }

    #[test]
    fn a_value_that_does_not_fit_goes_untagged() {
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        for v in [1 << 20, -(1 << 20) - 1, 1 << 23, i32::MIN, i32::MAX] {
            let f = fc.frame(&MavMessage::COMMAND_ACK(ack(v)));
            assert!(
                tag_ack(&f, &ack(v), AckTag::new(3, Some(0))).is_none(),
                "{v}"
            );
        }
    }
}
