//! Consecutive mission items packed into one `MAVLORA_MISSION_ITEMS` frame for the radio leg.
//!
//! A `MISSION_ITEM_INT` takes 49 bytes with its MAVLink 2 framing, and over a slow radio the
//! byte budget bounds an upload (LoRa SF7 at 251 B/s: 100 items need 19.5 s however well the
//! repairs go). Items of one plan differ little from one to the next: each is stored as the
//! fields that differ from the item before it in the same frame (the first: from an all-zero
//! item), so a frame needs nothing from any other frame and a lost one is repaired alone.
//!
//! Per item: a LEB128 varint field mask ([`X`] ... [`AUTOCONTINUE`]), then each field present,
//! in mask-bit order: `x`, `y` and `command` as the zigzag varint of the wrapping difference;
//! `z` and `param1..4` as the varint of the bit-reversed XOR of the two bit patterns (the sign,
//! exponent and top of the mantissa, where neighbours differ, land in the low bits; exact for
//! every value, NaN payloads included); `frame`, `current` and `autocontinue` as one byte.
//! Sequence numbers are implicit, targets and `mission_type` are the frame's. Waypoints of a
//! survey cost about 8 bytes each instead of 49 (100 of them: 5 frames, 945 bytes).
//!
//! A frame with no item is the router's status poll ([`poll`]).
//!
//! Decoding builds the standard `MISSION_ITEM_INT` payload and parses it with the dialect's own
//! parser, so an enum value the dialect does not know is refused as it would be in a
//! `MISSION_ITEM_INT`.

use mavlink::{MavlinkVersion, MessageData};

use crate::dialect::{
    MAVLORA_MISSION_ITEMS_DATA, MISSION_ITEM_INT_DATA, MavMessage, MavMissionType,
};

/// Mask bit of `x`.
pub const X: u32 = 1 << 0;
/// Mask bit of `y`.
pub const Y: u32 = 1 << 1;
/// Mask bit of `z`.
pub const Z: u32 = 1 << 2;
/// Mask bit of `param1` (`param2..4` follow).
pub const PARAM1: u32 = 1 << 3;
/// Mask bit of `command`.
pub const COMMAND: u32 = 1 << 7;
/// Mask bit of `frame`.
pub const FRAME: u32 = 1 << 8;
/// Mask bit of `current`.
pub const CURRENT: u32 = 1 << 9;
/// Mask bit of `autocontinue`.
pub const AUTOCONTINUE: u32 = 1 << 10;
const KNOWN: u32 = (AUTOCONTINUE << 1) - 1;

/// Data bytes one frame carries at most (the message's array).
pub const MAX_DATA: usize = 200;

/// Why a frame's items could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PackError {
    /// The data ends inside an item.
    #[error("packed items end inside item {0}")]
    Truncated(u8),
    /// A varint longer than its field.
    #[error("varint too long in item {0}")]
    Overflow(u8),
    /// A field mask with bits that name no field.
    #[error("unknown field bits {bits:#x} in item {item}")]
    UnknownFields {
        /// The item (0 = the frame's first).
        item: u8,
        /// The bits no field has.
        bits: u32,
    },
    /// The frame claims no item, or items past the plan's end.
    #[error("items {seq}..{seq}+{items} outside a plan of {count}")]
    Range {
        /// First item.
        seq: u16,
        /// Items claimed.
        items: u8,
        /// The plan's size.
        count: u16,
    },
    /// A field value the dialect refuses (an unknown `MAV_CMD` or `MAV_FRAME`).
    #[error("item {0} is not a valid MISSION_ITEM_INT")]
    Invalid(u8),
}

fn put_varint(out: &mut Vec<u8>, mut v: u32) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn zigzag(d: i32) -> u32 {
    ((d << 1) ^ (d >> 31)) as u32
}

fn unzigzag(v: u32) -> i32 {
    ((v >> 1) as i32) ^ -((v & 1) as i32)
}

fn float_delta(a: f32, base: f32) -> u32 {
    (a.to_bits() ^ base.to_bits()).reverse_bits()
}

fn params(i: &MISSION_ITEM_INT_DATA) -> [f32; 4] {
    [i.param1, i.param2, i.param3, i.param4]
}

