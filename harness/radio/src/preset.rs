//! Radio presets: modulation, framing, channel access, buffer and RF figures
//! as data, so a rig file can carry them (unknown fields are refused).
//!
//! The three constructors carry the paper's bench settings (section III-B):
//! [`Preset::sik_64k`], [`Preset::lora_sf7`] and [`Preset::dmd_dl1`]. In TOML:
//!
//! ```toml
//! name = "lora-sf7"
//! max_payload = 251          # serial bytes per air packet
//! overhead_bytes = 4         # firmware header per packet (RadioHead: to, from, id, flags)
//! buffer_bytes = 256         # serial-side buffer; bytes beyond it are dropped
//! gap_ms = 0.0               # idle time between two packets of one sender
//! frequency_mhz = 433.0
//! tx_power_dbm = 20.0
//! sensitivity_dbm = -100.0   # bench-effective, see loss.rs
//! curve_width_db = 0.5
//! [modulation.lora]
//! spreading_factor = 7
//! bandwidth_hz = 125000
//! coding_rate = 1
//! preamble_symbols = 8
//! explicit_header = true
//! crc = true
//! [access.burst]
//! idle_ms = 5.0
//! ```

use timebase::Duration;

use serde::{Deserialize, Serialize};

use super::airtime::{FskParams, LoraParams, Modulation};
use super::error::{ConfigError, check_range};

/// One radio model, as data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preset {
    /// A name for reports and measurement keys (`sik-64k`, `lora-sf7`, ...).
    pub name: String,
    /// Modulation and the transceiver's framing.
    pub modulation: Modulation,
    /// How a sender gets the channel.
    pub access: Access,
    /// Most serial bytes one air packet carries.
    pub max_payload: usize,
    /// Bytes the radio firmware adds to each payload before the transceiver
    /// frames it (SiK's 2-byte TDM trailer, RadioHead's 4-byte header).
    pub overhead_bytes: usize,
    /// Serial-side buffer of the sending radio: bytes that arrive when it is
    /// full are dropped, as SiK's `serial_rx_overflow` does.
    pub buffer_bytes: usize,
    /// Idle time a sender leaves after each of its packets (SiK waits one
    /// packet latency: receivers cope badly with back-to-back packets).
    pub gap_ms: f64,
    /// Carrier frequency, MHz (free-space path loss).
    pub frequency_mhz: f64,
    /// Conducted transmit power, dBm.
    pub tx_power_dbm: f64,
    /// Received power, dBm, at which 1 % of reference packets are lost:
    /// fitted to the bench (see [`super::loss`]), not the datasheet figure.
    pub sensitivity_dbm: f64,
    /// Width of the packet-error curve, dB (see [`super::loss::packet_error_rate`]).
    pub curve_width_db: f64,
}

/// Channel access: when a sender may transmit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Access {
    /// Time-division (SiK): each side owns alternate transmit windows separated
    /// by silence; a packet is formed from what is buffered when the window
    /// allows and must end inside it. SiK's window yielding ("bonus" ticks) is
    /// not modelled, so throughput is a lower bound when one side is idle;
    /// nor is `packet_get_next`'s short wait for a MAVLink frame to complete:
    /// whatever is buffered leaves as soon as the window allows.
    Tdm(TdmParams),
    /// Packet on demand: a packet leaves when `max_payload` bytes are buffered
    /// or the serial line has been idle for `idle_ms`. Paired in a
    /// [`Radio`](super::Radio), both directions share one half-duplex channel
    /// with ideal carrier sense (no collisions).
    Burst(BurstParams),
}

/// TDM timing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TdmParams {
    /// Transmit window of one side, ms.
    pub window_ms: f64,
    /// Silence after each window, ms.
    pub silence_ms: f64,
}

/// Packet-on-demand timing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BurstParams {
    /// Serial idle time after which a partial packet is sent, ms.
    pub idle_ms: f64,
}

