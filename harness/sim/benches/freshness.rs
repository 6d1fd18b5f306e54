//! `cargo bench -p harness-sim --bench freshness`: compact telemetry's bytes against its
//! freshness, for the shipped `[compact]` settings and a few candidate batchings, on the rig
//! file's radios (SiK 64k and LoRa SF7, clean and with 10 % bursty loss), with the PX4-like
//! and the ArduPilot-like autopilot flying the paper's route, signed as the binaries are.
//!
//! Prints one line per run: B/s handed to the radio on the drone's side (and the share of
//! time on air), positions per second at the ground, their age p50 / p95 / max and the longest
//! wait for a newer one (`gap`; `gap~` is the median over the seeds of each run's longest).
//! `FRESHNESS_SEEDS` (default 3) seeds per lossy radio, the worst of each figure printed; `FRESHNESS_ONLY=px4|ardupilot` to fly one autopilot. Then, for the shipped
//! batching, how long changes of mode and arming take to the ground (PX4-like autopilot, a
//! change every 7.3 s, the same seeds).

use harness_sim::freshness::{
    Freshness, FreshnessAutopilot, FreshnessRadio, FreshnessRun, mode_latencies, quantile,
};
use mavlora::Duration;
use mavlora::compact::CompactConfig;

/// (name, settings): `None` is the profile's own `[compact]` table.
fn candidates() -> Vec<(&'static str, Option<CompactConfig>)> {
    let c = |samples: usize, period_ms: u64| CompactConfig {
        sample_hz: 3.0,
        batch_samples: samples,
        batch_period: Duration::from_millis(period_ms),
        ..CompactConfig::default()
    };
    vec![
        ("shipped", None),
        ("3 Hz, 6 per 2 s", Some(c(6, 2000))),
        ("3 Hz, 4 per 1.33 s", Some(c(4, 1333))),
        ("3 Hz, 2 per 0.67 s", Some(c(2, 667))),
        ("3 Hz, 1 per 0.33 s", Some(c(1, 333))),
        (
            "shipped, coalesce 1.5s",
            Some(CompactConfig {
                coalesce: Duration::from_millis(1500),
                ..CompactConfig::default()
            }),
        ),
    ]
}

/// The median of one figure over several runs.
fn median(runs: &[Freshness], f: fn(&Freshness) -> f64) -> f64 {
    let mut v: Vec<f64> = runs.iter().map(f).collect();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The worst of each figure over several runs.
fn worst(runs: &[Freshness]) -> Freshness {
    let max = |f: fn(&Freshness) -> f64| runs.iter().map(f).fold(f64::MIN, f64::max);
    let min = |f: fn(&Freshness) -> f64| runs.iter().map(f).fold(f64::MAX, f64::min);
    Freshness {
        down_bytes_per_s: max(|r| r.down_bytes_per_s),
        down_by_id: runs[0].down_by_id.clone(),
        down_duty: max(|r| r.down_duty),
        position_hz: min(|r| r.position_hz),
        age_p50_s: max(|r| r.age_p50_s),
        age_p95_s: max(|r| r.age_p95_s),
        age_max_s: max(|r| r.age_max_s),
        max_gap_s: max(|r| r.max_gap_s),
    }
}

fn main() {
    let seeds: u64 = std::env::var("FRESHNESS_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let only = std::env::var("FRESHNESS_ONLY").ok();
    println!(
        "{:<10} {:<23} {:<16} {:>7} {:>6} {:>7} {:>6} {:>6} {:>6} {:>6} {:>6}  bytes by id",
        "autopilot",
        "batching",
        "radio",
        "B/s",
        "duty%",
        "pos Hz",
        "p50",
        "p95",
        "max",
        "gap",
        "gap~"
    );
    for autopilot in [FreshnessAutopilot::Px4, FreshnessAutopilot::ArduPilot] {
        if only.as_deref().is_some_and(|o| o != autopilot.name()) {
            continue;
        }
        for (name, compact) in candidates() {
            for radio in FreshnessRadio::ALL {
                let n = if radio.lossy() { seeds } else { 1 };
                let runs: Vec<Freshness> = (1..=n)
                    .map(|seed| {
                        FreshnessRun {
                            compact,
                            seed,
                            ..FreshnessRun::new(autopilot, radio)
                        }
                        .measure()
                    })
                    .collect();
                let f = worst(&runs);
                let gap_median = median(&runs, |r| r.max_gap_s);
                let by_id: Vec<String> = f
                    .down_by_id
                    .iter()
                    .filter(|(_, b)| *b >= 0.5)
                    .map(|(id, b)| format!("{id}:{b:.1}"))
                    .collect();
                println!(
                    "{:<10} {:<23} {:<16} {:>7.1} {:>6.2} {:>7.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2}  {}",
                    autopilot.name(),
                    name,
                    radio.name(),
                    f.down_bytes_per_s,
                    100.0 * f.down_duty,
                    f.position_hz,
                    f.age_p50_s,
                    f.age_p95_s,
                    f.age_max_s,
                    f.max_gap_s,
                    gap_median,
                    by_id.join(" ")
                );
            }
        }
    }
    println!("mode and arming changes, shipped batching, autopilot heartbeat to ground:");
    for radio in FreshnessRadio::ALL {
        let n = if radio.lossy() { seeds } else { 1 };
        let mut l: Vec<f64> = (1..=n)
            .flat_map(|seed| mode_latencies(radio, seed, 500.0))
            .collect();
        l.sort_by(f64::total_cmp);
        let within = l.iter().filter(|l| **l <= 0.5).count();
        println!(
            "  {:<16} {within}/{} within 0.5 s ({:.1} %), p50 {:.2} s, p95 {:.2} s, max {:.2} s",
            radio.name(),
            l.len(),
            100.0 * within as f64 / l.len() as f64,
            quantile(&l, 0.5),
            quantile(&l, 0.95),
            l.last().copied().unwrap_or(f64::NAN)
        );
    }
}