/// Appends `item` stored against `base` to `out`.
fn encode_item(out: &mut Vec<u8>, item: &MISSION_ITEM_INT_DATA, base: &MISSION_ITEM_INT_DATA) {
    let mut mask = 0;
    mask |= X * u32::from(item.x != base.x);
    mask |= Y * u32::from(item.y != base.y);
    mask |= Z * u32::from(item.z.to_bits() != base.z.to_bits());
    for (k, (p, b)) in params(item).iter().zip(params(base)).enumerate() {
        mask |= (PARAM1 << k) * u32::from(p.to_bits() != b.to_bits());
    }
    mask |= COMMAND * u32::from(item.command as u16 != base.command as u16);
    mask |= FRAME * u32::from(item.frame as u8 != base.frame as u8);
    mask |= CURRENT * u32::from(item.current != base.current);
    mask |= AUTOCONTINUE * u32::from(item.autocontinue != base.autocontinue);
    put_varint(out, mask);
    if mask & X != 0 {
        put_varint(out, zigzag(item.x.wrapping_sub(base.x)));
    }
    if mask & Y != 0 {
        put_varint(out, zigzag(item.y.wrapping_sub(base.y)));
    }
    if mask & Z != 0 {
        put_varint(out, float_delta(item.z, base.z));
    }
    for (k, (p, b)) in params(item).iter().zip(params(base)).enumerate() {
        if mask & (PARAM1 << k) != 0 {
            put_varint(out, float_delta(*p, b));
        }
    }
    if mask & COMMAND != 0 {
        let d = i32::from(item.command as u16) - i32::from(base.command as u16);
        put_varint(out, zigzag(d));
    }
    if mask & FRAME != 0 {
        out.push(item.frame as u8);
    }
    if mask & CURRENT != 0 {
        out.push(item.current);
    }
    if mask & AUTOCONTINUE != 0 {
        out.push(item.autocontinue);
    }
}

/// Packs the leading items of `items` (consecutive sequence numbers) into at most `cap` bytes
/// (at most [`MAX_DATA`] and 255 items): how many went in, and the bytes. At least one item
/// goes in whenever `items` is not empty (one item needs at most 43 bytes).
pub fn pack(items: &[MISSION_ITEM_INT_DATA], cap: usize) -> (usize, Vec<u8>) {
    let cap = cap.clamp(43, MAX_DATA);
    let mut out = Vec::with_capacity(cap);
    let mut base = MISSION_ITEM_INT_DATA::default();
    let mut n = 0;
    for item in items.iter().take(usize::from(u8::MAX)) {
        let before = out.len();
        encode_item(&mut out, item, &base);
        if out.len() > cap {
            out.truncate(before);
            break;
        }
        n += 1;
        base = item.clone();
    }
    (n, out)
}

/// The frames that carry `items` (consecutive sequence numbers) of the plan `id` of `count`
/// items, addressed to `vehicle`, each with at most `cap` data bytes.
// `..Default::default()` on a full literal: the dialect may grow.
#[allow(clippy::needless_update)]
pub fn frames(
    id: u32,
    count: u16,
    vehicle: (u8, u8),
    mission_type: MavMissionType,
    mut items: &[MISSION_ITEM_INT_DATA],
    cap: usize,
) -> Vec<MavMessage> {
    let mut out = Vec::new();
    while let Some(first) = items.first() {
        let (n, bytes) = pack(items, cap);
        let mut data = [0u8; MAX_DATA];
        data[..bytes.len()].copy_from_slice(&bytes);
        out.push(MavMessage::MAVLORA_MISSION_ITEMS(
            MAVLORA_MISSION_ITEMS_DATA {
                opaque_id: id,
                count,
                seq: first.seq,
                target_system: vehicle.0,
                target_component: vehicle.1,
                mission_type,
                items: n as u8,
                data,
                ..Default::default()
            },
        ));
        items = &items[n..];
    }
    out
}

/// The router's status poll: a frame of the transfer with no item (see [`super::relay`]: the
/// bridge answers with what it misses, "busy" or its ack). Once the router holds the whole
/// plan it names the plan too (`plan`: the CRC's low 24 bits, as [`super::plan::plan_part`]),
/// in the first data bytes: the transfer's count left before the ground had sent every item,
/// so its id cannot carry the CRC the bridge checks the assembled plan against.
// `..Default::default()` on a full literal: the dialect may grow.
#[allow(clippy::needless_update)]
pub fn poll(
    id: u32,
    count: u16,
    vehicle: (u8, u8),
    mission_type: MavMissionType,
    plan: Option<u32>,
) -> MavMessage {
    let mut data = [0u8; MAX_DATA];
    if let Some(plan) = plan {
        data[..4].copy_from_slice(&(PLAN_NAMED | (plan & 0x00FF_FFFF)).to_le_bytes());
    }
    MavMessage::MAVLORA_MISSION_ITEMS(MAVLORA_MISSION_ITEMS_DATA {
        opaque_id: id,
        count,
        target_system: vehicle.0,
        target_component: vehicle.1,
        mission_type,
        data,
        ..Default::default()
    })
}

/// Marks a poll's data as naming the plan (a poll without it has all-zero data).
const PLAN_NAMED: u32 = 1 << 24;

/// The plan a poll names (the CRC's low 24 bits), if it names one.
pub fn poll_plan(p: &MAVLORA_MISSION_ITEMS_DATA) -> Option<u32> {
    let word = u32::from_le_bytes([p.data[0], p.data[1], p.data[2], p.data[3]]);
    (p.items == 0 && word & !0x00FF_FFFF == PLAN_NAMED).then_some(word & 0x00FF_FFFF)
}

