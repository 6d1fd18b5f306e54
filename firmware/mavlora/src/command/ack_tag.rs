//! Which command a copy is and which command an ack answers, on the radio leg between bridge
//! and router (both ours; neither tag reaches the flight controller or the ground station).
//!
//! # Commands
//!
//! Each copy of a command the router sends on the radio carries a tag after its payload: the
//! `COMMAND_LONG` or `COMMAND_INT` payload at its full length (MAVLink 2's trailing-zero
//! truncation undone), then
//!
//! | bytes | meaning |
//! |---|---|
//! | 0..2 | the router's epoch ([`Epoch`], little endian): drawn at random at each router start |
//! | 2 | the radio confirmation: generation (bits 7..3) and attempt (bits 2..0), see [`radio_confirmation`](super::radio_confirmation) |
//! | 3 | the copy's age: time since the command's first copy went, in 100 ms (rounded down, at most 255) |
//!
//! A receiver that knows the message ignores bytes past its fields (MAVLink 2 extension
//! rules), so the frame still decodes as the command; the bridge gives the flight controller
//! the command re-encoded without them. A `COMMAND_LONG` also carries the radio confirmation
//! in its own `confirmation` field. `COMMAND_INT` has no such field: the tag is its only
//! generation, which is why it needs one.
//!
//! The epoch keeps a restarted router's generations apart from its previous run's: both start
//! with the same small numbers, and the bridge still holds the previous run's acks. Keyed by
//! (epoch, identity, generation), a copy of the new run's command is never answered with an
//! ack of the old run's (two runs draw the same epoch once in 2^16, and then it matters only
//! for a command of the same identity and generation within the cache's 12 s; 16 bits and
//! not 32 because every byte of a command copy and an ack is air time that telemetry
//! waits for on a half-duplex LoRa channel).
//!
//! The age tells a restarted bridge whether a copy's command may have come before it started
//! (then it cannot tell whether the autopilot ran it) or certainly after (then a copy it
//! never saw had its earlier copies lost, and goes): see [`AckCache::new`](super::AckCache::new).
//!
//! # Acks
//!
//! `COMMAND_ACK` names only the command id, so after a command was sent more than once the
//! router cannot tell a late copy's ack from the next command's (same id) by the ack alone:
//! it would have to hold the next one back until no such ack could arrive. The bridge knows
//! which generation it forwarded and writes it into the ack's `result_param2` (a MAVLink 2
//! extension field) on the way to the radio, and the epoch after the ack's full 10-byte
//! payload (2 bytes, as above); the router reads both, matches the ack to exactly that
//! command of its own run, and gives the ground station the ack as the autopilot sent it.
//!
//! The bridge also writes which copy of the command the ack answers (its attempt): the copy
//! it forwarded to the autopilot, or the copy it answered from its cache. The router then
//! measures the round trip from that copy's send, so a command sent several times (the
//! redundant copies of a lossy link) still gives an unambiguous sample, as QUIC's packet
//! numbers make Karn's rule unnecessary. A repeat of an ack the bridge sends of its own
//! accord answers no copy: it names none, and gives no sample.
//!
//! ## Layout of a tagged `result_param2`
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
//! untagged (no epoch either), and the router falls back to holding the next command back
//! (see [`CommandRetransmitter`](super::CommandRetransmitter)). An ack is tagged only with
//! both the mark and the epoch.
//!
//! Both ends must run this format: an older router sends no epoch, and the bridge forwards
//! its commands as they come, uncached.

use mavlink::MavlinkVersion;

use crate::dialect::{COMMAND_ACK_DATA, COMMAND_INT_DATA, COMMAND_LONG_DATA, MavMessage};
use crate::time::Duration;
use crate::wire::{Frame, OwnedFrame, encode, known, to_v2};

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
/// A router run's number, drawn at random at its start (see the [module](self) doc).
pub type Epoch = u16;

/// The epoch after a payload.
const EPOCH_LEN: usize = 2;
/// A command's tag after its payload: the epoch, the radio confirmation and the age.
const COMMAND_TAG_LEN: usize = EPOCH_LEN + 2;
/// The unit of a copy's age.
const AGE_UNIT: Duration = Duration::from_millis(100);

/// Which copy of which command a frame on the radio is (see the [module](self) doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CommandTag {
    /// The router run that sent it.
    pub epoch: Epoch,
    /// The radio confirmation: generation and attempt
    /// ([`split_confirmation`](super::split_confirmation)).
    pub confirmation: u8,
    /// How long after the command's first copy this copy went (to 100 ms, rounded down;
    /// at most 25.5 s).
    pub age: Duration,
}

