//! Time on air of one packet, per modulation.
//!
//! Airtime is what paces a radio link: the emulator holds each packet for its
//! time on air before it can arrive, and the duty-cycle budget counts it. The
//! arithmetic is integer nanoseconds so a preset gives the same airtime on
//! every host.

use timebase::Duration;

use serde::{Deserialize, Serialize};

use super::error::{ConfigError, check_range};

/// A modulation and the framing its transceiver adds around every payload.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Modulation {
    /// LoRa chirp spread spectrum (SX127x).
    Lora(LoraParams),
    /// (G)FSK with a byte-oriented packet handler (Si1000 in SiK radios, DMD DL1).
    Fsk(FskParams),
}

impl Modulation {
    /// Time on air of a packet whose transceiver payload is `len` bytes
    /// (firmware headers included, the transceiver's own framing added here).
    pub fn time_on_air(&self, len: usize) -> Duration {
        match self {
            Modulation::Lora(p) => p.time_on_air(len),
            Modulation::Fsk(p) => p.time_on_air(len),
        }
    }

    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        match self {
            Modulation::Lora(p) => p.validate(),
            Modulation::Fsk(p) => p.validate(),
        }
    }
}

/// LoRa modem settings, with time on air per Semtech AN1200.13 (the SX1276
/// datasheet's §4.1.1.7 formula).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoraParams {
    /// Spreading factor SF, 6..=12: chips per symbol = 2^SF.
    pub spreading_factor: u8,
    /// Bandwidth BW in Hz (e.g. 125000).
    pub bandwidth_hz: u32,
    /// Coding rate 4/(4+CR), CR in 1..=4 (1 = 4/5, 4 = 4/8).
    pub coding_rate: u8,
    /// Programmed preamble length n in symbols (RadioHead default 8); the
    /// modem adds 4.25 symbols of sync.
    pub preamble_symbols: u16,
    /// Explicit header (length, CR and CRC flag sent in the packet). RadioHead: on.
    pub explicit_header: bool,
    /// Payload CRC on.
    pub crc: bool,
    /// Low data rate optimisation (DE); absent = on exactly when T_sym > 16 ms,
    /// as the datasheet requires.
    #[serde(default)]
    pub low_data_rate_optimize: Option<bool>,
}

impl LoraParams {
    /// Symbol time T_sym = 2^SF / BW.
    pub fn symbol_time(&self) -> Duration {
        micros_up(self.symbol_nanos_x4() / 4)
    }

    /// 4·T_sym in ns; exact for every SF at the usual bandwidths.
    fn symbol_nanos_x4(&self) -> u64 {
        ((1u128 << self.spreading_factor) * 4_000_000_000u128 / self.bandwidth_hz as u128) as u64
    }

    /// Whether low data rate optimisation is on (given, or T_sym > 16 ms).
    pub fn low_data_rate(&self) -> bool {
        self.low_data_rate_optimize
            .unwrap_or(self.symbol_nanos_x4() > 4 * 16_000_000)
    }

    /// Payload symbols: 8 + max(ceil((8·PL − 4·SF + 28 + 16·CRC − 20·IH) / (4·(SF − 2·DE)))·(CR + 4), 0).
    pub fn payload_symbols(&self, payload_len: usize) -> u64 {
        let sf = self.spreading_factor as i64;
        let crc = self.crc as i64;
        let ih = !self.explicit_header as i64;
        let de = self.low_data_rate() as i64;
        let num = 8 * payload_len as i64 - 4 * sf + 28 + 16 * crc - 20 * ih;
        let den = 4 * (sf - 2 * de);
        let blocks = if num > 0 { (num + den - 1) / den } else { 0 };
        8 + blocks as u64 * (self.coding_rate as u64 + 4)
    }

    /// Time on air: (n + 4.25 + payload symbols) · T_sym.
    pub fn time_on_air(&self, payload_len: usize) -> Duration {
        // In quarter symbols so the 4.25 stays exact.
        let quarters =
            4 * self.preamble_symbols as u64 + 17 + 4 * self.payload_symbols(payload_len);
        micros_up(quarters * self.symbol_nanos_x4() / 16)
    }

    /// Raw bit rate SF · BW / 2^SF · 4/(4+CR), the figure LoRa calculators give
    /// (5468.75 bit/s = 683.6 B/s at SF7/125 kHz/4-5, as in the paper).
    pub fn bit_rate_bps(&self) -> f64 {
        let sf = self.spreading_factor as f64;
        sf * self.bandwidth_hz as f64 / f64::powi(2.0, self.spreading_factor as i32) * 4.0
            / (4.0 + self.coding_rate as f64)
    }

    fn validate(&self) -> Result<(), ConfigError> {
        check_range(
            "spreading_factor",
            self.spreading_factor as f64,
            6.0,
            12.0,
            "6..=12",
        )?;
        check_range(
            "bandwidth_hz",
            self.bandwidth_hz as f64,
            7_800.0,
            500_000.0,
            "7800..=500000 Hz",
        )?;
        check_range(
            "coding_rate",
            self.coding_rate as f64,
            1.0,
            4.0,
            "1..=4 (4/5..4/8)",
        )?;
        // SF − 2·DE must stay positive for the formula; SF6 with DE is not a real mode.
        if self.spreading_factor as i64 - 2 * self.low_data_rate() as i64 <= 4 {
            return Err(ConfigError::OutOfRange {
                field: "low_data_rate_optimize",
                value: 1.0,
                expected: "off below SF7",
            });
        }
        Ok(())
    }
}

