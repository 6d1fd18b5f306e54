//! SiK's S-register table (`parameters.c`): numbers, names, defaults, the checks `ATSn=`
//! applies, and the `ATI5` listing both printed and parsed.

use serde::{Deserialize, Serialize};

/// Number of S registers SiK 2.x lists (S0..=S15).
pub const PARAM_COUNT: usize = 16;

/// `FORMAT`'s value in SiK 2.x: a table of another format is not loaded.
pub const FORMAT_CURRENT: u32 = 25;

/// One S register.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[repr(u8)]
#[allow(missing_docs)]
pub enum Param {
    Format = 0,
    SerialSpeed,
    AirSpeed,
    NetId,
    TxPower,
    Ecc,
    Mavlink,
    OpResend,
    MinFreq,
    MaxFreq,
    NumChannels,
    DutyCycle,
    LbtRssi,
    Manchester,
    RtsCts,
    MaxWindow,
}

impl Param {
    /// All, by register number.
    pub const ALL: [Param; PARAM_COUNT] = [
        Param::Format,
        Param::SerialSpeed,
        Param::AirSpeed,
        Param::NetId,
        Param::TxPower,
        Param::Ecc,
        Param::Mavlink,
        Param::OpResend,
        Param::MinFreq,
        Param::MaxFreq,
        Param::NumChannels,
        Param::DutyCycle,
        Param::LbtRssi,
        Param::Manchester,
        Param::RtsCts,
        Param::MaxWindow,
    ];

    /// The settings two radios must share to hear each other or to behave alike on the
    /// air: what a rig checks on both ends before a run.
    pub const MUST_MATCH: [Param; 10] = [
        Param::AirSpeed,
        Param::NetId,
        Param::Ecc,
        Param::Mavlink,
        Param::MinFreq,
        Param::MaxFreq,
        Param::NumChannels,
        Param::DutyCycle,
        Param::LbtRssi,
        Param::MaxWindow,
    ];

    /// The register number (`n` of `ATSn`).
    pub fn number(self) -> u8 {
        self as u8
    }

    /// The register with number `n`.
    pub fn from_number(n: u32) -> Option<Param> {
        Param::ALL.get(usize::try_from(n).ok()?).copied()
    }

    /// The register named `name` as `ATI5` prints it.
    pub fn from_name(name: &str) -> Option<Param> {
        Param::ALL.into_iter().find(|p| p.name() == name)
    }

    /// The name `ATI5` prints.
    pub fn name(self) -> &'static str {
        match self {
            Param::Format => "FORMAT",
            Param::SerialSpeed => "SERIAL_SPEED",
            Param::AirSpeed => "AIR_SPEED",
            Param::NetId => "NETID",
            Param::TxPower => "TXPOWER",
            Param::Ecc => "ECC",
            Param::Mavlink => "MAVLINK",
            Param::OpResend => "OPPRESEND",
            Param::MinFreq => "MIN_FREQ",
            Param::MaxFreq => "MAX_FREQ",
            Param::NumChannels => "NUM_CHANNELS",
            Param::DutyCycle => "DUTY_CYCLE",
            Param::LbtRssi => "LBT_RSSI",
            Param::Manchester => "MANCHESTER",
            Param::RtsCts => "RTSCTS",
            Param::MaxWindow => "MAX_WINDOW",
        }
    }

    /// Whether SiK applies a set at once (`param_set`'s immediate cases) rather than at
    /// the next boot.
    pub fn immediate(self) -> bool {
        matches!(
            self,
            Param::TxPower
                | Param::DutyCycle
                | Param::LbtRssi
                | Param::Mavlink
                | Param::OpResend
                | Param::RtsCts
        )
    }
}

/// What a board brings to the table: banner, power levels, frequency band.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Board {
    /// `ATI`'s answer.
    pub banner: String,
    /// Transmit power levels the radio chip has, dBm, ascending; a set rounds down to one.
    pub power_levels: Vec<u32>,
    /// Band the board is built for: `MIN_FREQ`, `MAX_FREQ` (kHz) and `NUM_CHANNELS` a
    /// zero in the table stands for at boot.
    pub min_freq_khz: u32,
    pub max_freq_khz: u32,
    pub num_channels: u32,
}

