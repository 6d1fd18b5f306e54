//! Faults a link adds on top of loss, per direction: bit errors in what is
//! delivered, duplicated packets, packets overtaken by later ones, and
//! scheduled silences (the far radio hears nothing: a fade, a reboot, a
//! cable pulled on the bench).
//!
//! A rig file writes them in a direction's table:
//!
//! ```toml
//! bit_error_rate = 1e-5                        # each delivered bit flipped with this probability
//! duplicate = 0.01                             # share of delivered packets handed over twice
//! reorder = { share = 0.02, delay_ms = 80.0 }  # share held back this long: later ones overtake
//! silences = [{ at_s = 20.0, for_s = 3.0 }, { at_s = 60.0, for_s = 0.5, every_s = 30.0 }]
//! ```
//!
//! Each kind draws from its own ChaCha stream of the direction's seed, so
//! turning one on does not reshuffle the loss, jitter or another fault's draws.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use timebase::{Duration, Instant};

use super::error::{ConfigError, check_range};
use super::preset::ms;

/// A share of packets delivered late by a fixed extra delay, so packets sent
/// after them arrive first (a retransmitting radio, a multipath receiver).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reorder {
    /// Share of delivered packets held back, 0..=1.
    pub share: f64,
    /// How long one is held back, ms.
    pub delay_ms: f64,
}

/// A time when everything on air in this direction is lost.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Silence {
    /// Start, seconds after the link's time zero.
    pub at_s: f64,
    /// Length, seconds.
    pub for_s: f64,
    /// Repeats with this period from `at_s`, seconds (> `for_s`); once if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub every_s: Option<f64>,
}

impl Silence {
    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        check_range("silences.at_s", self.at_s, 0.0, 1e9, "0..=1e9 s")?;
        check_range("silences.for_s", self.for_s, 1e-6, 1e9, "(0, 1e9] s")?;
        if let Some(every) = self.every_s {
            check_range(
                "silences.every_s",
                every - self.for_s,
                1e-6,
                1e9,
                "longer than for_s",
            )?;
        }
        Ok(())
    }

    /// Whether `[start, end)` overlaps this silence (any repetition).
    pub fn overlaps(&self, start: Instant, end: Instant) -> bool {
        let (from, len) = (secs(self.at_s), ms(self.for_s * 1000.0));
        if end <= from {
            return false;
        }
        let Some(every) = self.every_s.map(|e| ms(e * 1000.0)) else {
            return start < from + len;
        };
        // The last repetition starting at or before `start`, and the next one.
        let k = start.saturating_duration_since(from).as_micros() / every.as_micros();
        let this = from + Duration::from_micros(k * every.as_micros());
        start < this + len || end > this + every
    }

    /// End of the repetition covering `t`, if `t` is inside one.
    pub fn end_if_inside(&self, t: Instant) -> Option<Instant> {
        let (from, len) = (secs(self.at_s), ms(self.for_s * 1000.0));
        if t < from {
            return None;
        }
        let this = match self.every_s.map(|e| ms(e * 1000.0)) {
            None => from,
            Some(every) => {
                let k = (t - from).as_micros() / every.as_micros();
                from + Duration::from_micros(k * every.as_micros())
            }
        };
        (t < this + len).then_some(this + len)
    }
}

fn secs(s: f64) -> Instant {
    Instant::ZERO + ms(s * 1000.0)
}

/// The fault settings of one direction, as [`LinkConfig`](super::LinkConfig) carries them.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct FaultConfig {
    pub bit_error_rate: f64,
    pub duplicate: f64,
    pub reorder: Option<Reorder>,
    pub silences: Vec<Silence>,
}

impl FaultConfig {
    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        check_range("bit_error_rate", self.bit_error_rate, 0.0, 0.5, "0..=0.5")?;
        check_range("duplicate", self.duplicate, 0.0, 1.0, "0..=1")?;
        if let Some(r) = &self.reorder {
            check_range("reorder.share", r.share, 0.0, 1.0, "0..=1")?;
            check_range(
                "reorder.delay_ms",
                r.delay_ms,
                0.0,
                600_000.0,
                "0..=600000 ms",
            )?;
        }
        self.silences.iter().try_for_each(Silence::validate)
    }
}

/// ChaCha streams of the fault draws (0: loss and jitter, 1: burst chain).
const REPEAT_STREAM: u64 = 2;
const CORRUPT_STREAM: u64 = 3;

/// The faults of one direction, with their random sources.
#[derive(Debug, Clone)]
pub(crate) struct Faults {
    config: FaultConfig,
    reorder_delay: Duration,
    /// Duplicate and reorder draws: two per delivered packet.
    repeat_rng: ChaCha8Rng,
    /// Bit-error draws: as many as there are errors, plus one.
    corrupt_rng: ChaCha8Rng,
}

/// What happens to one packet that reached the far radio.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Fate {
    /// Bits flipped in it.
    pub flipped: u64,
    /// Handed over a second time right after the first.
    pub duplicated: bool,
    /// Held back this long more: later packets overtake it.
    pub held: Option<Duration>,
}

impl Faults {
    pub(crate) fn new(config: FaultConfig, seed: u64) -> Faults {
        let rng = |stream| {
            let mut r = ChaCha8Rng::seed_from_u64(seed);
            r.set_stream(stream);
            r
        };
        Faults {
            reorder_delay: config.reorder.map_or(Duration::ZERO, |r| ms(r.delay_ms)),
            config,
            repeat_rng: rng(REPEAT_STREAM),
            corrupt_rng: rng(CORRUPT_STREAM),
        }
    }

