//! MavLora's full-length reproductions of the paper (in process; `realtime` runs the real
//! binaries over ptys): the real bridge and router engines, the simulated PX4 and ground
//! station, and the rig's radio model between them, under a virtual clock: the one world of
//! crate `harness-sim` ([`harness_sim::World`]). An 8.5-minute flight costs seconds, and a
//! seed gives the same numbers every time.
//!
//! One file per scenario: [`table_ii`] (bytes and messages per second per
//! bandwidth mechanism), [`mission`] (100-item upload over slow lossy
//! radios, relay vs naive), [`c2_latency`] (command → ack under loss),
//! [`sweep`] (attenuation sweep, the paper's Fig. 1), [`blind_drone`]
//! (uplink-only loss seen from the ground through `LINK_QUALITY`),
//! [`duty_cycle`] (the compact profile's airtime share on LoRa).
//!
//! The runner takes [`scenarios`] and a [`Radios`] (built-ins from
//! [`Radios::paper_defaults`], or the rig file's).
//!
//! Every measurement has dimensions `device = mavlora`, `transport = simulated`, and
//! `variant`, `radio` or `scenario` where the name shows one.
//!
//! | phase | measurements (built-in limit) |
//! |---|---|
//! | `table_ii` | `mavlora.<variant>.bytes_per_s`, `.msgs_per_s` for `wired`, `limit`, `limit_filter` (≤ 951 B/s), `compact` (≤ 50 B/s) |
//! | `mission_upload` | `mavlora.<radio>.mission_upload_s` (≤ 300 s), `.mission_bytes_on_air`, `.mission_efficiency`, `.naive.mission_upload_s`, `.naive.mission_bytes_on_air`, `.naive.duplicate_items` for `lora_sf7`, `sik_64k` |
//! | `c2_latency` | `mavlora.c2_latency_p50_ms`, `mavlora.c2_latency_p99_ms` (≤ 3000 ms); `mavlora.sik_64k.c2_latency_p50_ms`, `.c2_latency_p99_ms` (≤ 500 ms, the project's target on SiK), `.commands_lost`, `.commands_executed_twice` (= 0) |
//! | `attenuation_sweep` | `mavlora.<preset>.nominal_edge_db`, `.nominal_range_m` (paper ± 3 dB), CSV evidence |
//! | `blind_drone` | `mavlora.blind_drone.detect_p50_s`, `.detect_p95_s`, `.restore_p95_s` over 20 seeds (≤ 30 s, marginal from 5 s: the project's target for telling the pilot); `mavlora.lora_sf7.monitor_uplink_bytes_per_s`, `.monitor_downlink_bytes_per_s` (≤ 3 B/s) |
//! | `duty_cycle` | `mavlora.lora_sf7.duty_cycle_pct` (≤ 10 %), `mavlora.lora_sf7.uplink_duty_cycle_pct` |
//! | `soak` | an hour with silences, reboots, floods, commands and uploads: `mavlora.soak_heap_growth_pct` (≤ 5 %), `.soak_commands_acked_not_executed`, `.soak_commands_executed_twice`, `.soak_mission_mismatch_on_accept`, `.soak_radio_unbalanced_bytes` (= 0), `.soak_last_position_age_s` (≤ 3 s) |
//!
//! Each phase's log and `results.json` carry its figures; they are not copied here, where
//! they would go stale. `target/release/rig run rigs/emulated.toml --filter
//! mavlora::simulated` measures them again; `firmware/mavlora/docs/measurements.md` keeps
//! the figures measured along the way, each with its command.

pub mod blind_drone;
pub mod c2_latency;
pub mod duty_cycle;
pub mod mission;
pub mod soak;
pub mod sweep;
pub mod table_ii;

use anyhow::{Context, Result};
use mavlora::bridge::BridgeConfig;
use mavlora::filter::Profile;
use mavlora::router::RouterConfig;
use serde::{Deserialize, Serialize};

use crate::measurement::{Declarations, Dimension, SIMULATED, Spec};
use crate::runner::PhaseContext;
use harness_radio::{GilbertElliott, LinkConfig, Preset, RadioSetup};
pub use harness_sim::{direction_capacity, scheduler_for};

