//! Loss: a link budget through a packet-error curve, bursty loss
//! (Gilbert-Elliott, stepped in time), and fixed latency plus jitter.
//!
//! # The packet-error curve and its fit
//!
//! Received power P_rx = P_tx + G_tx + G_rx − L_cable − L_path, with L_path
//! either a direct attenuation in dB (the paper's step attenuator) or free
//! space, L = 20·log10(d_km) + 20·log10(f_MHz) + 32.44. The margin is
//! M = P_rx − (S + N), S the preset's sensitivity and N a receiver
//! desensitisation (a drone's own RF noise, set per direction). A packet as
//! long on air as the reference packet (21 data bytes, a MAVLink v2 HEARTBEAT)
//! is lost with probability
//!
//! PER_ref(M) = 1 / (1 + 99·exp(M / w))
//!
//! a logistic that is 1 % at M = 0, 50 % at M = −w·ln 99 ≈ −4.6·w and 0.1 % at
//! M ≈ +2.3·w. Longer packets fail more often, as independent symbol errors
//! would make them: PER = 1 − (1 − PER_ref)^(T_air / T_air,ref).
//!
//! Fit: S is set so that M = 0 (1 % loss, the last "nominal" step) falls at
//! the attenuation where the paper's Fig. 1 shows loss rising, with the
//! paper's powers and 0 dBi antennas, no cable loss: SiK 20 dBm − 84 dB =
//! −64 dBm, LoRa SF7 20 dBm − 120 dB = −100 dBm, DMD 27 dBm − 71 dB = −44 dBm.
//! These are far above the datasheet sensitivities (SiK −104 dBm at 100 kbit/s
//! in the paper's Table I, RFM95 −123 dBm at SF7, DMD −113 dBm): the
//! difference is the bench's own coupling loss (antenna in a shielded box,
//! cables) that the attenuator reading excludes; the fit keeps the paper's
//! free-space ranges (873 m, 55.1 km, 191 m). Widths are assumptions, not read
//! off the figure (the text gives edges only): LoRa 0.5 dB (coded chirps have
//! a sharp cliff: 1 % → 50 % in 2.3 dB), DMD 0.75 dB (3.4 dB), SiK 1 dB
//! (4.6 dB; uncoded GFSK with the drifting centre frequency the paper saw).

use timebase::{Duration, Instant};

use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::error::{ConfigError, check_range};
use super::preset::Preset;

/// Data bytes of the reference packet the error curve is stated for.
pub const REFERENCE_PACKET_BYTES: usize = 21;

/// Free-space path loss in dB: 20·log10(d_km) + 20·log10(f_MHz) + 32.44.
pub fn free_space_path_loss_db(distance_km: f64, frequency_mhz: f64) -> f64 {
    20.0 * distance_km.log10() + 20.0 * frequency_mhz.log10() + 32.44
}

/// The distance at which free space alone loses `loss_db` (the paper's
/// "range in an ideal world"), km.
pub fn free_space_range_km(loss_db: f64, frequency_mhz: f64) -> f64 {
    10f64.powf((loss_db - 32.44 - 20.0 * frequency_mhz.log10()) / 20.0)
}

/// PER of a reference-length packet at a margin: 1 / (1 + 99·exp(M/w)).
pub fn packet_error_rate(margin_db: f64, width_db: f64) -> f64 {
    1.0 / (1.0 + 99.0 * (margin_db / width_db).exp())
}

/// What lies between the transmitter and the receiver.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PathLoss {
    /// A fixed attenuation, dB (a step attenuator, or a measured loss).
    AttenuationDb(f64),
    /// Free space over a distance, metres.
    DistanceM(f64),
}

impl Default for PathLoss {
    fn default() -> Self {
        PathLoss::AttenuationDb(0.0)
    }
}

/// One direction's link budget. The preset gives power, frequency and
/// sensitivity; this gives what differs per installation and direction.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkBudget {
    /// Path loss: attenuation or distance.
    pub path: PathLoss,
    /// Transmit antenna gain, dBi.
    pub tx_antenna_gain_dbi: f64,
    /// Receive antenna gain, dBi.
    pub rx_antenna_gain_dbi: f64,
    /// Cable and connector loss, both ends, dB.
    pub cable_loss_db: f64,
    /// Receiver desensitisation, dB: raises the sensitivity (the paper's
    /// drone whose own noise blinds its receiver; set on GCS→UAV only).
    pub rx_noise_db: f64,
}

