//! What a SiK radio's registers mean to the link model: whether two radios hear each
//! other at all, and the preset a radio transmits with.

use serde::{Deserialize, Serialize};

use super::params::{Param, Params};
use crate::Preset;

/// The registers in force on a running radio: the link's from the last boot, the
/// immediate ones ([`Param::immediate`]) as last set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Settings {
    /// kbit/s, one the chip has.
    pub air_speed: u32,
    /// Golay error correction.
    pub ecc: bool,
    /// Network id: radios with different ids ignore each other.
    pub net_id: u32,
    /// Hopping band and channels, kHz.
    pub min_freq_khz: u32,
    pub max_freq_khz: u32,
    pub num_channels: u32,
    /// Manchester coding.
    pub manchester: bool,
    /// Conducted power, dBm.
    pub tx_power_dbm: u32,
    /// MAVLink framing: 0 off, 1 framing and `RADIO_STATUS`, 2 also low-latency RC.
    pub mavlink: u32,
    /// Share of time the radio may transmit, percent. Recorded, not applied: the model's
    /// own duty-cycle rule is the rig file's.
    pub duty_cycle: u32,
    /// Listen-before-talk threshold, SiK RSSI units (0 = off). Recorded, not applied:
    /// the model has no carrier sense on TDM presets.
    pub lbt_rssi: u32,
}

impl Settings {
    /// From the registers booted with (`boot`) and the ones set since (`ram`).
    pub fn new(boot: &Params, ram: &Params) -> Settings {
        Settings {
            air_speed: boot.get(Param::AirSpeed),
            ecc: boot.get(Param::Ecc) != 0,
            net_id: boot.get(Param::NetId),
            min_freq_khz: boot.get(Param::MinFreq),
            max_freq_khz: boot.get(Param::MaxFreq),
            num_channels: boot.get(Param::NumChannels),
            manchester: boot.get(Param::Manchester) != 0,
            tx_power_dbm: ram.get(Param::TxPower),
            mavlink: ram.get(Param::Mavlink),
            duty_cycle: ram.get(Param::DutyCycle),
            lbt_rssi: ram.get(Param::LbtRssi),
        }
    }

    /// Whether a radio with these settings decodes one with `other`'s: same rate and
    /// coding, same network id, same hopping sequence (band and channel count).
    pub fn hears(&self, other: &Settings) -> bool {
        self.air_speed == other.air_speed
            && self.ecc == other.ecc
            && self.net_id == other.net_id
            && self.min_freq_khz == other.min_freq_khz
            && self.max_freq_khz == other.max_freq_khz
            && self.num_channels == other.num_channels
            && self.manchester == other.manchester
    }

    /// The preset this radio transmits with, from the rig's `base`: for a SiK base, the
    /// air rate, ECC and power of these settings (frequency and the bench-fitted
    /// sensitivity kept); any other base is returned as it is.
    pub fn preset(&self, base: &Preset) -> Preset {
        if !base.name.starts_with("sik") {
            return base.clone();
        }
        Preset {
            tx_power_dbm: f64::from(self.tx_power_dbm),
            frequency_mhz: base.frequency_mhz,
            sensitivity_dbm: base.sensitivity_dbm,
            curve_width_db: base.curve_width_db,
            ..Preset::sik_air(self.air_speed, self.ecc)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sik::params::Board;

    #[test]
    fn defaults_map_onto_the_papers_sik_preset_and_ecc_onto_its_twin() {
        let board = Board::hm_trp_915();
        let p = Params::defaults(&board);
        let s = Settings::new(&p, &p);
        assert_eq!(s.preset(&Preset::sik_64k()), Preset::sik_64k());
        let mut ecc = p;
        assert!(ecc.set(&board, Param::Ecc, 1));
        assert_eq!(
            Settings::new(&ecc, &ecc).preset(&Preset::sik_64k()),
            Preset::sik_64k_ecc()
        );
        assert!(!s.hears(&Settings::new(&ecc, &ecc)));
        let lora = Preset::lora_sf7();
        assert_eq!(s.preset(&lora), lora);
    }
}