impl Board {
    /// An HM-TRP (Si1000) 915 MHz board, as mRo and Holybro ship it.
    pub fn hm_trp_915() -> Board {
        Board {
            banner: "SiK 2.2 on HM-TRP".into(),
            power_levels: vec![1, 2, 5, 8, 11, 14, 17, 20],
            min_freq_khz: 915_000,
            max_freq_khz: 928_000,
            num_channels: 50,
        }
    }

    /// The 433 MHz variant of the same board (the paper's radios).
    pub fn hm_trp_433() -> Board {
        Board {
            min_freq_khz: 414_000,
            max_freq_khz: 454_000,
            num_channels: 10,
            ..Board::hm_trp_915()
        }
    }
}

/// Serial speeds SiK accepts, in its one-letter-less shorthand (57 = 57600 baud).
const SERIAL_SPEEDS: [u32; 9] = [1, 2, 4, 9, 19, 38, 57, 115, 230];

/// Air data rates the Si1000 register tables provide, kbit/s; a set picks the lowest at
/// or above the value at boot.
pub const AIR_SPEEDS: [u32; 13] = [2, 4, 8, 16, 19, 24, 32, 48, 64, 96, 128, 192, 250];

/// A full S-register table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Params {
    values: [u32; PARAM_COUNT],
}

impl Params {
    /// The firmware's defaults on `board` (zero frequencies replaced by the band).
    pub fn defaults(board: &Board) -> Params {
        let mut values = [
            FORMAT_CURRENT,
            57,
            64,
            25,
            20,
            0,
            1,
            0,
            0,
            0,
            0,
            100,
            0,
            0,
            0,
            131,
        ];
        values[Param::TxPower as usize] = round_power(board, 20);
        let mut p = Params { values };
        p.fill_band(board);
        p
    }

    /// What boot does to a loaded table: zeros become the board's band, the air rate
    /// one the chip has.
    pub fn fill_band(&mut self, board: &Board) {
        let v = &mut self.values;
        if v[Param::MinFreq as usize] == 0 {
            v[Param::MinFreq as usize] = board.min_freq_khz;
        }
        if v[Param::MaxFreq as usize] == 0 {
            v[Param::MaxFreq as usize] = board.max_freq_khz;
        }
        if v[Param::NumChannels as usize] == 0 {
            v[Param::NumChannels as usize] = board.num_channels;
        }
        let air = v[Param::AirSpeed as usize];
        v[Param::AirSpeed as usize] = AIR_SPEEDS
            .into_iter()
            .find(|&s| s >= air)
            .unwrap_or(AIR_SPEEDS[AIR_SPEEDS.len() - 1]);
    }

    /// One register.
    pub fn get(&self, p: Param) -> u32 {
        self.values[p as usize]
    }

    /// `ATSn=value` as `param_set` does it: `false` (an `ERROR`) for a value the register
    /// refuses; some values are constrained or rounded as the firmware does.
    pub fn set(&mut self, board: &Board, p: Param, value: u32) -> bool {
        let ok = match p {
            Param::Format => false,
            Param::SerialSpeed => SERIAL_SPEEDS.contains(&value),
            Param::AirSpeed => value <= 256,
            Param::TxPower => value <= board.power_levels.last().copied().unwrap_or(0),
            Param::Ecc | Param::OpResend => value <= 1,
            Param::Mavlink => value <= 2,
            Param::MaxWindow => value <= 131,
            _ => true,
        };
        if !ok {
            return false;
        }
        let value = match p {
            Param::TxPower => round_power(board, value),
            Param::DutyCycle => value.min(100),
            Param::LbtRssi if value != 0 => value.clamp(25, 220),
            Param::RtsCts => (value != 0) as u32,
            _ => value,
        };
        self.values[p as usize] = value;
        true
    }

    /// Tags the table with the current format, as saving does.
    pub(crate) fn set_format(&mut self) {
        self.values[Param::Format as usize] = FORMAT_CURRENT;
    }

    /// The `ATI5` listing, lines as the firmware prints them (`S0: FORMAT=25\r\n`).
    pub fn ati5(&self) -> String {
        Param::ALL
            .into_iter()
            .map(|p| format!("S{}: {}={}\r\n", p.number(), p.name(), self.get(p)))
            .collect()
    }
}

