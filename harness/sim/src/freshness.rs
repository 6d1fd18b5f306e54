//! Compact telemetry's two figures that trade against each other: bytes per second on the
//! downlink and how fresh the positions are at the ground. One run flies a simulated autopilot
//! through the real bridge and router, signed as the binaries always are, with link
//! monitoring paced as the binaries pace it, over a radio of the rig file's kind, and reads:
//!
//! - B/s handed to the radio on the drone's side (everything: compact frames, link-quality
//!   reports, whatever else the profile lets through), and the share of time on air;
//! - at the ground station, `GLOBAL_POSITION_INT` per second, the age of each (arrival minus
//!   its `time_boot_ms`: the autopilot's clock starts with the world's) at the 50th and 95th
//!   percentile and at most, and the longest wait between two arrivals that brought a newer
//!   position.

use harness_radio::{GilbertElliott, LinkConfig, Preset, RadioSetup};
use mavlora::bridge::BridgeConfig;
use mavlora::compact::CompactConfig;
use mavlora::filter::Profile;
use mavlora::quality::LinkQualityConfig;
use mavlora::router::RouterConfig;
use mavlora::schedule::DEFAULT_RADIO_BACKLOG;
use mavlora::signing::{SigningConfig, SigningKey};
use mavlora::{Duration, Instant};

use crate::autopilot::{ArduPilotConfig, ArduPilotFc, Autopilot, Flight, PX4_NORMAL, Px4Fc, Route};
use crate::world::World;
use crate::{Direction, scheduler_for};

/// The radios the rig file flies compact telemetry over (`rigs/emulated.toml`): the two
/// presets, clean, and with its bursty loss (10 % of the time in fades: 1 s on LoRa, 250 ms
/// on SiK).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FreshnessRadio {
    /// SiK 64 kbit/s, no loss.
    Sik,
    /// LoRa SF7/125 kHz, no loss.
    Lora,
    /// SiK 64k with the rig's `sik-64k-bursty` fades.
    SikBursty,
    /// LoRa SF7 with the rig's `lora-sf7-bursty` fades.
    LoraBursty,
}

impl FreshnessRadio {
    /// All four, clean first.
    pub const ALL: [FreshnessRadio; 4] = [
        FreshnessRadio::Sik,
        FreshnessRadio::Lora,
        FreshnessRadio::SikBursty,
        FreshnessRadio::LoraBursty,
    ];

    /// Its name in the rig file.
    pub fn name(self) -> &'static str {
        match self {
            FreshnessRadio::Sik => "sik-64k",
            FreshnessRadio::Lora => "lora-sf7",
            FreshnessRadio::SikBursty => "sik-64k-bursty",
            FreshnessRadio::LoraBursty => "lora-sf7-bursty",
        }
    }

    /// Whether it loses packets.
    pub fn lossy(self) -> bool {
        matches!(self, FreshnessRadio::SikBursty | FreshnessRadio::LoraBursty)
    }

    /// Its preset.
    pub fn preset(self) -> Preset {
        match self {
            FreshnessRadio::Sik | FreshnessRadio::SikBursty => Preset::sik_64k(),
            FreshnessRadio::Lora | FreshnessRadio::LoraBursty => Preset::lora_sf7(),
        }
    }

    /// The radio, its random draws seeded from `seed`.
    pub fn setup(self, seed: u64) -> RadioSetup {
        let (preset, fade_ms) = match self {
            FreshnessRadio::Sik => ("sik-64k", None),
            FreshnessRadio::Lora => ("lora-sf7", None),
            FreshnessRadio::SikBursty => ("sik-64k", Some(250.0)),
            FreshnessRadio::LoraBursty => ("lora-sf7", Some(1000.0)),
        };
        let mut setup = RadioSetup::builtin(preset).expect("built-in preset");
        if let Some(fade_ms) = fade_ms {
            // 10 % of the time in fades of `fade_ms` on average, as the rig file says:
            // p_bad_to_good = 1/fade, p_good_to_bad = share·p_bg/(1 − share).
            let p_bg = 1.0 / fade_ms;
            let link = |seed| LinkConfig {
                seed,
                latency_ms: 5.0,
                burst: Some(GilbertElliott {
                    p_good_to_bad: 0.1 * p_bg / 0.9,
                    p_bad_to_good: p_bg,
                    loss_good: 0.0,
                    loss_bad: 1.0,
                }),
                ..LinkConfig::default()
            };
            setup.downlink = link(seed.wrapping_mul(2).wrapping_add(1));
            setup.uplink = link(seed.wrapping_mul(2).wrapping_add(2));
        }
        setup
    }
}

/// Which simulated autopilot flies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FreshnessAutopilot {
    /// The PX4-like one on its Normal profile, with `profiles/px4-compact.toml`.
    Px4,
    /// The ArduPilot-like one (MAVLink 1, 4 Hz groups), with `profiles/ardupilot-compact.toml`.
    ArduPilot,
}