/// One scenario: its measurements (with built-in limits) and its script.
pub struct Scenario {
    /// Short name, unique among these: `table_ii`.
    pub name: &'static str,
    /// What it shows, for the report.
    pub summary: &'static str,
    /// Declares the measurements, with their built-in limits for these
    /// radios, and returns the script that records every one of them.
    pub plan: fn(&mut Declarations, &Radios) -> Script,
}

/// A scenario's script, holding the handles of the measurements it declared.
pub type Script = Box<dyn FnOnce(&mut PhaseContext, &Radios) -> Result<()> + Send>;

/// A measurement of MavLora in a simulated world (device `mavlora`,
/// transport [`SIMULATED`], which stays out of the flat name).
pub fn spec(base: &str, unit: &str) -> Spec {
    Spec::new(base, unit)
        .dim(Dimension::Device, "mavlora")
        .dim(Dimension::Transport, SIMULATED)
}

/// Every simulated MavLora scenario, in the order they run.
pub fn scenarios() -> Vec<Scenario> {
    vec![
        table_ii::SCENARIO,
        mission::SCENARIO,
        c2_latency::SCENARIO,
        sweep::SCENARIO,
        blind_drone::SCENARIO,
        duty_cycle::SCENARIO,
        soak::SCENARIO,
    ]
}

/// The radios the scenarios use, and the seed of the run. A rig file may
/// replace each; [`Radios::paper_defaults`] are the built-ins.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Radios {
    /// Table II's carrier for the bridge variants; `None`: an ideal wire (the `wired`
    /// variant always runs on one).
    pub table_ii: Option<RadioSetup>,
    /// Mission uploads: measurement key (`lora_sf7`) and radio.
    pub mission: Vec<(String, RadioSetup)>,
    /// Command latency (SORA's TMPR bound).
    pub c2: RadioSetup,
    /// Command latency against the project's target (SiK 64k, 10 % loss each way) and the
    /// command mix's exactly-once counts.
    pub c2_target: RadioSetup,
    /// Attenuation sweep, one preset each (their link configs give seeds and latency; the
    /// sweep sets the attenuation).
    pub sweep: Vec<RadioSetup>,
    /// Blind drone: the radio before the drone's receiver goes deaf.
    pub blind_drone: RadioSetup,
    /// Duty cycle of compact telemetry.
    pub duty: RadioSetup,
    /// Mixed into every random source (flight controller, radio directions), so one number
    /// reruns or varies a whole run.
    pub seed: u64,
}

impl Default for Radios {
    fn default() -> Self {
        Radios::paper_defaults()
    }
}

/// Mean loss of the paper's real flight, rounded (Table III: 10.1 % UAV→GCS, 7.5 % GCS→UAV).
pub const PAPER_LOSS: f64 = 0.10;
/// Mean length of a fade (the burst chain's bad state), ms: the paper saw loss "distributed
/// throughout the flight", so short fades, not outages. The chain steps in time, so this is
/// one second whatever the packet rate; a packet is lost if a fade overlaps it, so long
/// LoRa packets (up to 0.4 s on air) are lost somewhat more often than the 10 % share of
/// time in fades (12–14 % measured; 0.5 s fades gave 14.1 %).
pub const BURST_MS: f64 = 1000.0;

fn lossy(seed: u64, loss: f64) -> LinkConfig {
    LinkConfig {
        burst: Some(GilbertElliott::with_mean(loss, BURST_MS).expect("valid mean loss")),
        latency_ms: 5.0,
        seed,
        ..LinkConfig::default()
    }
}

/// Independent loss of `loss` per air packet, whatever its length.
fn independent(seed: u64, loss: f64) -> LinkConfig {
    LinkConfig {
        packet_loss: loss,
        latency_ms: 5.0,
        seed,
        ..LinkConfig::default()
    }
}

fn clean(seed: u64) -> LinkConfig {
    LinkConfig {
        latency_ms: 5.0,
        seed,
        ..LinkConfig::default()
    }
}

fn setup(name: &str, downlink: LinkConfig, uplink: LinkConfig) -> RadioSetup {
    let mut s = RadioSetup::builtin(name).expect("built-in preset");
    s.downlink = downlink;
    s.uplink = uplink;
    s
}

