//! The packed `data` of `MAVLORA_COMPACT` (layout in the message's description in
//! `mavlora.xml`): [`CompactFrame`] ⇄ bytes. Exact: what [`CompactFrame::decode`] returns is
//! what was encoded, but for sample times (rounded to 10 ms from sample 0) and altitudes
//! (decimetres), which the compactor rounds before it encodes.
//!
//! Each section is optional, and each field of the status costs only the bytes its value
//! needs (varints), so a frame pays for what it carries: on a signed radio the 25 bytes of
//! framing and signature are the largest part of a one-second frame.

use crate::dialect::{LINK_QUALITY_DATA, MAVLORA_COMPACT_DATA};

/// Bytes of `data`.
pub const DATA_LEN: usize = 250;

/// Most position samples one frame carries (the count is 4 bits; ten keeps the worst case of
/// every section within [`DATA_LEN`]).
pub const MAX_SAMPLES: usize = 10;

const SAMPLES_MASK: u8 = 0x0F;
const HAS_STATUS: u8 = 1 << 4;
const HAS_LINK: u8 = 1 << 5;
const HAS_ALT_CHANGES: u8 = 1 << 6;
const HAS_AIR: u8 = 1 << 7;

const PART_HEARTBEAT: u8 = 1 << 0;
const PART_SYS: u8 = 1 << 1;
const PART_GPS: u8 = 1 << 2;
const PART_MISSION: u8 = 1 << 3;

/// One position sample, as the frame carries it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Sample {
    /// The autopilot's time, ms (sample 0 exact; later samples at 10 ms steps from it).
    pub time_boot_ms: u32,
    /// Latitude, degE7.
    pub lat: i32,
    /// Longitude, degE7.
    pub lon: i32,
    /// Altitude above home, dm.
    pub rel_dm: i32,
}

/// The position section: samples, oldest first, and what is said of the newest.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Positions {
    /// 1..=[`MAX_SAMPLES`] samples, in time order.
    pub samples: Vec<Sample>,
    /// Altitude above mean sea level minus altitude above home, dm.
    pub alt_offset_dm: i32,
    /// Velocity north, cm/s (newest sample).
    pub vx: i16,
    /// Velocity east, cm/s.
    pub vy: i16,
    /// Velocity down, cm/s.
    pub vz: i16,
    /// Heading, cdeg (`u16::MAX` unknown).
    pub hdg: u16,
    /// What the autopilot's VFR_HUD says that positions do not, if it sends one.
    pub air: Option<AirPart>,
}

/// What the autopilot's VFR_HUD says beyond its position and velocity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AirPart {
    /// Airspeed, cm/s.
    pub airspeed_cms: i32,
    /// Throttle, %.
    pub throttle: u16,
}

/// What the autopilot's HEARTBEAT says (enum values as their numbers).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct HeartbeatPart {
    /// `MAV_TYPE`.
    pub mavtype: u8,
    /// `MAV_AUTOPILOT`.
    pub autopilot: u8,
    /// `MAV_MODE_FLAG` bits.
    pub base_mode: u8,
    /// Autopilot-specific mode.
    pub custom_mode: u32,
    /// `MAV_STATE`.
    pub system_status: u8,
}

/// What the autopilot's SYS_STATUS says that a ground station shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SysPart {
    /// `MAV_SYS_STATUS_SENSOR` bits present.
    pub sensors_present: u32,
    /// Enabled.
    pub sensors_enabled: u32,
    /// Healthy.
    pub sensors_health: u32,
    /// Battery voltage, mV (`u16::MAX` unknown).
    pub voltage_battery: u16,
    /// Battery current, cA (-1 unknown).
    pub current_battery: i16,
    /// Battery remaining, % (-1 unknown).
    pub battery_remaining: i8,
    /// Main loop load, d%.
    pub load: u16,
}

/// What the autopilot's GPS_RAW_INT says of the fix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GpsPart {
    /// `GPS_FIX_TYPE`.
    pub fix_type: u8,
    /// Satellites visible (`u8::MAX` unknown).
    pub satellites_visible: u8,
    /// Horizontal dilution (`u16::MAX` unknown).
    pub eph: u16,
    /// Vertical dilution (`u16::MAX` unknown).
    pub epv: u16,
}