impl LinkBudget {
    /// A budget through a direct attenuation with 0 dBi antennas.
    pub fn attenuation(db: f64) -> LinkBudget {
        LinkBudget {
            path: PathLoss::AttenuationDb(db),
            ..LinkBudget::default()
        }
    }

    /// Path loss at the preset's frequency, dB.
    pub fn path_loss_db(&self, frequency_mhz: f64) -> f64 {
        match self.path {
            PathLoss::AttenuationDb(db) => db,
            PathLoss::DistanceM(m) => free_space_path_loss_db(m / 1000.0, frequency_mhz),
        }
    }

    /// Received power, dBm.
    pub fn received_dbm(&self, preset: &Preset) -> f64 {
        preset.tx_power_dbm + self.tx_antenna_gain_dbi + self.rx_antenna_gain_dbi
            - self.cable_loss_db
            - self.path_loss_db(preset.frequency_mhz)
    }

    /// Margin over the (desensitised) sensitivity, dB.
    pub fn margin_db(&self, preset: &Preset) -> f64 {
        self.received_dbm(preset) - (preset.sensitivity_dbm + self.rx_noise_db)
    }

    /// PER of a reference-length packet through this budget.
    pub fn reference_per(&self, preset: &Preset) -> f64 {
        packet_error_rate(self.margin_db(preset), preset.curve_width_db)
    }

    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        match self.path {
            PathLoss::AttenuationDb(db) => {
                check_range("attenuation_db", db, -50.0, 400.0, "-50..=400 dB")?
            }
            PathLoss::DistanceM(m) => check_range("distance_m", m, 1e-3, 1e9, "0.001..=1e9 m")?,
        }
        for (field, v) in [
            ("tx_antenna_gain_dbi", self.tx_antenna_gain_dbi),
            ("rx_antenna_gain_dbi", self.rx_antenna_gain_dbi),
            ("cable_loss_db", self.cable_loss_db),
            ("rx_noise_db", self.rx_noise_db),
        ] {
            check_range(field, v, -100.0, 100.0, "-100..=100 dB")?;
        }
        Ok(())
    }
}

/// Gilbert-Elliott burst loss: a two-state Markov chain stepped once per
/// millisecond of model time ([`GilbertElliott::STEP`]), busy or idle, so a burst
/// lasts as long in time whatever the packet rate (stepped per packet, a quiet
/// uplink with one command a second stretched one burst over seconds). Each
/// millisecond a packet is on air it is hit with `loss_good` or `loss_bad`
/// depending on the state then (a fade kills the packet it overlaps); the
/// chain jumps over idle time in closed form, one draw, so an hour of silence
/// costs nothing. With `loss_good` = 0 and `loss_bad` = 1 (the Gilbert model)
/// the share of time in the bad state is p_gb / (p_gb + p_bg), a burst lasts
/// 1 / p_bg ms on average, and a packet of airtime T ms is lost with about
/// that share plus p_gb·T (a burst starting while it is on air).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GilbertElliott {
    /// Probability of going from good to bad in one millisecond.
    pub p_good_to_bad: f64,
    /// Probability of going from bad to good in one millisecond.
    pub p_bad_to_good: f64,
    /// Loss probability of a packet for each millisecond it is on air in the good state.
    #[serde(default)]
    pub loss_good: f64,
    /// Loss probability of a packet for each millisecond it is on air in the bad state.
    #[serde(default = "one")]
    pub loss_bad: f64,
}

fn one() -> f64 {
    1.0
}

impl GilbertElliott {
    /// The chain's time step.
    pub const STEP: Duration = Duration::from_millis(1);

    /// The Gilbert model with a share of time in the bad state (0..1) and a mean
    /// burst length (ms, ≥ 1): p_bg = 1/burst, p_gb = share·p_bg / (1 − share).
    pub fn with_mean(bad_share: f64, burst_ms: f64) -> Result<GilbertElliott, ConfigError> {
        check_range("bad_share", bad_share, 0.0, 0.999, "0..=0.999")?;
        check_range("burst_ms", burst_ms, 1.0, 1e9, ">= 1 ms")?;
        let p_bad_to_good = 1.0 / burst_ms;
        Ok(GilbertElliott {
            p_good_to_bad: (bad_share * p_bad_to_good / (1.0 - bad_share)).min(1.0),
            p_bad_to_good,
            loss_good: 0.0,
            loss_bad: 1.0,
        })
    }