/// FSK framing: preamble and sync word sent as is, then the transceiver's
/// header and CRC around the payload, optionally Golay-coded.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FskParams {
    /// Air bit rate, bit/s.
    pub bit_rate_bps: u32,
    /// Preamble bytes.
    pub preamble_bytes: u16,
    /// Sync word bytes.
    pub sync_bytes: u16,
    /// Header (length, network id) and CRC bytes the packet handler adds.
    pub framing_bytes: u16,
    /// Golay (24,12) error correction: header, payload and CRC go on air as 6
    /// bytes per 3, which halves throughput (SiK `ECC=1`).
    #[serde(default)]
    pub golay: bool,
}

impl FskParams {
    /// Bytes on air for a `len`-byte payload.
    pub fn air_bytes(&self, len: usize) -> u64 {
        let coded = len as u64 + self.framing_bytes as u64;
        let coded = if self.golay {
            coded.div_ceil(3) * 6
        } else {
            coded
        };
        self.preamble_bytes as u64 + self.sync_bytes as u64 + coded
    }

    /// Time on air: air bytes · 8 / bit rate.
    pub fn time_on_air(&self, len: usize) -> Duration {
        micros_up(self.air_bytes(len) * 8 * 1_000_000_000 / self.bit_rate_bps as u64)
    }

    fn validate(&self) -> Result<(), ConfigError> {
        check_range(
            "bit_rate_bps",
            self.bit_rate_bps as f64,
            100.0,
            10_000_000.0,
            "100..=10000000 bit/s",
        )
    }
}

/// Nanoseconds (the exact arithmetic above) to whole microseconds, the model's resolution,
/// rounded up: a packet is not over before its last bit. Exact for the built-in presets.
fn micros_up(nanos: u64) -> Duration {
    Duration::from_micros(nanos.div_ceil(1000))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sf(spreading_factor: u8) -> LoraParams {
        LoraParams {
            spreading_factor,
            bandwidth_hz: 125_000,
            coding_rate: 1,
            preamble_symbols: 8,
            explicit_header: true,
            crc: true,
            low_data_rate_optimize: None,
        }
    }

    #[test]
    fn lora_sf7_21_bytes_is_the_briefs_57_ms() {
        // T_sym = 128/125 kHz = 1.024 ms; preamble 12.25 sym;
        // payload 8 + ceil((168 − 28 + 28 + 16)/28)·5 = 8 + 7·5 = 43 sym;
        // (12.25 + 43) · 1.024 ms = 56.576 ms.
        let p = sf(7);
        assert_eq!(p.symbol_time(), Duration::from_micros(1024));
        assert_eq!(p.payload_symbols(21), 43);
        assert_eq!(p.time_on_air(21), Duration::from_micros(56_576));
    }

    #[test]
    fn lora_by_hand() {
        // SF7, 255 B: ceil((2040 − 28 + 28 + 16)/28) = ceil(73.43) = 74 → 8 + 370 = 378 sym;
        // (12.25 + 378) · 1.024 ms = 399.616 ms.
        assert_eq!(sf(7).time_on_air(255), Duration::from_micros(399_616));
        // SF12: T_sym = 32.768 ms > 16 ms → DE on; 10 B: ceil((80 − 48 + 44)/40) = 2
        // → 8 + 10 = 18 sym; (12.25 + 18) · 32.768 ms = 991.232 ms.
        let p = sf(12);
        assert!(p.low_data_rate());
        assert_eq!(p.time_on_air(10), Duration::from_micros(991_232));
        // SF11: T_sym = 16.384 ms > 16 ms → DE on too.
        assert!(sf(11).low_data_rate());
        assert!(!sf(10).low_data_rate());
        // SF9, CR 4/8, 0 B: ceil((0 − 36 + 44)/36) = 1 → 8 + 8 = 16 sym;
        // (12.25 + 16) · 4.096 ms = 115.712 ms.
        let p = LoraParams {
            coding_rate: 4,
            ..sf(9)
        };
        assert_eq!(p.time_on_air(0), Duration::from_micros(115_712));
        // Implicit header, no CRC, 0 B: numerator −20 → the max(…, 0) → 8 sym;
        // (12.25 + 8) · 1.024 ms = 20.736 ms.
        let p = LoraParams {
            explicit_header: false,
            crc: false,
            ..sf(7)
        };
        assert_eq!(p.time_on_air(0), Duration::from_micros(20_736));
    }

    #[test]
    fn lora_bit_rate_is_the_papers_683_6_bytes_per_second() {
        let bytes_per_s = sf(7).bit_rate_bps() / 8.0;
        assert!((bytes_per_s - 683.59375).abs() < 1e-9, "{bytes_per_s}");
    }

    #[test]
    fn fsk_by_hand() {
        let sik = FskParams {
            bit_rate_bps: 64_000,
            preamble_bytes: 5,
            sync_bytes: 2,
            framing_bytes: 5,
            golay: false,
        };
        // 252 B (250 data + 2 trailer) + 5 framing + 7 preamble/sync = 264 B
        // = 2112 bit / 64 kbit/s = 33 ms.
        assert_eq!(sik.time_on_air(252), Duration::from_millis(33));
        // Golay: 120 + 5 = 125 → 42 blocks · 6 = 252, + 7 = 259 B = 32.375 ms.
        let ecc = FskParams { golay: true, ..sik };
        assert_eq!(ecc.time_on_air(120), Duration::from_micros(32_375));
    }

    #[test]
    fn rejects_impossible_lora_settings() {
        assert!(sf(13).validate().is_err());
        let p = LoraParams {
            coding_rate: 5,
            ..sf(7)
        };
        assert!(p.validate().is_err());
        assert!(sf(7).validate().is_ok());
    }
}