/// What the autopilot's MISSION_CURRENT says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MissionPart {
    /// Current item.
    pub seq: u16,
    /// Items in the mission (`u16::MAX` unknown).
    pub total: u16,
    /// `MISSION_STATE`.
    pub state: u8,
    /// Autopilot-specific mission mode (0 unknown).
    pub mode: u8,
}

/// The status section: each part only if the autopilot sent that message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Status {
    /// From HEARTBEAT.
    pub heartbeat: Option<HeartbeatPart>,
    /// From SYS_STATUS.
    pub sys: Option<SysPart>,
    /// From GPS_RAW_INT.
    pub gps: Option<GpsPart>,
    /// From MISSION_CURRENT.
    pub mission: Option<MissionPart>,
}

/// One `MAVLORA_COMPACT`, decoded.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CompactFrame {
    /// Position samples.
    pub positions: Option<Positions>,
    /// The vehicle's status.
    pub status: Option<Status>,
    /// The bridge's link-quality report.
    pub link: Option<LINK_QUALITY_DATA>,
}

/// Why a `data` field could not be decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// A field runs past the end of `data`.
    #[error("truncated")]
    Truncated,
    /// A count or value out of its range.
    #[error("value out of range")]
    Range,
}

/// Why a frame could not be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// More than [`MAX_SAMPLES`] samples, or none in a position section.
    #[error("sample count out of range")]
    Samples,
    /// Sample times that go back.
    #[error("sample times go back")]
    Time,
    /// More than [`DATA_LEN`] bytes.
    #[error("does not fit")]
    TooLong,
}

impl CompactFrame {
    /// The frame's `data`.
    pub fn encode(&self) -> Result<MAVLORA_COMPACT_DATA, EncodeError> {
        let mut w = Writer::default();
        let mut flags = 0u8;
        if let Some(p) = &self.positions {
            let n = p.samples.len();
            if n == 0 || n > MAX_SAMPLES {
                return Err(EncodeError::Samples);
            }
            flags |= n as u8;
            if p.air.is_some() {
                flags |= HAS_AIR;
            }
            if p.samples.windows(2).any(|s| s[0].rel_dm != s[1].rel_dm) {
                flags |= HAS_ALT_CHANGES;
            }
        }
        if self.status.is_some() {
            flags |= HAS_STATUS;
        }
        if self.link.is_some() {
            flags |= HAS_LINK;
        }
        w.u8(flags);
        if let Some(p) = &self.positions {
            encode_positions(&mut w, p, flags & HAS_ALT_CHANGES != 0)?;
        }
        if let Some(s) = &self.status {
            encode_status(&mut w, s);
        }
        if let Some(l) = &self.link {
            w.varint(l.time_boot_ms.into());
            w.varint(l.rx_packets.into());
            w.varint(l.rx_lost.into());
            w.varint(l.rx_bad_crc.into());
            w.u8(l.rssi as u8);
            w.u8(l.remote_rssi as u8);
            w.u8(l.noise as u8);
        }
        if w.bytes.len() > DATA_LEN {
            return Err(EncodeError::TooLong);
        }
        let mut data = [0u8; DATA_LEN];
        data[..w.bytes.len()].copy_from_slice(&w.bytes);
        Ok(MAVLORA_COMPACT_DATA { data })
    }

    /// Bytes of `data` this frame uses (a frame on the wire carries them without the zeros
    /// that follow: MAVLink 2 trims a payload's trailing zeros).
    pub fn encoded_len(&self) -> Result<usize, EncodeError> {
        let data = self.encode()?;
        Ok(data.data.iter().rposition(|b| *b != 0).map_or(0, |i| i + 1))
    }