/// SiK firmware timing at an air rate (`tdm.c`, `tdm_init`): 16 µs ticks,
/// (8 + 8e6/rate)/16 + 1 ticks per byte, a packet latency of 13 bytes + 13 ticks
/// (Golay: bytes cost double and 4 more), windows of three full packets capped
/// at the default `MAX_WINDOW` of 131 ms, silence of two packet latencies.
fn sik_tdm(air_rate_kbps: u32, golay: bool, max_data: u32) -> TdmParams {
    const TICK_US: f64 = 16.0;
    let mut ticks_per_byte = (8 + 8_000_000 / (air_rate_kbps * 1000)) / 16 + 1;
    let mut latency = 13 * ticks_per_byte + 13;
    if golay {
        ticks_per_byte *= 2;
        latency += 4 * ticks_per_byte;
    }
    let window = (3 * (latency + max_data * ticks_per_byte)).min(131 * 1000 / 16);
    TdmParams {
        window_ms: window as f64 * TICK_US / 1000.0,
        silence_ms: (2 * latency) as f64 * TICK_US / 1000.0,
    }
}

impl Preset {
    /// Names [`Preset::builtin`] knows.
    pub const BUILTIN: &[&str] = &["sik-64k", "sik-64k-ecc", "lora-sf7", "dmd-dl1"];

    /// A built-in preset by its name (as in [`Preset::BUILTIN`]).
    pub fn builtin(name: &str) -> Option<Preset> {
        match name {
            "sik-64k" => Some(Preset::sik_64k()),
            "sik-64k-ecc" => Some(Preset::sik_64k_ecc()),
            "lora-sf7" => Some(Preset::lora_sf7()),
            "dmd-dl1" => Some(Preset::dmd_dl1()),
            _ => None,
        }
    }

    /// mRo SiK at 64 kbit/s air rate, 100 mW (20 dBm) as on the paper's bench,
    /// without ECC. Firmware facts (ArduPilot SiK): 252-byte air packets
    /// including a 2-byte TDM trailer (250 data bytes), a 1850-byte serial
    /// receive buffer that drops on overflow, 5 preamble + 2 sync bytes and a
    /// 3-byte header + 2-byte CRC from the Si1000 packet handler.
    /// Bench fit: loss rises past 84 dB of attenuation (Fig. 1a).
    pub fn sik_64k() -> Preset {
        Preset::sik(false)
    }

    /// SiK at 64 kbit/s with Golay ECC: 118 data bytes per packet, every
    /// coded byte sent twice over; throughput halves.
    pub fn sik_64k_ecc() -> Preset {
        Preset::sik(true)
    }

    fn sik(golay: bool) -> Preset {
        Preset::sik_air(64, golay)
    }

    /// SiK at another air rate (`AIR_SPEED`, kbit/s), with or without Golay ECC: the
    /// firmware's TDM timing and framing at that rate. The RF figures stay the 64 kbit/s
    /// bench fit: a real radio gains sensitivity at lower rates, which this preset does
    /// not claim.
    pub fn sik_air(air_speed_kbps: u32, golay: bool) -> Preset {
        let air_speed_kbps = air_speed_kbps.max(1);
        let max_data = if golay { 252 / 2 - (6 + 2) } else { 252 - 2 };
        let tdm = sik_tdm(air_speed_kbps, golay, max_data);
        Preset {
            name: format!("sik-{air_speed_kbps}k{}", if golay { "-ecc" } else { "" }),
            modulation: Modulation::Fsk(FskParams {
                bit_rate_bps: air_speed_kbps * 1000,
                preamble_bytes: 5,
                sync_bytes: 2,
                framing_bytes: 5,
                golay,
            }),
            // The firmware waits one packet latency after each packet: half the silence.
            gap_ms: tdm.silence_ms / 2.0,
            access: Access::Tdm(tdm),
            max_payload: max_data as usize,
            overhead_bytes: 2,
            buffer_bytes: 1850,
            frequency_mhz: 433.0,
            tx_power_dbm: 20.0,
            sensitivity_dbm: 20.0 - 84.0,
            curve_width_db: 1.0,
        }
    }