impl FreshnessAutopilot {
    /// Its name in the tables.
    pub fn name(self) -> &'static str {
        match self {
            FreshnessAutopilot::Px4 => "px4",
            FreshnessAutopilot::ArduPilot => "ardupilot",
        }
    }

    /// The shipped compact profile it flies with.
    pub fn profile_text(self) -> &'static str {
        match self {
            FreshnessAutopilot::Px4 => crate::profiles::PX4_COMPACT_TOML,
            FreshnessAutopilot::ArduPilot => crate::profiles::ARDUPILOT_COMPACT_TOML,
        }
    }
}

/// What one run measured.
#[derive(Debug, Clone, PartialEq)]
pub struct Freshness {
    /// Bytes per second the bridge handed to the radio, everything included.
    pub down_bytes_per_s: f64,
    /// Of those, per message id.
    pub down_by_id: Vec<(u32, f64)>,
    /// Share of the time the drone's radio was on air (0..=1).
    pub down_duty: f64,
    /// `GLOBAL_POSITION_INT` at the ground per second.
    pub position_hz: f64,
    /// Position age at the ground, 50th percentile, s.
    pub age_p50_s: f64,
    /// 95th percentile, s.
    pub age_p95_s: f64,
    /// Oldest, s.
    pub age_max_s: f64,
    /// Longest time between two arrivals of a newer position, s.
    pub max_gap_s: f64,
}

/// One run: `autopilot` with its shipped profile (`profile_text` to fly another), the bridge
/// compacting with `compact`, over `radio` seeded with `seed`, measured from `from_s` to
/// `until_s` of flight (the paper's route, 513 s, then landed at home).
#[derive(Debug, Clone)]
pub struct FreshnessRun {
    /// The autopilot.
    pub autopilot: FreshnessAutopilot,
    /// Profile text; `None`: the autopilot's shipped compact profile.
    pub profile_text: Option<String>,
    /// The compactor's settings; `None`: what the profile's `[compact]` table says.
    pub compact: Option<CompactConfig>,
    /// The radio.
    pub radio: FreshnessRadio,
    /// Seed of the radio and the autopilot.
    pub seed: u64,
    /// Start of the measurement, s.
    pub from_s: f64,
    /// End of the run, s.
    pub until_s: f64,
}

impl FreshnessRun {
    /// The PX4-like autopilot with its shipped profile over `radio`, seed 1, measured from
    /// 20 s to 500 s (cruise and the descent of the paper's route).
    pub fn new(autopilot: FreshnessAutopilot, radio: FreshnessRadio) -> Self {
        Self {
            autopilot,
            profile_text: None,
            compact: None,
            radio,
            seed: 1,
            from_s: 20.0,
            until_s: 500.0,
        }
    }

    /// Flies it and measures.
    pub fn measure(&self) -> Freshness {
        let text = self
            .profile_text
            .as_deref()
            .unwrap_or(self.autopilot.profile_text());
        let profile = Profile::parse(text, "freshness").expect("profile parses");
        let preset = self.radio.preset();
        let budget = scheduler_for(Some(&preset));
        let mut b = BridgeConfig::new(profile.clone(), budget);
        // As the binaries run it (the router: none).
        b.radio_backlog = Some(DEFAULT_RADIO_BACKLOG);
        b.compact = Some(
            self.compact
                .unwrap_or_else(|| profile.compact().unwrap_or_default()),
        );
        b.signing = Some(signing(1));
        // Paced as the binaries pace it: a share of the budget, for signed reports.
        b.quality = LinkQualityConfig::for_budget(budget.rate_bytes_per_s, true);
        let mut r = RouterConfig::new(budget);
        r.signing = Some(signing(2));
        r.quality = LinkQualityConfig::for_budget(budget.rate_bytes_per_s, true);
        let setup = self.radio.setup(self.seed);
        let flight = Flight::Route(Route::PAPER);
        match self.autopilot {
            FreshnessAutopilot::Px4 => {
                let fc = Px4Fc::new(PX4_NORMAL, Instant::ZERO, self.seed).with_flight(flight);
                self.fly(World::new(fc, Some((b, r)), Some(&setup)).expect("world"))
            }
            FreshnessAutopilot::ArduPilot => {
                let fc = ArduPilotFc::new(ArduPilotConfig::default(), Instant::ZERO, self.seed)
                    .with_flight(flight);
                self.fly(World::new(fc, Some((b, r)), Some(&setup)).expect("world"))
            }
        }
    }