    /// A frame's `data`, decoded.
    pub fn decode(msg: &MAVLORA_COMPACT_DATA) -> Result<Self, DecodeError> {
        let mut r = Reader {
            bytes: &msg.data,
            at: 0,
        };
        let flags = r.u8()?;
        let n = usize::from(flags & SAMPLES_MASK);
        if n > MAX_SAMPLES {
            return Err(DecodeError::Range);
        }
        let positions = if n > 0 {
            Some(decode_positions(
                &mut r,
                n,
                flags & HAS_ALT_CHANGES != 0,
                flags & HAS_AIR != 0,
            )?)
        } else if flags & (HAS_ALT_CHANGES | HAS_AIR) != 0 {
            return Err(DecodeError::Range);
        } else {
            None
        };
        let status = if flags & HAS_STATUS != 0 {
            Some(decode_status(&mut r)?)
        } else {
            None
        };
        let link = if flags & HAS_LINK != 0 {
            Some(LINK_QUALITY_DATA {
                time_boot_ms: r.varint_u32()?,
                rx_packets: r.varint_u16()?,
                rx_lost: r.varint_u16()?,
                rx_bad_crc: r.varint_u16()?,
                rssi: r.u8()? as i8,
                remote_rssi: r.u8()? as i8,
                noise: r.u8()? as i8,
            })
        } else {
            None
        };
        Ok(Self {
            positions,
            status,
            link,
        })
    }
}

/// Sample times as 10 ms steps from sample 0, rounded.
fn steps(samples: &[Sample]) -> Vec<i64> {
    let t0 = samples[0].time_boot_ms;
    samples
        .iter()
        .map(|s| round_div(i64::from(s.time_boot_ms.wrapping_sub(t0)), 10))
        .collect()
}

/// The predicted latitude (or longitude) step of sample i from the step before it, scaled by
/// the ratio of the two time steps (`dt` in 10 ms, `prev_dt` the one before); wrapping.
fn predicted(prev_step: i32, dt: i64, prev_dt: i64) -> i32 {
    if prev_dt <= 0 {
        return 0;
    }
    round_div(i64::from(prev_step) * dt, prev_dt) as i32
}

/// cos(d°) for d = 0..=90, in 1/32768: the longitude guess's scale, exactly the same integers
/// at both ends (a platform's `cos` may differ in its last bit).
const COS_Q15: [i64; 91] = [
    32768, 32763, 32748, 32723, 32688, 32643, 32588, 32524, 32449, 32365, 32270, 32166, 32052,
    31928, 31795, 31651, 31499, 31336, 31164, 30983, 30792, 30592, 30382, 30163, 29935, 29698,
    29452, 29197, 28932, 28660, 28378, 28088, 27789, 27482, 27166, 26842, 26510, 26170, 25822,
    25466, 25102, 24730, 24351, 23965, 23571, 23170, 22763, 22348, 21926, 21498, 21063, 20622,
    20174, 19720, 19261, 18795, 18324, 17847, 17364, 16877, 16384, 15886, 15384, 14876, 14365,
    13848, 13328, 12803, 12275, 11743, 11207, 10668, 10126, 9580, 9032, 8481, 7927, 7371, 6813,
    6252, 5690, 5126, 4560, 3993, 3425, 2856, 2286, 1715, 1144, 572, 0,
];

/// Where the velocity says sample 1 is, from sample 0 at `lat` moving at `vx`, `vy` (cm/s,
/// north and east) for `dt` (10 ms): (latitude, longitude) steps in degE7. A guess, so its
/// integer arithmetic need only be the same at both ends: 1 m is 89.83 degE7 of latitude
/// (8983 / 100), of longitude that over cos(latitude) (linear between whole degrees, at least
/// cos 89°); a step over 60 s is taken as 60 s.
fn velocity_guess(lat: i32, vx: i16, vy: i16, dt: i64) -> (i32, i32) {
    // Within a batch a step is at most a minute; any longer (a frame made up of noise) is
    // guessed as a minute, which keeps the products inside 64 bits.
    let dt = dt.clamp(0, 6_000);
    let north = round_div(i64::from(vx) * dt * 8983, 1_000_000);
    let abs = i64::from(lat).unsigned_abs().min(900_000_000) as i64;
    let (deg, frac) = ((abs / 10_000_000) as usize, abs % 10_000_000);
    let next = COS_Q15[(deg + 1).min(90)];
    let cos = (COS_Q15[deg] + round_div((next - COS_Q15[deg]) * frac, 10_000_000)).max(572);
    let east = round_div(i64::from(vy) * dt * 8983 * 32768, 1_000_000 * cos);
    (north as i32, east as i32)
}

