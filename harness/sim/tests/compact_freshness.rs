//! Compact telemetry's freshness and bytes with the shipped `[compact]` batching, flown
//! through the real engines, signed, over the rig file's radios (harness_sim::freshness). The
//! targets (issue 21, from the paper's 3 Hz need and the EU 433 MHz duty-cycle rule): position
//! at the ground at least 2.9 Hz, age p95 at most 1.0 s, no wait for a newer one over 1.5 s,
//! at most 68 B/s on the downlink, on SiK 64k and LoRa SF7; at 10 % bursty loss at least
//! 2.5 Hz; mode and armed changes at the ground within 0.5 s.
//! `cargo bench -p harness-sim --bench freshness` prints the same figures for candidate
//! batchings (docs/measurements.md).

use harness_sim::freshness::{
    FreshnessAutopilot, FreshnessRadio, FreshnessRun, mode_latencies, quantile,
};

/// Long enough for the figures to settle, short enough for a debug build: cruise.
fn run(autopilot: FreshnessAutopilot, radio: FreshnessRadio, seed: u64) -> FreshnessRun {
    FreshnessRun {
        seed,
        from_s: 20.0,
        until_s: 200.0,
        ..FreshnessRun::new(autopilot, radio)
    }
}

#[test]
fn shipped_batching_keeps_positions_fresh_within_68_bytes_per_second() {
    // Regression (issue 21): six positions every 2 s left a position 1.7-1.8 s old at the
    // ground at the 95th percentile.
    for autopilot in [FreshnessAutopilot::Px4, FreshnessAutopilot::ArduPilot] {
        for radio in [FreshnessRadio::Sik, FreshnessRadio::Lora] {
            let f = run(autopilot, radio, 1).measure();
            eprintln!("{} {}: {f:?}", autopilot.name(), radio.name());
            let what = format!("{} on {}", autopilot.name(), radio.name());
            assert!(f.position_hz >= 2.9, "{what}: {:.2} Hz", f.position_hz);
            assert!(f.age_p95_s <= 1.0, "{what}: age p95 {:.2} s", f.age_p95_s);
            assert!(f.max_gap_s <= 1.5, "{what}: gap {:.2} s", f.max_gap_s);
            assert!(
                f.down_bytes_per_s <= 68.0,
                "{what}: {:.1} B/s down",
                f.down_bytes_per_s
            );
        }
    }
}

#[test]
fn at_ten_percent_bursty_loss_positions_keep_2_5_hz() {
    // The other lossy target, no wait over 3 s, is not met: see docs/measurements.md (the
    // longest waits are two or three lost frames in a row on SiK, and LoRa's fades, 1 s on
    // average, themselves last longer than 3 s now and then). Printed, not asserted.
    for radio in [FreshnessRadio::SikBursty, FreshnessRadio::LoraBursty] {
        for seed in 1..=2 {
            let f = run(FreshnessAutopilot::Px4, radio, seed).measure();
            eprintln!("{} seed {seed}: {f:?}", radio.name());
            assert!(
                f.position_hz >= 2.5,
                "{} seed {seed}: {:.2} Hz",
                radio.name(),
                f.position_hz
            );
            assert!(f.down_bytes_per_s <= 68.0, "{f:?}");
        }
    }
}

#[test]
fn mode_and_arming_changes_reach_the_ground_within_half_a_second() {
    // Regression (issue 22, item 15): a change went in one status frame; with it lost, the
    // ground showed the old mode until the next status, up to 10 s later. Timed from the
    // autopilot's first HEARTBEAT with the change (PX4 sends one a second, and v1.16 keeps it
    // at 1 Hz whatever SET_MESSAGE_INTERVAL asks).
    for radio in [FreshnessRadio::Sik, FreshnessRadio::Lora] {
        let l = mode_latencies(radio, 1, 200.0);
        assert!(l.len() >= 20, "{l:?}");
        assert!(l.iter().all(|l| *l <= 0.5), "{}: {l:?}", radio.name());
    }
    // At 10 % bursty loss three copies 150 ms apart are most often enough; a fade longer than
    // the copies' span is not crossed by any of them (printed; docs/measurements.md).
    for radio in [FreshnessRadio::SikBursty, FreshnessRadio::LoraBursty] {
        let mut l = mode_latencies(radio, 1, 200.0);
        l.sort_by(f64::total_cmp);
        let within = l.iter().filter(|l| **l <= 0.5).count();
        eprintln!(
            "{}: {within}/{} within 0.5 s, p50 {:.2} s, p95 {:.2} s",
            radio.name(),
            l.len(),
            quantile(&l, 0.5),
            quantile(&l, 0.95)
        );
        assert!(within * 10 >= l.len() * 8, "{}: {l:?}", radio.name());
    }
}
