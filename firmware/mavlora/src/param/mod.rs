//! Parameter lists over a slow radio: the bridge packs the `PARAM_VALUE`s an autopilot streams
//! into `MAVLORA_PARAM_VALUES` frames (id 13, [`pack`]: ~11 bytes a value instead of 50), the
//! router gives the ground stations back the standard `PARAM_VALUE`s, byte for byte what the
//! autopilot sent, as the autopilot.
//!
//! - [`ParamPacker`] (bridge): the backlog, frames as full as the budget allows
//!   ([`ParamPackConfig::for_rate`]).
//! - [`pack`]: the format, [`pack::pack`] and [`pack::unpack`].
//! - [`param_value_frame`] (router): one standard frame from a value's bytes.
//! - [`ReadGate`] (router): a ground's reads of values the list in flight is about to bring,
//!   and its repeats of a read in flight, wait at the router instead of crowding the radio.
//! - [`ParamCache`] (router): a list asked for again is given from the ground side once the
//!   vehicle's own hash (PX4's `_HASH_CHECK`) says its parameters are those cached.
//!
//! What stays standard: a lost frame is read again by index (`PARAM_REQUEST_READ`), and the
//! autopilot's answers to a ground's own `PARAM_SET` or `PARAM_REQUEST_READ` go raw, ahead of
//! the list (the bridge's `param_answers`; answers to reads within a quarter of the budget,
//! so that a ground reading many cannot starve position).

pub mod cache;
pub mod pack;
mod packer;
mod reads;

pub use cache::{CacheRadio, HASH_CHECK_NAME, ParamCache, ParamCacheStats};
pub use pack::{ParamPackError, ParamValue};
pub use packer::{
    BACKLOG, FRAME_OVERHEAD, FRAME_PERIOD, ParamPackConfig, ParamPackStats, ParamPacker,
};
pub use reads::{LIST_QUIET, REPEAT_HOLD_MAX, REPEAT_HOLD_MIN, ReadGate, ReadGateStats};

use mavlink::MessageData;

use crate::dialect::PARAM_VALUE_DATA;
use crate::wire::{OwnedFrame, STX_V2};

/// A MAVLink 2 `PARAM_VALUE` frame from (`system`, `component`) with sequence `sequence`
/// holding `value`'s payload byte for byte (trailing zeros trimmed, as MAVLink 2 sends it),
/// built without decoding it: its value bits are never a float here.
pub fn param_value_frame(
    system: u8,
    component: u8,
    sequence: u8,
    value: &ParamValue,
) -> OwnedFrame {
    let payload = value.payload();
    // MAVLink 2 trims trailing zeros but always keeps the first byte.
    let len = payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
    let id = PARAM_VALUE_DATA::ID.to_le_bytes();
    let mut bytes = Vec::with_capacity(10 + len + 2);
    bytes.extend_from_slice(&[STX_V2, len as u8, 0, 0, sequence, system, component]);
    bytes.extend_from_slice(&id[..3]);
    bytes.extend_from_slice(&payload[..len]);
    let crc = mavlink::calculate_crc(&bytes[1..], PARAM_VALUE_DATA::EXTRA_CRC);
    bytes.extend_from_slice(&crc.to_le_bytes());
    OwnedFrame::new_unchecked(bytes)
}