fn encode_positions(w: &mut Writer, p: &Positions, alt_changes: bool) -> Result<(), EncodeError> {
    let first = p.samples[0];
    let t = steps(&p.samples);
    if t.windows(2).any(|d| d[1] < d[0]) || t.iter().any(|s| *s > i64::from(u32::MAX / 10)) {
        return Err(EncodeError::Time);
    }
    w.u32(first.time_boot_ms);
    w.u32(first.lat as u32);
    w.u32(first.lon as u32);
    w.zvarint(first.rel_dm.into());
    w.zvarint(p.alt_offset_dm.into());
    w.zvarint(p.vx.into());
    w.zvarint(p.vy.into());
    w.zvarint(p.vz.into());
    w.u16(p.hdg);
    if let Some(a) = p.air {
        w.zvarint(a.airspeed_cms.into());
        w.varint(a.throttle.into());
    }
    for i in 1..p.samples.len() {
        let (s, prev) = (p.samples[i], p.samples[i - 1]);
        let dt = t[i] - t[i - 1];
        w.varint(dt as u64);
        let older = (i >= 2).then(|| (p.samples[i - 2], t[i - 1] - t[i - 2]));
        let by_velocity = velocity_guess(first.lat, p.vx, p.vy, dt);
        for (now, before, older, first_guess) in [
            (
                s.lat,
                prev.lat,
                older.map(|(o, prev_dt)| (o.lat, prev_dt)),
                by_velocity.0,
            ),
            (
                s.lon,
                prev.lon,
                older.map(|(o, prev_dt)| (o.lon, prev_dt)),
                by_velocity.1,
            ),
        ] {
            let step = now.wrapping_sub(before);
            let guess = older.map_or(first_guess, |(o, prev_dt)| {
                predicted(before.wrapping_sub(o), dt, prev_dt)
            });
            w.zvarint(step.wrapping_sub(guess).into());
        }
        if alt_changes {
            w.zvarint(i64::from(s.rel_dm) - i64::from(prev.rel_dm));
        }
    }
    Ok(())
}

fn decode_positions(
    r: &mut Reader,
    n: usize,
    alt_changes: bool,
    air: bool,
) -> Result<Positions, DecodeError> {
    let time_boot_ms = r.u32()?;
    let lat = r.u32()? as i32;
    let lon = r.u32()? as i32;
    let rel_dm = r.zvarint_i32()?;
    let alt_offset_dm = r.zvarint_i32()?;
    let vx = r.zvarint_i16()?;
    let vy = r.zvarint_i16()?;
    let vz = r.zvarint_i16()?;
    let hdg = r.u16()?;
    let air = if air {
        Some(AirPart {
            airspeed_cms: r.zvarint_i32()?,
            throttle: r.varint_u16()?,
        })
    } else {
        None
    };
    let mut samples = Vec::with_capacity(n);
    samples.push(Sample {
        time_boot_ms,
        lat,
        lon,
        rel_dm,
    });
    let mut t: Vec<i64> = vec![0];
    for i in 1..n {
        let dt = i64::from(r.varint_u32()?);
        let ti = t[i - 1] + dt;
        if ti > i64::from(u32::MAX) / 10 {
            return Err(DecodeError::Range);
        }
        t.push(ti);
        let prev = samples[i - 1];
        let older = (i >= 2).then(|| samples[i - 2]);
        let prev_dt = if i >= 2 { t[i - 1] - t[i - 2] } else { 0 };
        let by_velocity = velocity_guess(lat, vx, vy, dt);
        let mut next = |before: i32, older: Option<i32>, first_guess: i32| {
            let residual = r.zvarint_i32_wrapping()?;
            let guess = older.map_or(first_guess, |o| {
                predicted(before.wrapping_sub(o), dt, prev_dt)
            });
            Ok::<i32, DecodeError>(before.wrapping_add(guess).wrapping_add(residual))
        };
        let lat = next(prev.lat, older.map(|o| o.lat), by_velocity.0)?;
        let lon = next(prev.lon, older.map(|o| o.lon), by_velocity.1)?;
        let rel_dm = if alt_changes {
            i32::try_from(i64::from(prev.rel_dm) + r.zvarint()?).map_err(|_| DecodeError::Range)?
        } else {
            prev.rel_dm
        };
        samples.push(Sample {
            time_boot_ms: time_boot_ms.wrapping_add((ti * 10) as u32),
            lat,
            lon,
            rel_dm,
        });
    }
    Ok(Positions {
        samples,
        alt_offset_dm,
        vx,
        vy,
        vz,
        hdg,
        air,
    })
}

