//! Consecutive `PARAM_VALUE`s of one component packed into one `MAVLORA_PARAM_VALUES` frame
//! (the dialect's description is the format).
//!
//! A `PARAM_VALUE` takes 50 bytes on a signed radio (12 of framing and checksum, a 25-byte
//! payload, 13 of signature) and a ground station loading a list waits on every one: 1,396
//! of them (ArduCopter 4.6) are ~70 kB, 24 s of a SiK radio's budget, 280 s of a LoRa SF7's.
//! Neighbours in a list share most of their name (`ATC_RAT_PIT_D`, `ATC_RAT_PIT_FF`; PX4 sends
//! them sorted), most values are 0 or a short float (`1.0` is `00 00 80 3F`), and the count
//! and the next index are known: each value is stored as what its name adds to the one before
//! it, its type, only the value bytes that are not zero at one end, and its index only when
//! it skips. ArduCopter's list packs to ~11 bytes a value.
//!
//! Exact for every value: the name's 16 bytes (the name is `param_id` without its trailing
//! zeros, so whatever follows a terminating zero inside it comes back too), the value's four
//! payload bytes as sent (a float, a NaN with any payload, PX4's byte-wise integers), the
//! type, the count and the index. [`ParamValue`] is the payload itself, never a decoded
//! float: nothing here does float arithmetic on a value.
//!
//! A frame needs nothing from any other: a lost one is read again by index, the standard way.

use crate::dialect::MAVLORA_PARAM_VALUES_DATA;

/// Bytes of a `PARAM_VALUE` payload: value (4), count (2), index (2), name (16), type (1).
pub const PAYLOAD_LEN: usize = 25;

/// Data bytes one frame carries at most (the message's array).
pub const MAX_DATA: usize = 200;

/// Bytes one value takes at most: two header bytes, a 16-character name, four value bytes
/// and an index step (a varint of at most three bytes).
pub const MAX_VALUE_BYTES: usize = 2 + 16 + 4 + 3;

/// Bytes the smallest value takes: two header bytes and one new character.
pub const MIN_VALUE_BYTES: usize = 3;

/// Highest type a frame can carry (4 bits); values of other types go as `PARAM_VALUE`.
pub const MAX_TYPE: u8 = 15;

/// One `PARAM_VALUE` as its payload says it: every byte, nothing decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ParamValue {
    /// The value's four payload bytes (little endian), as sent.
    pub value: [u8; 4],
    /// `param_count`.
    pub count: u16,
    /// `param_index`.
    pub index: u16,
    /// `param_id`, all 16 bytes.
    pub name: [u8; 16],
    /// `param_type`, as sent (any byte).
    pub param_type: u8,
}

impl ParamValue {
    /// The value a `PARAM_VALUE` payload holds (MAVLink 2 trims trailing zeros: a shorter
    /// payload is zero-padded); `None` for a payload longer than the message's 25 bytes (its
    /// extra bytes could not be given back).
    pub fn from_payload(payload: &[u8]) -> Option<Self> {
        if payload.len() > PAYLOAD_LEN {
            return None;
        }
        let mut p = [0u8; PAYLOAD_LEN];
        p[..payload.len()].copy_from_slice(payload);
        let mut name = [0u8; 16];
        name.copy_from_slice(&p[8..24]);
        Some(Self {
            value: [p[0], p[1], p[2], p[3]],
            count: u16::from_le_bytes([p[4], p[5]]),
            index: u16::from_le_bytes([p[6], p[7]]),
            name,
            param_type: p[24],
        })
    }

    /// The full 25-byte payload (MAVLink 2 trims its trailing zeros on the wire).
    pub fn payload(&self) -> [u8; PAYLOAD_LEN] {
        let mut p = [0u8; PAYLOAD_LEN];
        p[..4].copy_from_slice(&self.value);
        p[4..6].copy_from_slice(&self.count.to_le_bytes());
        p[6..8].copy_from_slice(&self.index.to_le_bytes());
        p[8..24].copy_from_slice(&self.name);
        p[24] = self.param_type;
        p
    }

    /// The name's length without its trailing zero bytes.
    pub fn name_len(&self) -> usize {
        self.name.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1)
    }

    /// Whether a frame can carry it: a name that is not all zero, a type of at most
    /// [`MAX_TYPE`].
    pub fn packable(&self) -> bool {
        self.name_len() > 0 && self.param_type <= MAX_TYPE
    }
}