    /// Share of time spent in the bad state.
    pub fn bad_share(&self) -> f64 {
        self.p_good_to_bad / (self.p_good_to_bad + self.p_bad_to_good)
    }

    /// Long-run loss probability of a packet on air for one step.
    pub fn mean_loss(&self) -> f64 {
        let b = self.bad_share();
        b * self.loss_bad + (1.0 - b) * self.loss_good
    }

    /// Mean stay in the bad state, ms.
    pub fn mean_burst_ms(&self) -> f64 {
        1.0 / self.p_bad_to_good
    }

    /// Probability of being bad `steps` steps after being bad (`from_bad`) or good.
    pub fn p_bad_after(&self, from_bad: bool, steps: u64) -> f64 {
        let (a, b) = (self.p_good_to_bad, self.p_bad_to_good);
        let pi = self.bad_share();
        // (1 − a − b)^n: how much of the start state is left after n steps.
        let memory = (1.0 - a - b).powi(steps.min(i32::MAX as u64) as i32);
        if from_bad {
            pi + (1.0 - pi) * memory
        } else {
            pi * (1.0 - memory)
        }
    }

    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        check_range("p_good_to_bad", self.p_good_to_bad, 0.0, 1.0, "0..=1")?;
        check_range("p_bad_to_good", self.p_bad_to_good, 1e-9, 1.0, "(0, 1]")?;
        check_range("loss_good", self.loss_good, 0.0, 1.0, "0..=1")?;
        check_range("loss_bad", self.loss_bad, 0.0, 1.0, "0..=1")
    }
}

/// The burst chain's state in time.
#[derive(Debug, Clone)]
struct Chain {
    params: GilbertElliott,
    bad: bool,
    /// Index of the step the state is for (model time / STEP).
    step: u64,
    /// The chain's own draws: how many it makes depends on airtime, and must not
    /// shift the independent-loss and jitter draws.
    rng: ChaCha8Rng,
}

impl Chain {
    fn jump_to(&mut self, step: u64) {
        if step <= self.step {
            return;
        }
        let p_bad = self.params.p_bad_after(self.bad, step - self.step);
        self.bad = self.rng.random::<f64>() < p_bad;
        self.step = step;
    }

    /// Whether a packet on air over `[start, start + airtime)` is hit; leaves the
    /// chain at the step after the packet.
    fn hit(&mut self, start: Instant, airtime: Duration) -> bool {
        let step_us = GilbertElliott::STEP.as_micros();
        let first = start.as_micros() / step_us;
        let last = (start.as_micros() + airtime.as_micros())
            .div_ceil(step_us)
            .max(first + 1);
        self.jump_to(first);
        // A packet that starts inside the step where the previous one ended (the
        // chain is already past `first`) is judged from the current step on.
        let from = self.step;
        let mut hit = false;
        for _ in from..last.max(from + 1) {
            let (p_loss, p_move) = if self.bad {
                (self.params.loss_bad, self.params.p_bad_to_good)
            } else {
                (self.params.loss_good, self.params.p_good_to_bad)
            };
            hit |= self.rng.random::<f64>() < p_loss;
            if self.rng.random::<f64>() < p_move {
                self.bad = !self.bad;
            }
            self.step += 1;
        }
        hit
    }
}

/// Decides, packet by packet, whether a packet is lost: the budget's
/// independent loss and a fixed per-packet loss, or'ed with the burst chain
/// stepped in time.
#[derive(Debug, Clone)]
pub struct LossModel {
    reference_per: f64,
    packet_loss: f64,
    chain: Option<Chain>,
}

impl LossModel {
    /// A model losing reference-length packets independently with
    /// `reference_per`, every packet with `packet_loss` whatever its length, plus
    /// the optional burst chain (starting good at time zero, drawing from its own
    /// generator seeded with `seed`).
    pub fn new(
        reference_per: f64,
        packet_loss: f64,
        burst: Option<GilbertElliott>,
        seed: u64,
    ) -> LossModel {
        LossModel {
            reference_per: reference_per.clamp(0.0, 1.0),
            packet_loss: packet_loss.clamp(0.0, 1.0),
            chain: burst.map(|params| {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(BURST_STREAM);
                Chain {
                    params,
                    bad: false,
                    step: 0,
                    rng,
                }
            }),
        }
    }