fn encode_status(w: &mut Writer, s: &Status) {
    let mut parts = 0u8;
    for (present, bit) in [
        (s.heartbeat.is_some(), PART_HEARTBEAT),
        (s.sys.is_some(), PART_SYS),
        (s.gps.is_some(), PART_GPS),
        (s.mission.is_some(), PART_MISSION),
    ] {
        if present {
            parts |= bit;
        }
    }
    w.u8(parts);
    if let Some(h) = &s.heartbeat {
        w.u8(h.mavtype);
        w.u8(h.autopilot);
        w.u8(h.base_mode);
        w.u32(h.custom_mode);
        w.u8(h.system_status);
    }
    if let Some(y) = &s.sys {
        w.varint(y.sensors_present.into());
        w.varint((y.sensors_enabled ^ y.sensors_present).into());
        w.varint((y.sensors_health ^ y.sensors_present).into());
        w.varint(y.voltage_battery.into());
        w.zvarint(y.current_battery.into());
        w.u8(y.battery_remaining as u8);
        w.varint(y.load.into());
    }
    if let Some(g) = &s.gps {
        w.u8(g.fix_type);
        w.u8(g.satellites_visible);
        w.varint(g.eph.into());
        w.varint(g.epv.into());
    }
    if let Some(m) = &s.mission {
        w.varint(m.seq.into());
        w.varint(m.total.into());
        w.u8(m.state);
        w.u8(m.mode);
    }
}

fn decode_status(r: &mut Reader) -> Result<Status, DecodeError> {
    let parts = r.u8()?;
    if parts & !(PART_HEARTBEAT | PART_SYS | PART_GPS | PART_MISSION) != 0 {
        return Err(DecodeError::Range);
    }
    let heartbeat = if parts & PART_HEARTBEAT != 0 {
        Some(HeartbeatPart {
            mavtype: r.u8()?,
            autopilot: r.u8()?,
            base_mode: r.u8()?,
            custom_mode: r.u32()?,
            system_status: r.u8()?,
        })
    } else {
        None
    };
    let sys = if parts & PART_SYS != 0 {
        let present = r.varint_u32()?;
        let enabled = r.varint_u32()? ^ present;
        let health = r.varint_u32()? ^ present;
        Some(SysPart {
            sensors_present: present,
            sensors_enabled: enabled,
            sensors_health: health,
            voltage_battery: r.varint_u16()?,
            current_battery: r.zvarint_i16()?,
            battery_remaining: r.u8()? as i8,
            load: r.varint_u16()?,
        })
    } else {
        None
    };
    let gps = if parts & PART_GPS != 0 {
        Some(GpsPart {
            fix_type: r.u8()?,
            satellites_visible: r.u8()?,
            eph: r.varint_u16()?,
            epv: r.varint_u16()?,
        })
    } else {
        None
    };
    let mission = if parts & PART_MISSION != 0 {
        Some(MissionPart {
            seq: r.varint_u16()?,
            total: r.varint_u16()?,
            state: r.u8()?,
            mode: r.u8()?,
        })
    } else {
        None
    };
    Ok(Status {
        heartbeat,
        sys,
        gps,
        mission,
    })
}