/// The highest power level not above `dbm`.
fn round_power(board: &Board, dbm: u32) -> u32 {
    board
        .power_levels
        .iter()
        .copied()
        .filter(|&l| l <= dbm)
        .max()
        .unwrap_or(board.power_levels.first().copied().unwrap_or(0))
}

/// One line of an `ATI5` listing, as read back: a radio may list registers this table
/// does not know (an RFD900's S16 and up), so names stay strings.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ParamEntry {
    /// Register number.
    pub number: u8,
    /// Name as listed.
    pub name: String,
    /// Value.
    pub value: u32,
}

/// A line of an `ATI5` answer that is not `Sn: NAME=value`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("not an ATI5 line: {line:?}")]
pub struct Ati5Error {
    /// The line, as received.
    pub line: String,
}

/// Parses `ATI5` lines (`S3: NETID=25`, the space optional); blank lines are skipped.
pub fn parse_ati5(text: &str) -> Result<Vec<ParamEntry>, Ati5Error> {
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .map(|line| {
            let bad = || Ati5Error { line: line.into() };
            let rest = line.strip_prefix('S').ok_or_else(bad)?;
            let (number, rest) = rest.split_once(':').ok_or_else(bad)?;
            let (name, value) = rest.trim_start().split_once('=').ok_or_else(bad)?;
            let valid_name = !name.is_empty()
                && name
                    .bytes()
                    .all(|b| b.is_ascii_uppercase() || b.is_ascii_digit() || b == b'_');
            if !valid_name {
                return Err(bad());
            }
            Ok(ParamEntry {
                number: number.parse().map_err(|_| bad())?,
                name: name.into(),
                value: value.parse().map_err(|_| bad())?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_list_as_the_firmware_does_and_parse_back() {
        let board = Board::hm_trp_915();
        let p = Params::defaults(&board);
        let text = p.ati5();
        assert!(
            text.starts_with("S0: FORMAT=25\r\nS1: SERIAL_SPEED=57\r\n"),
            "{text}"
        );
        assert!(
            text.contains("S8: MIN_FREQ=915000\r\n") && text.ends_with("S15: MAX_WINDOW=131\r\n")
        );
        let entries = parse_ati5(&text).unwrap();
        assert_eq!(entries.len(), PARAM_COUNT);
        for (e, param) in entries.iter().zip(Param::ALL) {
            assert_eq!(
                (e.number, e.name.as_str(), e.value),
                (param.number(), param.name(), p.get(param))
            );
        }
        // Without the space, as the issue quotes it, too.
        assert_eq!(parse_ati5("S3:NETID=7").unwrap()[0].value, 7);
    }

    #[test]
    fn garbage_lines_are_refused_with_the_line() {
        for bad in [
            "S3 NETID=25",
            "X3: NETID=25",
            "S3: NETID=twenty",
            "S3: =4",
            "S3: net id=4",
        ] {
            let err = parse_ati5(bad).unwrap_err();
            assert_eq!(err.line, bad);
        }
    }

    #[test]
    fn sets_follow_param_set() {
        let board = Board::hm_trp_915();
        let mut p = Params::defaults(&board);
        assert!(!p.set(&board, Param::Format, 25), "S0 is read-only");
        assert!(!p.set(&board, Param::Ecc, 2));
        assert!(!p.set(&board, Param::TxPower, 21));
        assert!(p.set(&board, Param::TxPower, 19));
        assert_eq!(p.get(Param::TxPower), 17, "rounded down to a chip level");
        assert!(p.set(&board, Param::LbtRssi, 3));
        assert_eq!(p.get(Param::LbtRssi), 25);
        assert!(p.set(&board, Param::DutyCycle, 400));
        assert_eq!(p.get(Param::DutyCycle), 100);
        assert!(!p.set(&board, Param::SerialSpeed, 56));
        assert!(p.set(&board, Param::AirSpeed, 100));
        p.fill_band(&board);
        assert_eq!(
            p.get(Param::AirSpeed),
            128,
            "boot picks the next rate the chip has"
        );
    }
}