    /// Whether the packet on air from `start` for `airtime` is lost;
    /// `length_ratio` is its airtime over the reference packet's. Draws exactly
    /// three numbers from `rng` per call, whatever the settings (the budget's,
    /// the fixed packet loss's, one spare that keeps a seed's draws where recorded
    /// runs have them), and the burst knobs draw from the chain's own generator,
    /// so a seed's independent loss is the same with or without bursts.
    pub fn lose<R: Rng + ?Sized>(
        &mut self,
        rng: &mut R,
        start: Instant,
        airtime: Duration,
        length_ratio: f64,
    ) -> bool {
        let u_independent: f64 = rng.random();
        let u_packet: f64 = rng.random();
        let _spare: f64 = rng.random();
        let per = 1.0 - (1.0 - self.reference_per).powf(length_ratio.max(0.0));
        let lost = u_independent < per || u_packet < self.packet_loss;
        let hit = self.chain.as_mut().is_some_and(|c| c.hit(start, airtime));
        lost | hit
    }

    /// Changes the independent loss (a sweep step), keeping the burst state.
    pub fn set_reference_per(&mut self, reference_per: f64) {
        self.reference_per = reference_per.clamp(0.0, 1.0);
    }

    /// Whether the burst chain is in its bad state (as of the last packet).
    pub fn in_bad_state(&self) -> bool {
        self.chain.as_ref().is_some_and(|c| c.bad)
    }
}

/// ChaCha stream of the burst chain (stream 0: independent loss and jitter).
const BURST_STREAM: u64 = 1;

