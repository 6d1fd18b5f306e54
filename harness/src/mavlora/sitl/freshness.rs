//! How fresh the positions a ground station shows are, judged against the vehicle's own clock.
//!
//! Each GLOBAL_POSITION_INT carries `time_boot_ms`, the vehicle's clock when it was
//! sampled. The truth connection gives pairs (CLOCK_MONOTONIC when read, `time_boot_ms`)
//! straight from the autopilot; the smallest `t − time_boot_ms` among them near a moment is
//! the vehicle clock's offset then (the least-delayed message; a local one, because a SITL
//! that falls behind real time drifts). A position's **age** at the ground is then its
//! arrival time minus its sampling time on that clock: what a pilot's map is behind by.
//! A **gap** is the time between two arrivals of newer positions.

use anyhow::Context as _;

use crate::clock::Mono;
use crate::mavlora::fixture::sitl::Position;
use crate::runner::PhaseContext;
use crate::stats;

/// Clock samples this far either side of a position's arrival set its offset.
const OFFSET_SPAN_S: f64 = 5.0;

/// One position as the ground got it, with its age.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aged {
    pub arrived: Mono,
    pub time_boot_ms: u32,
    pub age_s: f64,
}

/// Freshness of the positions that arrived in a window.
#[derive(Debug, Clone, PartialEq)]
pub struct Freshness {
    /// New samples (distinct `time_boot_ms`) per second of the vehicle time they span: the
    /// rate the ground's picture is updated at. Not per second of the window: compact
    /// telemetry delivers three samples a frame, so a window that ends just before a frame
    /// would read 2.9 Hz for a link that missed nothing (29 frames of 3 in 30 s). A stall at
    /// the window's end is `gap_max_s`'s to catch.
    pub rate_hz: f64,
    pub age_p50_s: f64,
    pub age_p95_s: f64,
    pub age_max_s: f64,
    /// Longest time without a new position, window edges included.
    pub gap_max_s: f64,
    pub samples: Vec<Aged>,
}

/// The vehicle clock's offset (`CLOCK_MONOTONIC − time_boot_ms`, s) near `at`, from the truth
/// connection's samples; `None` without any.
fn offset_near(clock: &[(Mono, u32)], at: Mono) -> Option<f64> {
    let offset = |(t, ms): &(Mono, u32)| t.as_secs_f64() - f64::from(*ms) / 1000.0;
    let near = clock
        .iter()
        .filter(|(t, _)| (t.as_secs_f64() - at.as_secs_f64()).abs() <= OFFSET_SPAN_S)
        .map(offset)
        .fold(f64::INFINITY, f64::min);
    if near.is_finite() {
        return Some(near);
    }
    clock.iter().map(offset).reduce(f64::min)
}

/// The freshness of the new positions that arrived at the ground between `from` and `to`;
/// `None` if no clock sample or no position.
pub fn judge(
    ground: &[Position],
    clock: &[(Mono, u32)],
    from: Mono,
    to: Mono,
) -> Option<Freshness> {
    let mut newest: Option<u32> = None;
    let mut samples = Vec::new();
    for p in ground {
        // Only newer samples are news; a repeat or an older one shows nothing new.
        if newest.is_some_and(|n| p.time_boot_ms <= n) {
            continue;
        }
        newest = Some(p.time_boot_ms);
        if p.t.as_secs_f64() < from.as_secs_f64() || p.t.as_secs_f64() > to.as_secs_f64() {
            continue;
        }
        let offset = offset_near(clock, p.t)?;
        samples.push(Aged {
            arrived: p.t,
            time_boot_ms: p.time_boot_ms,
            age_s: p.t.as_secs_f64() - (f64::from(p.time_boot_ms) / 1000.0 + offset),
        });
    }
    if samples.is_empty() {
        return None;
    }
    let mut edges = vec![from.as_secs_f64()];
    edges.extend(samples.iter().map(|s| s.arrived.as_secs_f64()));
    edges.push(to.as_secs_f64());
    let gap_max_s = edges.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    let mut ages: Vec<f64> = samples.iter().map(|s| s.age_s).collect();
    ages.sort_by(f64::total_cmp);
    let window = to.as_secs_f64() - from.as_secs_f64();
    let span_s = match (samples.first(), samples.last()) {
        (Some(a), Some(b)) => f64::from(b.time_boot_ms.saturating_sub(a.time_boot_ms)) / 1000.0,
        _ => 0.0,
    };
    let rate_hz = if samples.len() >= 2 && span_s > 0.0 {
        (samples.len() - 1) as f64 / span_s
    } else {
        samples.len() as f64 / window
    };
    Some(Freshness {
        rate_hz,
        age_p50_s: stats::quantile(&ages, 0.50),
        age_p95_s: stats::quantile(&ages, 0.95),
        age_max_s: *ages.last().expect("not empty"),
        gap_max_s,
        samples,
    })
}