    /// Adafruit Feather LoRa (SX1276, RadioHead RH_RF95) at SF7, 125 kHz,
    /// CR 4/5, 100 mW (20 dBm), as in Fig. 1b: 8-symbol preamble, explicit
    /// header, CRC on, 4-byte RadioHead header, 251 data bytes per packet.
    /// The Feather has no serial-radio firmware of its own; assumed here: a
    /// sketch with a 256-byte buffer that sends a packet when it is full or
    /// after 5 ms without serial input. Bench fit: loss rises past 120 dB.
    pub fn lora_sf7() -> Preset {
        Preset {
            name: "lora-sf7".into(),
            modulation: Modulation::Lora(LoraParams {
                spreading_factor: 7,
                bandwidth_hz: 125_000,
                coding_rate: 1,
                preamble_symbols: 8,
                explicit_header: true,
                crc: true,
                low_data_rate_optimize: None,
            }),
            access: Access::Burst(BurstParams { idle_ms: 5.0 }),
            max_payload: 251,
            overhead_bytes: 4,
            buffer_bytes: 256,
            gap_ms: 0.0,
            frequency_mhz: 433.0,
            tx_power_dbm: 20.0,
            sensitivity_dbm: 20.0 - 120.0,
            curve_width_db: 0.5,
        }
    }

    /// DMD DL1 at 100 kbit/s, 500 mW (27 dBm), as in Fig. 1c. DMD does not
    /// publish its framing; assumed: FSK with 4 preamble + 4 sync bytes and a
    /// 5-byte header + CRC, up to 255 data bytes per packet, a 2048-byte
    /// serial buffer, a packet after 3 ms of serial idle, 1 ms between packets
    /// for the hop, one half-duplex channel. Bench fit: loss rises past 71 dB.
    pub fn dmd_dl1() -> Preset {
        Preset {
            name: "dmd-dl1".into(),
            modulation: Modulation::Fsk(FskParams {
                bit_rate_bps: 100_000,
                preamble_bytes: 4,
                sync_bytes: 4,
                framing_bytes: 5,
                golay: false,
            }),
            access: Access::Burst(BurstParams { idle_ms: 3.0 }),
            max_payload: 255,
            overhead_bytes: 0,
            buffer_bytes: 2048,
            gap_ms: 1.0,
            frequency_mhz: 433.0,
            tx_power_dbm: 10.0 * 500f64.log10(),
            sensitivity_dbm: 10.0 * 500f64.log10() - 71.0,
            curve_width_db: 0.75,
        }
    }

    /// Time on air of a packet carrying `data_len` serial bytes.
    pub fn time_on_air(&self, data_len: usize) -> Duration {
        self.modulation.time_on_air(data_len + self.overhead_bytes)
    }

    /// Upper bound on serial bytes per second one sender can move: full
    /// packets back to back, no gaps, windows or losses.
    pub fn max_data_rate(&self) -> f64 {
        self.max_payload as f64 / self.time_on_air(self.max_payload).as_secs_f64()
    }

    /// Checks every setting; [`Link::new`](super::Link::new) calls it.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.modulation.validate()?;
        check_range(
            "max_payload",
            self.max_payload as f64,
            1.0,
            65_535.0,
            "1..=65535 bytes",
        )?;
        check_range(
            "buffer_bytes",
            self.buffer_bytes as f64,
            self.max_payload as f64,
            16e6,
            "at least max_payload",
        )?;
        check_range("gap_ms", self.gap_ms, 0.0, 10_000.0, "0..=10000 ms")?;
        check_range(
            "frequency_mhz",
            self.frequency_mhz,
            1.0,
            100_000.0,
            "1..=100000 MHz",
        )?;
        check_range(
            "tx_power_dbm",
            self.tx_power_dbm,
            -50.0,
            60.0,
            "-50..=60 dBm",
        )?;
        check_range(
            "sensitivity_dbm",
            self.sensitivity_dbm,
            -200.0,
            50.0,
            "-200..=50 dBm",
        )?;
        check_range(
            "curve_width_db",
            self.curve_width_db,
            0.01,
            30.0,
            "0.01..=30 dB",
        )?;
        match self.access {
            Access::Tdm(t) => {
                check_range(
                    "window_ms",
                    t.window_ms,
                    0.001,
                    10_000.0,
                    "0.001..=10000 ms",
                )?;
                check_range("silence_ms", t.silence_ms, 0.0, 10_000.0, "0..=10000 ms")?;
                let full = self.time_on_air(self.max_payload);
                if full > ms(t.window_ms) {
                    return Err(ConfigError::WindowTooShort {
                        payload: self.max_payload,
                        airtime_ms: full.as_secs_f64() * 1e3,
                        window_ms: t.window_ms,
                    });
                }
            }
            Access::Burst(b) => {
                check_range("idle_ms", b.idle_ms, 0.0, 10_000.0, "0..=10000 ms")?;
            }
        }
        Ok(())
    }

    /// Path loss at which a reference packet is lost 1 % of the time with
    /// 0 dBi antennas and no cable loss: the last "nominal" attenuation of an
    /// attenuation sweep (the fitted Fig. 1 edge for the paper's presets).
    pub fn nominal_edge_db(&self) -> f64 {
        self.tx_power_dbm - self.sensitivity_dbm
    }

    /// Whether the two directions of a pair share one channel in time.
    pub fn half_duplex(&self) -> bool {
        matches!(self.access, Access::Burst(_))
    }
}