    /// Whether a packet on air over `[start, end)` falls in a silence.
    pub(crate) fn silenced(&self, start: Instant, end: Instant) -> bool {
        self.config.silences.iter().any(|s| s.overlaps(start, end))
    }

    /// Adds a silence to those configured (a fault a test schedules while the link runs).
    pub(crate) fn add_silence(&mut self, silence: Silence) -> Result<(), ConfigError> {
        silence.validate()?;
        self.config.silences.push(silence);
        Ok(())
    }

    /// End of the silence covering `t`, if one does.
    pub(crate) fn silence_end(&self, t: Instant) -> Option<Instant> {
        self.config
            .silences
            .iter()
            .filter_map(|s| s.end_if_inside(t))
            .max()
    }

    /// The fate of a received packet; flips its bits in place.
    pub(crate) fn apply(&mut self, data: &mut [u8]) -> Fate {
        let flipped = flip_bits(&mut self.corrupt_rng, self.config.bit_error_rate, data);
        let u_dup: f64 = self.repeat_rng.random();
        let u_reorder: f64 = self.repeat_rng.random();
        let held = self
            .config
            .reorder
            .filter(|r| u_reorder < r.share)
            .map(|_| self.reorder_delay);
        Fate {
            flipped,
            duplicated: u_dup < self.config.duplicate,
            held,
        }
    }
}

/// Flips each bit of `data` with probability `ber`, jumping from one error to the
/// next (geometric gaps) rather than drawing per bit; returns how many flipped.
fn flip_bits(rng: &mut ChaCha8Rng, ber: f64, data: &mut [u8]) -> u64 {
    if ber <= 0.0 {
        return 0;
    }
    let bits = data.len() as u64 * 8;
    let log_keep = (1.0 - ber).ln();
    let mut at = 0u64;
    let mut flipped = 0;
    loop {
        let u: f64 = rng.random();
        // Bits kept before the next error: P(gap = k) = (1 − ber)^k · ber.
        let gap = ((1.0 - u).ln() / log_keep).floor();
        if !gap.is_finite() || gap >= (bits - at) as f64 {
            return flipped;
        }
        at += gap as u64;
        data[(at / 8) as usize] ^= 1 << (at % 8);
        flipped += 1;
        at += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(s: f64) -> Instant {
        secs(s)
    }

    #[test]
    fn the_module_doc_example_parses_into_a_direction() {
        let example: String = include_str!("faults.rs")
            .lines()
            .skip_while(|l| !l.starts_with("//! ```toml"))
            .skip(1)
            .take_while(|l| !l.starts_with("//! ```"))
            .map(|l| format!("{}\n", l.trim_start_matches("//!").trim_start()))
            .collect();
        let cfg: crate::LinkConfig = toml::from_str(&example).unwrap();
        assert_eq!(cfg.bit_error_rate, 1e-5);
        assert_eq!(cfg.reorder.unwrap().delay_ms, 80.0);
        assert_eq!(cfg.silences[1].every_s, Some(30.0));
        cfg.fault_config().validate().unwrap();
        // A misspelt knob is refused, not ignored.
        assert!(toml::from_str::<crate::LinkConfig>("duplicates = 0.1").is_err());
        assert!(
            toml::from_str::<crate::LinkConfig>("silences = [{ at_s = 1.0, len_s = 2.0 }]")
                .is_err()
        );
    }

    #[test]
    fn a_silence_covers_its_interval_and_repeats() {
        let once = Silence {
            at_s: 10.0,
            for_s: 2.0,
            every_s: None,
        };
        assert!(!once.overlaps(t(9.0), t(10.0)));
        assert!(once.overlaps(t(9.9), t(10.1)));
        assert!(once.overlaps(t(11.9), t(12.5)));
        assert!(!once.overlaps(t(12.0), t(13.0)));
        assert_eq!(once.end_if_inside(t(11.0)), Some(t(12.0)));
        assert_eq!(once.end_if_inside(t(12.0)), None);
        let every = Silence {
            every_s: Some(30.0),
            ..once
        };
        assert!(every.overlaps(t(41.0), t(41.1)));
        assert!(!every.overlaps(t(42.0), t(69.9)));
        assert!(every.overlaps(t(69.9), t(70.1)));
        assert_eq!(every.end_if_inside(t(100.5)), Some(t(102.0)));
    }

    #[test]
    fn silences_that_cannot_be_honoured_are_refused() {
        let bad = Silence {
            at_s: 0.0,
            for_s: 5.0,
            every_s: Some(5.0),
        };
        assert!(bad.validate().unwrap_err().to_string().contains("every_s"));
        let negative = Silence {
            at_s: -1.0,
            for_s: 1.0,
            every_s: None,
        };
        assert!(negative.validate().is_err());
    }

    #[test]
    fn bit_errors_hit_at_the_configured_rate_and_nowhere_else() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (ber, len, rounds) = (1e-3, 256, 400);
        let mut flipped = 0;
        for _ in 0..rounds {
            let mut data = vec![0u8; len];
            let n = flip_bits(&mut rng, ber, &mut data);
            // The count returned is exactly the bits set.
            assert_eq!(n, data.iter().map(|b| b.count_ones() as u64).sum::<u64>());
            flipped += n;
        }
        let expected = ber * (len * 8 * rounds) as f64; // 819
        assert!(
            (flipped as f64 - expected).abs() < 4.0 * expected.sqrt(),
            "{flipped} flips, expected {expected}"
        );
        let mut clean = vec![0x55u8; len];
        assert_eq!(flip_bits(&mut rng, 0.0, &mut clean), 0);
        assert!(clean.iter().all(|&b| b == 0x55));
    }
}