/// Keeps each position's age as evidence (`position_age.csv`: seconds since the first
/// arrival, `time_boot_ms`, age in seconds), for the report's age-over-time figure.
pub fn attach_series(ctx: &mut PhaseContext, f: &Freshness) -> anyhow::Result<()> {
    use std::fmt::Write as _;
    let mut csv = String::from("t_s,time_boot_ms,age_s\n");
    let t0 = f.samples.first().map_or(0.0, |s| s.arrived.as_secs_f64());
    for s in &f.samples {
        let _ = writeln!(
            csv,
            "{:.3},{},{:.3}",
            s.arrived.as_secs_f64() - t0,
            s.time_boot_ms,
            s.age_s
        );
    }
    let path = ctx.dir.join(SERIES_FILE);
    std::fs::create_dir_all(&ctx.dir)?;
    std::fs::write(&path, csv).with_context(|| format!("cannot write {}", path.display()))?;
    ctx.attach(SERIES_FILE, path, "text/csv");
    Ok(())
}

/// The attachment holding a phase's position ages.
pub const SERIES_FILE: &str = "position_age.csv";

#[cfg(test)]
mod tests {
    use super::*;

    fn at(s: f64) -> Mono {
        Mono::from_secs_f64(s)
    }

    fn pos(t: f64, ms: u32) -> Position {
        Position {
            t: at(t),
            time_boot_ms: ms,
            lat: 0,
            lon: 0,
            alt_mm: 0,
            relative_alt_mm: 0,
        }
    }

    /// The vehicle booted at t = 100 s; the truth link adds 2..12 ms. Batches of three
    /// samples 1/3 s apart arrive 0.1 s after the newest: ages 0.1, 0.433, 0.767 s.
    #[test]
    fn ages_are_arrival_minus_sampling_on_the_vehicle_clock() {
        let clock: Vec<(Mono, u32)> = (0..40)
            .map(|i| {
                (
                    at(100.0 + i as f64 + 0.002 + 0.01 * (i % 2) as f64),
                    i * 1000,
                )
            })
            .collect();
        let mut ground = Vec::new();
        for batch in 0..10u32 {
            let newest_ms = 1000 + batch * 1000;
            let arrive = 100.0 + f64::from(newest_ms) / 1000.0 + 0.1;
            for k in (0..3u32).rev() {
                ground.push(pos(arrive, newest_ms - k * 333));
            }
        }
        let f = judge(&ground, &clock, at(101.0), at(110.5)).unwrap();
        assert_eq!(f.samples.len(), 30);
        // The offset is the least-delayed sample's: 100.002.
        assert!((f.age_max_s - (0.1 + 0.666 - 0.002)).abs() < 1e-6, "{f:?}");
        assert!((f.age_p50_s - (0.1 + 0.333 - 0.002)).abs() < 1e-6, "{f:?}");
        assert!((f.gap_max_s - 1.0).abs() < 1e-6, "{f:?}");
        // 29 intervals over 334..10000 ms of vehicle time, not 30 samples / 9.5 s
        assert!((f.rate_hz - 29.0 / 9.666).abs() < 1e-9, "{f:?}");
    }

    /// Regression (CI): PX4 on LoRa SF7 read 2.8999988 Hz against 2.9: the 30 s window
    /// held 29 compact frames of three samples each, the 30th arriving just after it. The
    /// samples were 320-340 ms apart, none missing.
    #[test]
    fn a_window_that_ends_before_a_batch_does_not_lower_the_rate() {
        let clock = vec![(at(100.0), 0)];
        let mut ground = Vec::new();
        // samples 340 ms apart (2.94 Hz), three to a frame: a frame every 1.02 s
        for batch in 0..32u32 {
            let newest_ms = 1020 + batch * 1020;
            let arrive = 100.0 + f64::from(newest_ms) / 1000.0 + 0.2;
            for k in (0..3u32).rev() {
                ground.push(pos(arrive, newest_ms - k * 340));
            }
        }
        // 30 s from just after frame 0: frames 1..=29 (the 30th comes 0.6 s later)
        let from = 100.0 + 1.02 + 0.2 + 0.01;
        let f = judge(&ground, &clock, at(from), at(from + 30.0)).unwrap();
        assert_eq!(f.samples.len(), 87, "29 frames of 3 (87 / 30 s = 2.9 Hz)");
        assert!((f.rate_hz - 1.0 / 0.34).abs() < 1e-6, "{}", f.rate_hz);
    }

    #[test]
    fn repeats_and_older_samples_are_not_news_and_silence_is_a_gap() {
        let clock = vec![(at(10.0), 0)];
        let ground = vec![
            pos(10.5, 400),
            pos(10.6, 400),
            pos(10.7, 300),
            pos(14.0, 3_900),
        ];
        let f = judge(&ground, &clock, at(10.0), at(15.0)).unwrap();
        let got: Vec<u32> = f.samples.iter().map(|s| s.time_boot_ms).collect();
        assert_eq!(got, [400, 3_900]);
        assert!((f.gap_max_s - 3.5).abs() < 1e-9, "{f:?}");
        assert!(judge(&ground, &[], at(10.0), at(15.0)).is_none());
    }
}