    fn fly<A: Autopilot>(&self, mut w: World<A>) -> Freshness {
        let from = crate::secs(self.from_s);
        let until = crate::secs(self.until_s);
        w.run_until(from);
        let sent_before = w.sent(Direction::Downlink).clone();
        let air_before = w
            .link_stats(Direction::Downlink)
            .map_or(Duration::ZERO, |s| s.airtime);
        w.run_until(until);
        let span = (self.until_s - self.from_s).max(1e-9);
        let sent = w.sent(Direction::Downlink).since(&sent_before);
        let air = w
            .link_stats(Direction::Downlink)
            .map_or(Duration::ZERO, |s| s.airtime)
            .as_secs_f64()
            - air_before.as_secs_f64();
        let positions: Vec<(Instant, u32)> = w
            .gcs
            .positions
            .iter()
            .copied()
            .filter(|(t, _)| *t >= from)
            .collect();
        let mut ages: Vec<f64> = positions
            .iter()
            .map(|(t, ms)| {
                t.saturating_duration_since(Instant::from_millis(u64::from(*ms)))
                    .as_secs_f64()
            })
            .collect();
        ages.sort_by(f64::total_cmp);
        let max_gap = longest_wait_for_news(&positions, from, until);
        Freshness {
            down_bytes_per_s: sent.total_bytes() as f64 / span,
            down_by_id: sent
                .bytes
                .iter()
                .map(|(id, b)| (*id, *b as f64 / span))
                .collect(),
            down_duty: air / span,
            position_hz: positions.len() as f64 / span,
            age_p50_s: quantile(&ages, 0.50),
            age_p95_s: quantile(&ages, 0.95),
            age_max_s: ages.last().copied().unwrap_or(f64::INFINITY),
            max_gap_s: max_gap.as_secs_f64(),
        }
    }
}

/// How long changes of mode and arming take from the autopilot to the ground: the PX4-like
/// autopilot flies the paper's route over `radio` (seeded with `seed`) with its shipped
/// compact profile and switches mode (AUTO.MISSION ⇄ POSCTL, and disarms and arms again every
/// fourth change) every 7.3 s from 20 s to `until_s`; each change is timed from the first
/// HEARTBEAT of the autopilot that showed it to the first at the ground station that did.
/// A change the ground never saw (the next came first) counts as infinite.
pub fn mode_latencies(radio: FreshnessRadio, seed: u64, until_s: f64) -> Vec<f64> {
    let text = FreshnessAutopilot::Px4.profile_text();
    let profile = Profile::parse(text, "freshness").expect("profile parses");
    let budget = scheduler_for(Some(&radio.preset()));
    let mut b = BridgeConfig::new(profile.clone(), budget);
    b.radio_backlog = Some(DEFAULT_RADIO_BACKLOG);
    b.compact = Some(profile.compact().unwrap_or_default());
    b.signing = Some(signing(1));
    b.quality = LinkQualityConfig::for_budget(budget.rate_bytes_per_s, true);
    let mut r = RouterConfig::new(budget);
    r.signing = Some(signing(2));
    r.quality = LinkQualityConfig::for_budget(budget.rate_bytes_per_s, true);
    let fc = Px4Fc::new(PX4_NORMAL, Instant::ZERO, seed).with_flight(Flight::Route(Route::PAPER));
    let mut w = World::new(fc, Some((b, r)), Some(&radio.setup(seed))).expect("world");
    let mut k = 0u32;
    loop {
        let at = 20.0 + 7.3 * f64::from(k);
        if at >= until_s {
            break;
        }
        w.run_until(crate::secs(at));
        let custom_mode = if k.is_multiple_of(2) {
            0x0003_0000
        } else {
            0x0404_0000
        };
        w.fc.set_mode(custom_mode, k % 4 != 3);
        k += 1;
    }
    w.run_until(crate::secs(until_s + 5.0));
    let sent: Vec<(Instant, u32, bool)> =
        w.fc.modes_sent()
            .iter()
            .copied()
            .filter(|(t, _, _)| *t >= crate::secs(20.0))
            .collect();
    sent.iter()
        .map(|&(at, m, a)| {
            w.gcs
                .modes
                .iter()
                .find(|&&(t, gm, ga)| t >= at && (gm, ga) == (m, a))
                .filter(|&&(t, _, _)| {
                    // not a later change back to the same mode
                    sent.iter()
                        .find(|&&(t2, _, _)| t2 > at)
                        .is_none_or(|&(t2, _, _)| t < t2)
                })
                .map_or(f64::INFINITY, |&(t, _, _)| {
                    t.saturating_duration_since(at).as_secs_f64()
                })
        })
        .collect()
}

/// Nearest-rank quantile of sorted samples (infinite when there are none).
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::INFINITY;
    }
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// The radio key both ends hold (any key: what is measured is its bytes).
/// The longest the ground waited, from `from` to `until`, for a position newer than the newest
/// it had: `positions` are (arrival, the vehicle's `time_boot_ms`) in arrival order.
pub(crate) fn longest_wait_for_news(
    positions: &[(Instant, u32)],
    from: Instant,
    until: Instant,
) -> Duration {
    let mut newest: Option<u32> = None;
    let mut last_new = from;
    let mut max_gap = Duration::ZERO;
    for (t, ms) in positions {
        if newest.is_none_or(|n| *ms > n) {
            newest = Some(*ms);
            max_gap = max_gap.max(t.saturating_duration_since(last_new));
            last_new = *t;
        }
    }
    max_gap.max(until.saturating_duration_since(last_new))
}

/// The test key both ends of a simulated link sign with.
pub(crate) fn signing(link_id: u8) -> SigningConfig {
    SigningConfig {
        key: SigningKey([7; 32]),
        link_id,
        epoch: 3_000_000_000,
        state: Default::default(),
    }
}
