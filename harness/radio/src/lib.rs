//! Line-of-sight radio models for the rig's link emulator and the simulated
//! worlds: airtime, loss, duty cycle, and a sans-IO engine per direction.
//!
//! Contract, after quinn-proto and smoltcp: no IO and no clock; the rig's
//! radio emulator driver runs this model between two serial ports.
//! Time is a [`timebase::Instant`] (microseconds since an epoch the driver
//! picks: the emulator its start, a simulation zero), passed to every call;
//! it must not go backwards (earlier times are treated as the latest seen).
//! Deterministic: the model runs at whole microseconds (airtime and jitter
//! rounded up), the resolution of every engine in the house.
//! Randomness comes from a ChaCha8 generator seeded per direction, so a seed
//! and the same calls give the same run, bit for bit.
//!
//! - [`Preset`]: a radio as data ([`Preset::sik_64k`], [`Preset::lora_sf7`],
//!   [`Preset::dmd_dl1`]); [`Modulation`] gives its time on air
//!   ([`airtime`]).
//! - [`LinkConfig`]: what differs per direction: [`LinkBudget`] through the
//!   packet-error curve ([`loss`]), [`GilbertElliott`] bursts stepped in time,
//!   a fixed packet loss, latency and jitter, a [`DutyCycle`] rule ([`duty`]),
//!   faults ([`faults`]: bit errors, duplicates, reordering, scheduled
//!   [`Silence`]s), the seed.
//! - [`Link`]: one direction: `handle_input(now, bytes)`,
//!   `poll_timeout()`, `handle_timeout(now)`, then drain `poll_output()`, with
//!   [`LinkStats`] for the evidence.
//! - [`Radio`]: two directions of one preset, half duplex where the preset is:
//!   [`Direction::Uplink`] (ground → drone) and [`Direction::Downlink`].
//! - [`sik`]: SiK firmware on the serial sides: the AT command set, the registers and what
//!   they mean to the link, `RADIO_STATUS`.
//!
//! A rig file carries a radio as a preset plus one [`LinkConfig`] per
//! direction, e.g. the paper's blind drone on SiK:
//!
//! ```toml
//! [uplink]                       # GCS → UAV: the drone's noise desensitises its receiver
//! seed = 2
//! latency_ms = 5.0
//! budget = { path = { distance_m = 400.0 }, rx_noise_db = 12.0 }
//! burst = { p_good_to_bad = 0.0005, p_bad_to_good = 0.01 }  # per ms: 100 ms fades, 4.8 % of the time
//!
//! [downlink]                     # UAV → GCS
//! seed = 1
//! latency_ms = 5.0
//! budget = { path = { distance_m = 400.0 } }
//! duty = { window_s = 3600.0, max_share = 0.1, enforce = true }
//! ```

pub mod airtime;
pub mod duty;
mod error;
pub mod faults;
pub mod link;
pub mod loss;
mod pair;
pub mod preset;
pub mod setup;
pub mod sik;

pub use airtime::{FskParams, LoraParams, Modulation};
pub use duty::{DutyCycle, DutyTracker};
pub use error::ConfigError;
pub use faults::{Reorder, Silence};
pub use link::{AirPacket, Link, LinkConfig, LinkStats, ReceiverReading, Slot};
pub use loss::{GilbertElliott, LinkBudget, LossModel, PathLoss};
pub use pair::{Direction, Radio};
pub use preset::{Access, BurstParams, Preset, TdmParams};
pub use setup::{PresetSpec, RadioSetup};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_module_doc_example_parses() {
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Example {
            uplink: LinkConfig,
            downlink: LinkConfig,
        }
        let example: String = include_str!("lib.rs")
            .lines()
            .skip_while(|l| !l.starts_with("//! ```toml"))
            .skip(1)
            .take_while(|l| !l.starts_with("//! ```"))
            .map(|l| format!("{}\n", l.trim_start_matches("//!").trim_start()))
            .collect();
        let e: Example = toml::from_str(&example).unwrap();
        assert_eq!(e.uplink.budget.rx_noise_db, 12.0);
        assert!(e.downlink.duty.enforce);
        let radio = Radio::new(&Preset::sik_64k(), &e.uplink, &e.downlink).unwrap();
        // 400 m: FSPL ≈ 77.2 dB, 6.8 dB inside the SiK edge; the uplink's 12 dB
        // of noise puts it 5.2 dB past it.
        assert!(radio.link(Direction::Uplink).reference_per() > 0.5);
        assert!(radio.link(Direction::Downlink).reference_per() < 1e-3);
    }
}