/// Why a frame's values could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParamPackError {
    /// The frame claims no value.
    #[error("a frame of no value")]
    Empty,
    /// The data ends inside a value.
    #[error("the data ends inside value {0}")]
    Truncated(u8),
    /// A name that keeps more of the previous name than there is (or anything, on the first
    /// value), is longer than 16 bytes, or ends with a zero byte.
    #[error("value {0} has a malformed name")]
    Name(u8),
    /// An index step on the first value, or an index past 65535.
    #[error("value {0} has a malformed index")]
    Index(u8),
    /// A varint longer than an index step can be.
    #[error("varint too long in value {0}")]
    Overflow(u8),
    /// Non-zero bytes after the last value.
    #[error("non-zero bytes after the last value")]
    Trailing,
}

fn put_varint(out: &mut Vec<u8>, mut v: u32) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// The shortest way to store `value`: (form, the bytes stored).
fn value_form(value: [u8; 4]) -> (u8, &'static [usize]) {
    const HIGH: [&[usize]; 4] = [&[3], &[2, 3], &[1, 2, 3], &[0, 1, 2, 3]];
    const LOW: [&[usize]; 3] = [&[0], &[0, 1], &[0, 1, 2]];
    let v = u32::from_le_bytes(value);
    if v == 0 {
        return (0, &[]);
    }
    let low_zeros = (v.trailing_zeros() / 8) as usize; // low bytes that are zero
    let high_zeros = (v.leading_zeros() / 8) as usize; // high bytes that are zero
    let high_kept = 4 - low_zeros; // 1..=4 bytes from the top
    let low_kept = 4 - high_zeros; // 1..=4 bytes from the bottom
    if high_kept <= low_kept || low_kept == 4 {
        let k = high_kept;
        (k as u8, HIGH[k - 1])
    } else {
        (4 + low_kept as u8, LOW[low_kept - 1])
    }
}

/// Appends `v`, stored against the previous value of the frame (`None`: it is the first), to
/// `out`. `v` must be [`ParamValue::packable`] and, after a previous value, of a higher index.
fn encode_value(out: &mut Vec<u8>, v: &ParamValue, prev: Option<&ParamValue>) {
    let len = v.name_len();
    let keep = match prev {
        None => 0,
        Some(p) => {
            let max = (len - 1).min(p.name_len()).min(15);
            v.name[..max]
                .iter()
                .zip(&p.name[..max])
                .take_while(|(a, b)| a == b)
                .count()
        }
    };
    let new = len - keep;
    out.push(keep as u8 | (((new - 1) as u8) << 4));
    out.extend_from_slice(&v.name[keep..len]);
    let (form, bytes) = value_form(v.value);
    let step = prev.map_or(1, |p| u32::from(v.index) - u32::from(p.index));
    let skips = step != 1;
    out.push(v.param_type | (form << 4) | (u8::from(skips) << 7));
    out.extend(bytes.iter().map(|&i| v.value[i]));
    if skips {
        put_varint(out, step - 2);
    }
}

/// Whether `v` may follow `prev` in one frame: the same count, a higher index.
fn continues(prev: &ParamValue, v: &ParamValue) -> bool {
    v.count == prev.count && v.index > prev.index
}

/// Packs the leading values of `values` into at most `cap` data bytes (clamped to
/// [`MAX_VALUE_BYTES`]..=[`MAX_DATA`], at most 255 values): how many went in, and the bytes.
/// A run ends at a value that is not [`packable`](ParamValue::packable), that has another
/// count, or whose index is not above the one before; the first value goes in whenever it is
/// packable (0 values otherwise).
pub fn pack<'a>(values: impl IntoIterator<Item = &'a ParamValue>, cap: usize) -> (usize, Vec<u8>) {
    let cap = cap.clamp(MAX_VALUE_BYTES, MAX_DATA);
    let mut out = Vec::with_capacity(cap);
    let mut prev: Option<&ParamValue> = None;
    let mut n = 0;
    for v in values.into_iter().take(usize::from(u8::MAX)) {
        if !v.packable() || prev.is_some_and(|p| !continues(p, v)) {
            break;
        }
        let before = out.len();
        encode_value(&mut out, v, prev);
        if out.len() > cap {
            out.truncate(before);
            break;
        }
        n += 1;
        prev = Some(v);
    }
    (n, out)
}