impl Radios {
    /// Built-ins: an ideal wire for Table II; LoRa SF7 and SiK 64 kbps with 10 % bursty loss
    /// both ways (10 % of the time in 1 s fades) for missions; LoRa SF7 with 10 %
    /// independent loss per packet for commands (the paper found its loss spread over the
    /// flight); the three bench presets
    /// for the sweep; SiK at 400 m for the blind drone (the radio module's doc example);
    /// loss-free LoRa SF7 for the duty cycle. Seed 1.
    pub fn paper_defaults() -> Radios {
        Radios {
            table_ii: None,
            mission: vec![
                (
                    "lora_sf7".into(),
                    setup("lora-sf7", lossy(11, PAPER_LOSS), lossy(12, PAPER_LOSS)),
                ),
                (
                    "sik_64k".into(),
                    setup("sik-64k", lossy(21, PAPER_LOSS), lossy(22, PAPER_LOSS)),
                ),
            ],
            c2: setup(
                "lora-sf7",
                independent(31, PAPER_LOSS),
                independent(32, PAPER_LOSS),
            ),
            c2_target: setup(
                "sik-64k",
                independent(33, PAPER_LOSS),
                independent(34, PAPER_LOSS),
            ),
            sweep: ["sik-64k", "lora-sf7", "dmd-dl1"]
                .iter()
                .enumerate()
                .map(|(i, n)| setup(n, clean(41 + i as u64), clean(51 + i as u64)))
                .collect(),
            blind_drone: {
                let mut s = setup("sik-64k", clean(61), clean(62));
                let at = harness_radio::LinkBudget {
                    path: harness_radio::PathLoss::DistanceM(400.0),
                    ..Default::default()
                };
                s.downlink.budget = at;
                s.uplink.budget = at;
                s
            },
            duty: setup("lora-sf7", clean(71), clean(72)),
            seed: 1,
        }
    }

    /// `setup` with its direction seeds mixed with the run's seed.
    pub fn seeded(&self, setup: &RadioSetup) -> RadioSetup {
        let mut s = setup.clone();
        s.downlink.seed = mix(self.seed, s.downlink.seed);
        s.uplink.seed = mix(self.seed, s.uplink.seed);
        s
    }
}

/// Two seeds into one (SplitMix64's finaliser over their combination).
pub fn mix(a: u64, b: u64) -> u64 {
    let mut z = a.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ b.rotate_left(17);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Bridge and router settings for a profile (text), compact telemetry on or off, over a
/// radio of `preset` (`None`: an ideal wire).
pub fn mavlora_configs(
    profile: &str,
    profile_name: &str,
    compact: bool,
    preset: Option<&Preset>,
) -> Result<(BridgeConfig, RouterConfig)> {
    let profile = Profile::parse(profile, profile_name)
        .with_context(|| format!("MavLora profile {profile_name}"))?;
    let budget = scheduler_for(preset);
    // The batching the profile's [compact] table sets, as the bridge program takes it.
    let batching = profile.compact().unwrap_or_default();
    let mut b = BridgeConfig::new(profile, budget);
    b.compact = compact.then_some(batching);
    let mut r = RouterConfig::new(budget);
    if preset.is_none() {
        // An ideal wire has no radio budget for link monitoring to take its share of (its
        // nominal rate would buy a report every 0.5 s): monitor as on the LoRa SF7 channel
        // the paper's compact figures are for.
        b.quality = mavlora::quality::LinkQualityConfig::default();
        r.quality = mavlora::quality::LinkQualityConfig::default();
    }
    Ok((b, r))
}

/// Nearest-rank quantile of sorted samples, shared with the real-time scenarios.
pub use crate::stats::quantile;

/// Creates the phase folder for evidence files.
pub fn evidence_dir(ctx: &PhaseContext) -> Result<std::path::PathBuf> {
    std::fs::create_dir_all(&ctx.dir).with_context(|| format!("creating {}", ctx.dir.display()))?;
    Ok(ctx.dir.clone())
}

#[cfg(test)]
mod tests;