/// `n / d` rounded to nearest, halves away from zero (`d` > 0).
pub(crate) fn round_div(n: i64, d: i64) -> i64 {
    if n >= 0 {
        (n + d / 2) / d
    } else {
        (n - d / 2) / d
    }
}

#[derive(Default)]
struct Writer {
    bytes: Vec<u8>,
}

impl Writer {
    fn u8(&mut self, v: u8) {
        self.bytes.push(v);
    }

    fn u16(&mut self, v: u16) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    fn u32(&mut self, v: u32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    fn varint(&mut self, mut v: u64) {
        loop {
            let byte = (v & 0x7F) as u8;
            v >>= 7;
            if v == 0 {
                self.bytes.push(byte);
                return;
            }
            self.bytes.push(byte | 0x80);
        }
    }

    fn zvarint(&mut self, v: i64) {
        self.varint(((v << 1) ^ (v >> 63)) as u64);
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], DecodeError> {
        let end = self.at + N;
        let bytes = self.bytes.get(self.at..end).ok_or(DecodeError::Truncated)?;
        self.at = end;
        Ok(bytes.try_into().expect("N bytes"))
    }

    fn u8(&mut self) -> Result<u8, DecodeError> {
        Ok(self.take::<1>()?[0])
    }

    fn u16(&mut self) -> Result<u16, DecodeError> {
        Ok(u16::from_le_bytes(self.take()?))
    }

    fn u32(&mut self) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.take()?))
    }

    fn varint(&mut self) -> Result<u64, DecodeError> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = self.u8()?;
            let bits = u64::from(byte & 0x7F);
            if shift == 63 && bits > 1 {
                return Err(DecodeError::Range);
            }
            v |= bits << shift;
            if byte & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(DecodeError::Range)
    }

    fn zvarint(&mut self) -> Result<i64, DecodeError> {
        let v = self.varint()?;
        Ok(((v >> 1) as i64) ^ -((v & 1) as i64))
    }

    fn varint_u32(&mut self) -> Result<u32, DecodeError> {
        u32::try_from(self.varint()?).map_err(|_| DecodeError::Range)
    }

    fn varint_u16(&mut self) -> Result<u16, DecodeError> {
        u16::try_from(self.varint()?).map_err(|_| DecodeError::Range)
    }

    fn zvarint_i32(&mut self) -> Result<i32, DecodeError> {
        i32::try_from(self.zvarint()?).map_err(|_| DecodeError::Range)
    }

    /// A residual of wrapping 32-bit arithmetic: any value an i32 difference can take.
    fn zvarint_i32_wrapping(&mut self) -> Result<i32, DecodeError> {
        self.zvarint_i32()
    }

    fn zvarint_i16(&mut self) -> Result<i16, DecodeError> {
        i16::try_from(self.zvarint()?).map_err(|_| DecodeError::Range)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Any altitude the compactor can make: an i32 of mm in dm.
    const REL_DM: std::ops::RangeInclusive<i32> = -21_474_837..=21_474_836;

    /// Samples in time order on 10 ms steps from the first, each step at most 60 s (a batch
    /// spans at most one batch period), anything else any value its type can hold: what the
    /// compactor can send.
    fn positions() -> impl Strategy<Value = Positions> {
        (
            (any::<u32>(), any::<i32>(), any::<i32>(), REL_DM),
            prop::collection::vec(
                (0u32..=6_000, any::<i32>(), any::<i32>(), REL_DM),
                0..MAX_SAMPLES,
            ),
            -42_949_673i32..=42_949_673,
            any::<(i16, i16, i16)>(),
            any::<u16>(),
            prop::option::of((-1_000_000i32..=1_000_000, any::<u16>())),
        )
            .prop_map(
                |((t0, lat, lon, rel_dm), rest, alt_offset_dm, (vx, vy, vz), hdg, air)| {
                    let first = Sample {
                        time_boot_ms: t0,
                        lat,
                        lon,
                        rel_dm,
                    };
                    let mut samples = vec![first];
                    let mut t = t0;
                    for (dt, lat, lon, rel_dm) in rest {
                        t = t.wrapping_add(dt * 10);
                        samples.push(Sample {
                            time_boot_ms: t,
                            lat,
                            lon,
                            rel_dm,
                        });
                    }
                    Positions {
                        samples,
                        alt_offset_dm,
                        vx,
                        vy,
                        vz,
                        hdg,
                        air: air.map(|(airspeed_cms, throttle)| AirPart {
                            airspeed_cms,
                            throttle,
                        }),
                    }
                },
            )
    }

    fn status() -> impl Strategy<Value = Status> {
        (
            prop::option::of(any::<(u8, u8, u8, u32, u8)>().prop_map(|(a, b, c, d, e)| {
                HeartbeatPart {
                    mavtype: a,
                    autopilot: b,
                    base_mode: c,
                    custom_mode: d,
                    system_status: e,
                }
            })),
            prop::option::of(any::<(u32, u32, u32, u16, i16, i8, u16)>().prop_map(
                |(p, e, h, v, c, r, l)| SysPart {
                    sensors_present: p,
                    sensors_enabled: e,
                    sensors_health: h,
                    voltage_battery: v,
                    current_battery: c,
                    battery_remaining: r,
                    load: l,
                },
            )),
            prop::option::of(
                any::<(u8, u8, u16, u16)>().prop_map(|(f, s, h, v)| GpsPart {
                    fix_type: f,
                    satellites_visible: s,
                    eph: h,
                    epv: v,
                }),
            ),
            prop::option::of(
                any::<(u16, u16, u8, u8)>().prop_map(|(seq, total, state, mode)| MissionPart {
                    seq,
                    total,
                    state,
                    mode,
                }),
            ),
        )
            .prop_map(|(heartbeat, sys, gps, mission)| Status {
                heartbeat,
                sys,
                gps,
                mission,
            })
    }

    fn link() -> impl Strategy<Value = LINK_QUALITY_DATA> {
        any::<(u32, u16, u16, u16, i8, i8, i8)>().prop_map(|(t, p, l, c, r, rr, n)| {
            LINK_QUALITY_DATA {
                time_boot_ms: t,
                rx_packets: p,
                rx_lost: l,
                rx_bad_crc: c,
                rssi: r,
                remote_rssi: rr,
                noise: n,
            }
        })
    }

    proptest! {
        /// decode(encode(x)) == x for any frame of any section, extreme values included: the
        /// worst case of every section fits.
        #[test]
        fn any_frame_round_trips(
            positions in prop::option::of(positions()),
            status in prop::option::of(status()),
            link in prop::option::of(link()),
        ) {
            let frame = CompactFrame { positions, status, link };
            let data = frame.encode().unwrap();
            prop_assert_eq!(CompactFrame::decode(&data).unwrap(), frame);
        }

        /// Whatever bytes arrive, decoding returns a frame or an error, never a panic.
        #[test]
        fn any_bytes_decode_or_fail(bytes in prop::collection::vec(any::<u8>(), 0..=DATA_LEN)) {
            let mut data = [0u8; DATA_LEN];
            data[..bytes.len()].copy_from_slice(&bytes);
            let _ = CompactFrame::decode(&MAVLORA_COMPACT_DATA { data });
        }
    }

    #[test]
    fn a_cruising_batch_of_three_is_small() {
        // 10 m/s north-east at 100 m, 3 Hz: what the bytes budget is planned on.
        let samples: Vec<Sample> = (0..3)
            .map(|i| Sample {
                time_boot_ms: 60_000 + i * 333,
                lat: 553_700_000 + i as i32 * 212,
                lon: 103_900_000 + i as i32 * 372,
                rel_dm: 1000,
            })
            .collect();
        let frame = CompactFrame {
            positions: Some(Positions {
                samples,
                alt_offset_dm: 4890,
                vx: 707,
                vy: 707,
                vz: 0,
                hdg: 4500,
                air: None,
            }),
            ..CompactFrame::default()
        };
        // 12 bytes of sample 0's time and place, 12 of the rest of it, 5 and 3 for the others
        assert!(
            frame.encoded_len().unwrap() <= 32,
            "{}",
            frame.encoded_len().unwrap()
        );
    }
}