/// What the bridge wrote into an ack it sends on the radio.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AckTag {
    /// The router run whose command it answers.
    pub epoch: Epoch,
    /// Generation of the command answered (0..32).
    pub generation: u8,
    /// Attempt (the radio confirmation's, 0..=6) of the copy answered; `None` for a repeat
    /// the bridge sent of its own accord, or a copy past attempt 6.
    pub attempt: Option<u8>,
}

impl AckTag {
    /// The tag of an ack for `generation` of the router run `epoch`, answering the copy
    /// `attempt` (7 and more: none).
    pub fn new(epoch: Epoch, generation: u8, attempt: Option<u8>) -> Self {
        Self {
            epoch,
            generation: generation & 0x1f,
            attempt: attempt.filter(|&a| u32::from(a) < NO_ATTEMPT),
        }
    }
}

/// The payload length of a command or ack with every field (MAVLink 2 truncation undone).
fn full_len(msg: &MavMessage) -> Option<usize> {
    match msg {
        MavMessage::COMMAND_LONG(_) => Some(COMMAND_LONG_DATA::ENCODED_LEN),
        MavMessage::COMMAND_INT(_) => Some(COMMAND_INT_DATA::ENCODED_LEN),
        MavMessage::COMMAND_ACK(_) => Some(COMMAND_ACK_DATA::ENCODED_LEN),
        _ => None,
    }
}

/// `frame` (MAVLink 2) with its payload at `len` bytes followed by `tag`, checksum recomputed.
fn append(frame: &OwnedFrame, len: usize, tag: &[u8]) -> Option<OwnedFrame> {
    let frame = to_v2(frame.clone())?;
    let extra = known::crc_extra(frame.message_id())?;
    let mut payload = frame.payload().to_vec();
    payload.resize(len, 0);
    payload.extend_from_slice(tag);
    let mut bytes = frame.as_bytes()[..10].to_vec();
    bytes[1] = payload.len() as u8;
    // Unsigned: the radio leg signs what it sends after this.
    bytes[2] = 0;
    bytes.extend_from_slice(&payload);
    bytes.extend_from_slice(&[0, 0]);
    let mut out = Frame::new_unchecked(bytes);
    out.fill_checksum(extra);
    Some(out)
}

/// The `n` tag bytes after the full payload of `frame` (decoded: `msg`), if it has them.
fn tag_bytes<'a>(frame: &'a OwnedFrame, msg: &MavMessage, n: usize) -> Option<&'a [u8]> {
    let len = full_len(msg)?;
    (frame.version() == MavlinkVersion::V2 && frame.payload_len() == len + n)
        .then(|| &frame.payload()[len..])
}

fn epoch_of(bytes: &[u8]) -> Epoch {
    Epoch::from_le_bytes([bytes[0], bytes[1]])
}

/// The command `frame` (decoded: `msg`) as it goes on the radio, tagged with `tag` (always
/// MAVLink 2); other frames unchanged.
pub fn tag_command(frame: &OwnedFrame, msg: &MavMessage, tag: CommandTag) -> OwnedFrame {
    let Some(len) = full_len(msg).filter(|_| !matches!(msg, MavMessage::COMMAND_ACK(_))) else {
        return frame.clone();
    };
    let mut bytes = [0; COMMAND_TAG_LEN];
    bytes[..EPOCH_LEN].copy_from_slice(&tag.epoch.to_le_bytes());
    bytes[EPOCH_LEN] = tag.confirmation;
    bytes[EPOCH_LEN + 1] = (tag.age.as_micros() / AGE_UNIT.as_micros()).min(255) as u8;
    append(frame, len, &bytes).unwrap_or_else(|| frame.clone())
}

/// The tag of a command from the radio (`frame` decodes to `msg`); `None`: untagged.
pub fn untag_command(frame: &OwnedFrame, msg: &MavMessage) -> Option<CommandTag> {
    if !matches!(
        msg,
        MavMessage::COMMAND_LONG(_) | MavMessage::COMMAND_INT(_)
    ) {
        return None;
    }
    let bytes = tag_bytes(frame, msg, COMMAND_TAG_LEN)?;
    Some(CommandTag {
        epoch: epoch_of(bytes),
        confirmation: bytes[EPOCH_LEN],
        age: AGE_UNIT * u32::from(bytes[EPOCH_LEN + 1]),
    })
}