/// Milliseconds (validated finite and non-negative) as a `Duration`.
pub(crate) fn ms(value: f64) -> Duration {
    Duration::from_secs_f64(value.max(0.0) / 1000.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sik_timing_follows_the_firmware() {
        // 64 kbit/s: (8 + 125)/16 + 1 = 9 ticks/byte; latency 13·9 + 13 = 130 ticks;
        // window 3·(130 + 250·9) = 7140 ticks = 114.24 ms; silence 260 ticks = 4.16 ms.
        let t = sik_tdm(64, false, 250);
        assert!((t.window_ms - 114.24).abs() < 1e-9, "{t:?}");
        assert!((t.silence_ms - 4.16).abs() < 1e-9, "{t:?}");
        // Golay: 18 ticks/byte, latency 130 + 72 = 202; window 3·(202 + 118·18) = 6978 ticks.
        let t = sik_tdm(64, true, 118);
        assert!((t.window_ms - 111.648).abs() < 1e-9, "{t:?}");
    }

    #[test]
    fn presets_validate_and_carry_the_papers_settings() {
        for p in [
            Preset::sik_64k(),
            Preset::sik_64k_ecc(),
            Preset::lora_sf7(),
            Preset::dmd_dl1(),
        ] {
            p.validate().unwrap_or_else(|e| panic!("{}: {e}", p.name));
        }
        assert!((Preset::dmd_dl1().tx_power_dbm - 26.99).abs() < 0.01);
        assert!((Preset::sik_64k().nominal_edge_db() - 84.0).abs() < 1e-9);
        assert!((Preset::lora_sf7().nominal_edge_db() - 120.0).abs() < 1e-9);
        assert!((Preset::dmd_dl1().nominal_edge_db() - 71.0).abs() < 1e-9);
        // Three full SiK packets (33 ms each) and their gaps fit a window.
        let sik = Preset::sik_64k();
        assert_eq!(sik.time_on_air(250), Duration::from_millis(33));
        // ECC roughly halves what one packet-second carries.
        let ratio = Preset::sik_64k_ecc().max_data_rate() / sik.max_data_rate();
        assert!((0.45..0.52).contains(&ratio), "{ratio}");
    }

    #[test]
    fn a_preset_round_trips_through_toml_and_refuses_unknown_fields() {
        let p = Preset::lora_sf7();
        let text = toml::to_string(&p).unwrap();
        let back: Preset = toml::from_str(&text).unwrap();
        assert_eq!(back, p);
        let bad = format!("{text}\nantenna = \"big\"\n");
        let err = toml::from_str::<Preset>(&bad).unwrap_err().to_string();
        assert!(err.contains("unknown field"), "{err}");
        let bad = text.replace("spreading_factor", "spreading_factr");
        assert!(toml::from_str::<Preset>(&bad).is_err());
    }

    #[test]
    fn the_module_doc_example_parses() {
        let doc = include_str!("preset.rs");
        let example: String = doc
            .lines()
            .skip_while(|l| !l.starts_with("//! ```toml"))
            .skip(1)
            .take_while(|l| !l.starts_with("//! ```"))
            .map(|l| l.trim_start_matches("//!").trim_start())
            .map(|l| format!("{l}\n"))
            .collect();
        let p: Preset = toml::from_str(&example).unwrap();
        assert_eq!(p, Preset::lora_sf7());
    }

    #[test]
    fn refuses_a_window_too_short_for_a_full_packet() {
        let mut p = Preset::sik_64k();
        p.access = Access::Tdm(TdmParams {
            window_ms: 20.0,
            silence_ms: 4.0,
        });
        assert!(matches!(
            p.validate(),
            Err(ConfigError::WindowTooShort { .. })
        ));
    }
}