/// A delay drawn uniformly in [0, `max`].
pub(crate) fn jitter<R: Rng + ?Sized>(rng: &mut R, max: Duration) -> Duration {
    if max.is_zero() {
        // Keep the draw so enabling jitter does not shift later loss draws.
        let _: f64 = rng.random();
        return Duration::ZERO;
    }
    // Whole microseconds, rounded up like airtime (a delivery is never early).
    let nanos = std::time::Duration::from(max).mul_f64(rng.random::<f64>());
    Duration::from_micros(nanos.as_nanos().div_ceil(1000) as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_space_reproduces_the_papers_ranges() {
        // 84 dB → 873 m, 120 dB → 55.1 km at 433 MHz, to 0.5 %.
        for (db, km) in [(84.0, 0.873), (120.0, 55.1)] {
            let range = free_space_range_km(db, 433.0);
            assert!((range / km - 1.0).abs() < 0.005, "{db} dB: {range} km");
            assert!((free_space_path_loss_db(km, 433.0) - db).abs() < 0.05);
        }
        // The paper's 191 m for 71 dB is 70.8 dB by this formula (71 dB is 195.7 m).
        assert!((free_space_path_loss_db(0.191, 433.0) - 70.79).abs() < 0.01);
        assert!((free_space_range_km(71.0, 433.0) - 0.1957).abs() < 0.0005);
    }

    #[test]
    fn the_curve_is_one_percent_at_the_fitted_edge() {
        for (preset, edge) in [
            (Preset::sik_64k(), 84.0),
            (Preset::lora_sf7(), 120.0),
            (Preset::dmd_dl1(), 71.0),
        ] {
            let at = |db: f64| LinkBudget::attenuation(db).reference_per(&preset);
            assert!((at(edge) - 0.01).abs() < 1e-9, "{}", preset.name);
            // 3 dB better is nominal, 6 dB worse is mostly lost.
            assert!(at(edge - 3.0) < 0.001, "{}", preset.name);
            assert!(at(edge + 6.0) > 0.5, "{}", preset.name);
            let w = preset.curve_width_db;
            assert!((at(edge + w * 99f64.ln()) - 0.5).abs() < 1e-9);
        }
    }

    #[test]
    fn desensitising_the_receiver_moves_the_edge() {
        let lora = Preset::lora_sf7();
        let blind = LinkBudget {
            rx_noise_db: 20.0,
            ..LinkBudget::attenuation(100.0)
        };
        assert!((blind.reference_per(&lora) - 0.01).abs() < 1e-9);
    }

    #[test]
    fn gilbert_with_mean_round_trips() {
        let ge = GilbertElliott::with_mean(0.1, 5.0).unwrap();
        assert!((ge.mean_loss() - 0.1).abs() < 1e-12);
        assert!((ge.mean_burst_ms() - 5.0).abs() < 1e-12);
        assert!(GilbertElliott::with_mean(1.0, 5.0).is_err());
        assert!(GilbertElliott::with_mean(0.1, 0.5).is_err());
    }
}

#[cfg(test)]
mod burst_tests {
    use super::*;
    use rand::SeedableRng;

    const MS: Duration = Duration::from_millis(1);

    /// Share of lost packets whose next packet, `gap` later, is lost too: one
    /// 1-ms packet every `gap` for `n` packets, Gilbert chain only.
    fn lost_after_lost(ge: GilbertElliott, gap: Duration, n: u64) -> (f64, f64) {
        let mut model = LossModel::new(0.0, 0.0, Some(ge), 5);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let (mut lost, mut pairs, mut both) = (0u64, 0u64, 0u64);
        let mut prev = false;
        for k in 0..n {
            let l = model.lose(&mut rng, Instant::ZERO + gap * k as u32, MS, 1.0);
            lost += l as u64;
            if prev {
                pairs += 1;
                both += l as u64;
            }
            prev = l;
        }
        (lost as f64 / n as f64, both as f64 / pairs as f64)
    }

    /// Regression: the chain stepped once per packet, so on a quiet uplink (one
    /// command a second) a burst of "3 packets" lasted 3 s. Stepped per ms, a loss
    /// 1 s after a loss is as likely as any loss, and 2 ms after one it is likely.
    #[test]
    fn a_bursts_duration_is_independent_of_the_packet_rate() {
        // 50 ms fades, 10 % of the time.
        let ge = GilbertElliott::with_mean(0.1, 50.0).unwrap();
        for (gap_ms, n) in [(2u64, 400_000), (20, 200_000), (1000, 100_000)] {
            let gap = MS * gap_ms as u32;
            let (loss, again) = lost_after_lost(ge, gap, n);
            // A 1-ms packet is hit if it starts bad or the chain turns bad during it.
            let expected_loss = ge.bad_share() + (1.0 - ge.bad_share()) * ge.p_good_to_bad;
            assert!(
                (loss - expected_loss).abs() < 0.01,
                "{gap_ms} ms: loss {loss}"
            );
            // Bad at the next packet, from bad one step after this one started.
            let p_bad = ge.p_bad_after(true, gap_ms - 1);
            let expected = p_bad + (1.0 - p_bad) * ge.p_good_to_bad;
            assert!(
                (again - expected).abs() < 0.03,
                "{gap_ms} ms apart: {again:.3} of losses followed by a loss, expected {expected:.3}"
            );
        }
        // What that means in time: the mean fade is 50 ms whatever the rate.
        let (_, dense) = lost_after_lost(ge, MS * 2, 400_000);
        let (_, sparse) = lost_after_lost(ge, MS * 1000, 100_000);
        assert!(
            dense > 0.9 && sparse < 0.15,
            "dense {dense}, sparse {sparse}"
        );
    }

    #[test]
    fn the_chain_jumps_idle_time_in_closed_form() {
        let ge = GilbertElliott::with_mean(0.2, 10.0).unwrap();
        assert!((ge.p_bad_after(true, 0) - 1.0).abs() < 1e-12);
        assert!(ge.p_bad_after(false, 0).abs() < 1e-12);
        for from_bad in [false, true] {
            assert!((ge.p_bad_after(from_bad, 1_000_000) - 0.2).abs() < 1e-9);
        }
        // One step is the transition probability itself.
        assert!((ge.p_bad_after(false, 1) - ge.p_good_to_bad).abs() < 1e-12);
        assert!((ge.p_bad_after(true, 1) - (1.0 - ge.p_bad_to_good)).abs() < 1e-12);
    }

    #[test]
    fn packet_loss_is_per_packet_whatever_its_length() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for airtime_ms in [1u64, 300] {
            let mut model = LossModel::new(0.0, 0.1, None, 1);
            let n = 50_000;
            let lost = (0..n)
                .filter(|&k| {
                    let t = Instant::ZERO + MS * (k * 1000) as u32;
                    model.lose(&mut rng, t, MS * airtime_ms as u32, airtime_ms as f64)
                })
                .count();
            let share = lost as f64 / n as f64;
            assert!((share - 0.1).abs() < 0.01, "{airtime_ms} ms: {share}");
        }
    }
}