/// Bytes `items` take as standard frames: one unsigned MAVLink 2 `MISSION_ITEM_INT` each
/// (trailing zeros trimmed), what a ground station sends and a transparent radio carries.
pub fn standard_bytes(items: &[MISSION_ITEM_INT_DATA]) -> usize {
    items
        .iter()
        .map(|i| {
            let msg = MavMessage::MISSION_ITEM_INT(i.clone());
            crate::wire::encode(MavlinkVersion::V2, mavlink::MavHeader::default(), &msg)
                .as_bytes()
                .len()
        })
        .sum()
}

/// The sequence numbers a frame carries.
pub fn span(p: &MAVLORA_MISSION_ITEMS_DATA) -> std::ops::Range<u32> {
    u32::from(p.seq)..u32::from(p.seq) + u32::from(p.items)
}

struct Reader<'a> {
    data: &'a [u8],
    at: usize,
    item: u8,
}

impl Reader<'_> {
    fn byte(&mut self) -> Result<u8, PackError> {
        let b = *self
            .data
            .get(self.at)
            .ok_or(PackError::Truncated(self.item))?;
        self.at += 1;
        Ok(b)
    }

    fn varint(&mut self) -> Result<u32, PackError> {
        let mut v: u32 = 0;
        for shift in (0..35).step_by(7) {
            let b = self.byte()?;
            let bits = u32::from(b & 0x7F);
            if shift == 28 && bits > 0x0F {
                return Err(PackError::Overflow(self.item));
            }
            v |= bits << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(PackError::Overflow(self.item))
    }
}

/// The items of a frame, in order, addressed as the frame is.
pub fn unpack(p: &MAVLORA_MISSION_ITEMS_DATA) -> Result<Vec<MISSION_ITEM_INT_DATA>, PackError> {
    if p.items == 0 || u32::from(p.seq) + u32::from(p.items) > u32::from(p.count) {
        return Err(PackError::Range {
            seq: p.seq,
            items: p.items,
            count: p.count,
        });
    }
    let mut r = Reader {
        data: &p.data,
        at: 0,
        item: 0,
    };
    let mut base = MISSION_ITEM_INT_DATA::default();
    let mut out = Vec::with_capacity(usize::from(p.items));
    for k in 0..p.items {
        r.item = k;
        let mask = r.varint()?;
        if mask & !KNOWN != 0 {
            return Err(PackError::UnknownFields {
                item: k,
                bits: mask & !KNOWN,
            });
        }
        let mut x = base.x;
        let mut y = base.y;
        let mut z = base.z.to_bits();
        let mut ps = params(&base).map(f32::to_bits);
        let mut command = base.command as u16;
        let mut frame = base.frame as u8;
        let mut current = base.current;
        let mut autocontinue = base.autocontinue;
        if mask & X != 0 {
            x = x.wrapping_add(unzigzag(r.varint()?));
        }
        if mask & Y != 0 {
            y = y.wrapping_add(unzigzag(r.varint()?));
        }
        if mask & Z != 0 {
            z ^= r.varint()?.reverse_bits();
        }
        for (k, p) in ps.iter_mut().enumerate() {
            if mask & (PARAM1 << k) != 0 {
                *p ^= r.varint()?.reverse_bits();
            }
        }
        if mask & COMMAND != 0 {
            let c = i32::from(command) + unzigzag(r.varint()?);
            command = u16::try_from(c).map_err(|_| PackError::Invalid(k))?;
        }
        if mask & FRAME != 0 {
            frame = r.byte()?;
        }
        if mask & CURRENT != 0 {
            current = r.byte()?;
        }
        if mask & AUTOCONTINUE != 0 {
            autocontinue = r.byte()?;
        }
        // The standard payload, parsed by the dialect (its enum checks included).
        let mut raw = Vec::with_capacity(38);
        for v in ps {
            raw.extend_from_slice(&v.to_le_bytes());
        }
        raw.extend_from_slice(&x.to_le_bytes());
        raw.extend_from_slice(&y.to_le_bytes());
        raw.extend_from_slice(&z.to_le_bytes());
        raw.extend_from_slice(&(p.seq + u16::from(k)).to_le_bytes());
        raw.extend_from_slice(&command.to_le_bytes());
        raw.extend_from_slice(&[
            p.target_system,
            p.target_component,
            frame,
            current,
            autocontinue,
            p.mission_type as u8,
        ]);
        let item = MISSION_ITEM_INT_DATA::deser(MavlinkVersion::V2, &raw)
            .map_err(|_| PackError::Invalid(k))?;
        base = item.clone();
        out.push(item);
    }
    Ok(out)
}

#[cfg(test)]
#[path = "pack_tests.rs"]
mod tests;
