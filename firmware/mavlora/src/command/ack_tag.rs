//! Which command an ack answers, on the radio leg between bridge and router.
//!
//! `COMMAND_ACK` names only the command id, so after a command was sent more than once the
//! router could not tell a late copy's ack from the next command's (same id) and had to
//! hold the next one back until no such ack could arrive. The bridge knows which generation
//! it forwarded (the radio confirmation, see [`radio_confirmation`](super::radio_confirmation))
//! and writes it into the ack's `result_param2` (a MAVLink 2 extension field) on the way to
//! the radio; the router reads it, matches the ack to exactly that command, and gives the
//! ground station the ack as the autopilot sent it.
//!
//! # Layout of a tagged `result_param2`
//!
//! | bits | meaning |
//! |---|---|
//! | 31..30 | `0b10`: tagged |
//! | 29 | the autopilot sent the ack as MAVLink 1 (the router sends it on so) |
//! | 28..24 | generation (5 bits) |
//! | 23..0 | the autopilot's own `result_param2`, 24-bit two's complement |
//!
//! A value the autopilot put there that fits 24 bits (every command-specific enum does) has
//! its top 9 bits alike, so it never reads as tagged. One that does not fit is sent
//! untagged, and the router falls back to holding the next command back (see
//! [`CommandRetransmitter`](super::CommandRetransmitter)).

use mavlink::MavlinkVersion;

use crate::dialect::{COMMAND_ACK_DATA, MavMessage};
use crate::wire::{OwnedFrame, encode};

const MARK: u32 = 0b10 << 30;
const MARK_MASK: u32 = 0b11 << 30;
const WAS_V1: u32 = 1 << 29;
const GENERATION_SHIFT: u32 = 24;
const VALUE_MASK: u32 = 0x00ff_ffff;
/// The autopilot's own values that fit beside the tag.
const VALUE_RANGE: std::ops::Range<i32> = -(1 << 23)..(1 << 23);

/// The ack `frame` (decoded: `ack`) as it goes on the radio, tagged with `generation`
/// (always MAVLink 2: MAVLink 1 has no extension fields); `None` if the autopilot's own
/// `result_param2` does not fit beside the tag (the frame then goes as it is).
pub fn tag_ack(frame: &OwnedFrame, ack: &COMMAND_ACK_DATA, generation: u8) -> Option<OwnedFrame> {
    if !VALUE_RANGE.contains(&ack.result_param2) {
        return None;
    }
    let v1 = if frame.version() == MavlinkVersion::V1 {
        WAS_V1
    } else {
        0
    };
    let raw = MARK
        | v1
        | (u32::from(generation & 0x1f) << GENERATION_SHIFT)
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

/// An ack from the radio: if tagged, the generation it answers and the ack as the autopilot
/// sent it (its `result_param2` and MAVLink version restored), frame and message; `None` for
/// an untagged ack.
pub fn untag_ack(
    frame: &OwnedFrame,
    ack: &COMMAND_ACK_DATA,
) -> Option<(u8, OwnedFrame, COMMAND_ACK_DATA)> {
    let raw = ack.result_param2 as u32;
    if raw & MARK_MASK != MARK {
        return None;
    }
    let generation = ((raw >> GENERATION_SHIFT) & 0x1f) as u8;
    // Sign-extend the 24-bit value.
    let value = (((raw & VALUE_MASK) << 8) as i32) >> 8;
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
    Some((generation, out, plain))
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
            for v in [0, 1, -1, 42, (1 << 23) - 1, -(1 << 23)] {
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
                    let tagged = tag_ack(&f, &a, generation).expect("fits");
                    assert_eq!(tagged.version(), MavlinkVersion::V2);
                    let (g, back, plain) = untag_ack(&tagged, &decoded(&tagged)).unwrap();
                    assert_eq!(g, generation);
                    assert_eq!(plain, a);
                    assert_eq!(back.as_bytes(), f.as_bytes(), "{version:?} {v} {g}");
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
    fn a_value_that_does_not_fit_goes_untagged() {
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        for v in [1 << 23, -(1 << 23) - 1, i32::MIN, i32::MAX] {
            let f = fc.frame(&MavMessage::COMMAND_ACK(ack(v)));
            assert!(tag_ack(&f, &ack(v), 3).is_none(), "{v}");
        }
    }
}