/// The ack `frame` (decoded: `ack`) as it goes on the radio, tagged with `tag` (always
/// MAVLink 2: MAVLink 1 has no extension fields); `None` if the autopilot's own
/// `result_param2` does not fit beside the tag (the frame then goes as it is).
pub fn tag_ack(frame: &OwnedFrame, ack: &COMMAND_ACK_DATA, tag: AckTag) -> Option<OwnedFrame> {
    if !VALUE_RANGE.contains(&ack.result_param2) {
        return None;
    }
    let tag = AckTag::new(tag.epoch, tag.generation, tag.attempt);
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
    let marked = encode(
        MavlinkVersion::V2,
        frame.header(),
        &MavMessage::COMMAND_ACK(tagged),
    );
    append(
        &marked,
        COMMAND_ACK_DATA::ENCODED_LEN,
        &tag.epoch.to_le_bytes(),
    )
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
    let epoch = epoch_of(tag_bytes(
        frame,
        &MavMessage::COMMAND_ACK(ack.clone()),
        EPOCH_LEN,
    )?);
    let generation = ((raw >> GENERATION_SHIFT) & 0x1f) as u8;
    let attempt = (raw >> ATTEMPT_SHIFT) & NO_ATTEMPT;
    let tag = AckTag::new(
        epoch,
        generation,
        (attempt != NO_ATTEMPT).then_some(attempt as u8),
    );
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
                for (epoch, generation) in [(0, 0), (1, 1), (0xbeef, 17), (Epoch::MAX, 31)] {
                    for attempt in [Some(0), Some(3), Some(6), None] {
                        let tag = AckTag::new(epoch, generation, attempt);
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
        assert_eq!(AckTag::new(5, 33, Some(7)), AckTag::new(5, 1, None));
        assert_eq!(AckTag::new(5, 2, Some(200)).attempt, None);
        assert_eq!(AckTag::new(5, 2, Some(6)).attempt, Some(6));
    }

    #[test]
    fn a_value_that_does_not_fit_goes_untagged() {
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        for v in [1 << 20, -(1 << 20) - 1, 1 << 23, i32::MIN, i32::MAX] {
            let f = fc.frame(&MavMessage::COMMAND_ACK(ack(v)));
            assert!(
                tag_ack(&f, &ack(v), AckTag::new(9, 3, Some(0))).is_none(),
                "{v}"
            );
        }
    }

    #[test]
    fn an_ack_marked_in_result_param2_without_the_epoch_is_untagged() {
        // what a router of this format gets from a bridge of the previous one
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        let raw = (MARK | (3 << GENERATION_SHIFT)) as i32;
        let f = fc.frame(&MavMessage::COMMAND_ACK(ack(raw)));
        assert!(untag_ack(&f, &ack(raw)).is_none());
    }

    fn long(confirmation: u8) -> MavMessage {
        MavMessage::COMMAND_LONG(crate::dialect::COMMAND_LONG_DATA {
            target_system: 1,
            target_component: 1,
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            confirmation,
            param1: 1.0,
            ..Default::default()
        })
    }

    fn int() -> MavMessage {
        MavMessage::COMMAND_INT(crate::dialect::COMMAND_INT_DATA {
            target_system: 1,
            target_component: 1,
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            param1: 1.0,
            ..Default::default()
        })
    }

    #[test]
    fn a_tagged_command_decodes_as_itself_and_gives_its_tag_back() {
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        for (msg, confirmation) in [(long(0), 0), (long(0x1d), 0x1d), (int(), 0x1d)] {
            let f = gcs.frame(&msg);
            let tag = CommandTag {
                epoch: 0x0304,
                confirmation,
                age: Duration::from_millis(1200),
            };
            let tagged = tag_command(&f, &msg, tag);
            assert_eq!(tagged.decode::<MavMessage>().unwrap(), msg);
            assert_eq!(tagged.header(), f.header());
            assert_eq!(untag_command(&tagged, &msg), Some(tag));
            // untagged: as the ground sent it
            assert_eq!(untag_command(&f, &msg), None);
        }
    }

    #[test]
    fn a_v1_command_is_tagged_as_mavlink_2() {
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V1);
        let f = gcs.frame(&int());
        let tag = CommandTag {
            epoch: 7,
            confirmation: 8,
            age: Duration::ZERO,
        };
        let tagged = tag_command(&f, &int(), tag);
        assert_eq!(tagged.version(), MavlinkVersion::V2);
        assert_eq!(untag_command(&tagged, &int()), Some(tag));
    }
}