/// The frame carrying `values`, which [`pack`] packed whole (from `component`).
// `..Default::default()` on a full literal: the dialect may grow.
#[allow(clippy::needless_update)]
pub fn frame(component: u8, values: &[ParamValue], data: &[u8]) -> MAVLORA_PARAM_VALUES_DATA {
    let mut d = [0u8; MAX_DATA];
    d[..data.len()].copy_from_slice(data);
    MAVLORA_PARAM_VALUES_DATA {
        param_count: values.first().map_or(0, |v| v.count),
        param_index: values.first().map_or(0, |v| v.index),
        component,
        values: values.len() as u8,
        data: d,
        ..Default::default()
    }
}

struct Reader<'a> {
    data: &'a [u8],
    at: usize,
    value: u8,
}

impl Reader<'_> {
    fn byte(&mut self) -> Result<u8, ParamPackError> {
        let b = *self
            .data
            .get(self.at)
            .ok_or(ParamPackError::Truncated(self.value))?;
        self.at += 1;
        Ok(b)
    }

    /// An index step's varint: at most three bytes, below 2^16.
    fn step(&mut self) -> Result<u32, ParamPackError> {
        let mut v: u32 = 0;
        for shift in [0, 7, 14] {
            let b = self.byte()?;
            v |= u32::from(b & 0x7F) << shift;
            if b & 0x80 == 0 {
                return if v <= u32::from(u16::MAX) {
                    Ok(v)
                } else {
                    Err(ParamPackError::Overflow(self.value))
                };
            }
        }
        Err(ParamPackError::Overflow(self.value))
    }
}

/// The values of a frame, in order; anything malformed refuses the whole frame.
pub fn unpack(p: &MAVLORA_PARAM_VALUES_DATA) -> Result<Vec<ParamValue>, ParamPackError> {
    if p.values == 0 {
        return Err(ParamPackError::Empty);
    }
    let mut r = Reader {
        data: &p.data,
        at: 0,
        value: 0,
    };
    let mut out: Vec<ParamValue> = Vec::with_capacity(usize::from(p.values));
    for k in 0..p.values {
        r.value = k;
        let prev = out.last();
        let lens = r.byte()?;
        let keep = usize::from(lens & 0x0F);
        let new = usize::from(lens >> 4) + 1;
        let prev_len = prev.map_or(0, ParamValue::name_len);
        if keep > prev_len || keep + new > 16 {
            return Err(ParamPackError::Name(k));
        }
        let mut name = [0u8; 16];
        if let Some(prev) = prev {
            name[..keep].copy_from_slice(&prev.name[..keep]);
        }
        for c in &mut name[keep..keep + new] {
            *c = r.byte()?;
        }
        // The name was stored without its trailing zeros.
        if name[keep + new - 1] == 0 {
            return Err(ParamPackError::Name(k));
        }
        let kind = r.byte()?;
        let param_type = kind & 0x0F;
        let form = (kind >> 4) & 0x07;
        let skips = kind & 0x80 != 0;
        let mut value = [0u8; 4];
        let stored: &[usize] = match form {
            0 => &[],
            1 => &[3],
            2 => &[2, 3],
            3 => &[1, 2, 3],
            4 => &[0, 1, 2, 3],
            5 => &[0],
            6 => &[0, 1],
            _ => &[0, 1, 2],
        };
        for &i in stored {
            value[i] = r.byte()?;
        }
        let index = match prev {
            None if skips => return Err(ParamPackError::Index(k)),
            None => u32::from(p.param_index),
            Some(prev) => {
                let step = if skips { r.step()? + 2 } else { 1 };
                u32::from(prev.index) + step
            }
        };
        let index = u16::try_from(index).map_err(|_| ParamPackError::Index(k))?;
        out.push(ParamValue {
            value,
            count: p.param_count,
            index,
            name,
            param_type,
        });
    }
    if p.data[r.at..].iter().any(|&b| b != 0) {
        return Err(ParamPackError::Trailing);
    }
    Ok(out)
}

#[cfg(test)]
#[path = "pack_tests.rs"]
mod tests;
