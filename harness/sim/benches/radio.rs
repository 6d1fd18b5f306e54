//! `cargo bench -p harness-sim --bench radio`: prints
//! 1. frames per second through the bridge's path (reader → filter → scheduler → radio) on
//!    one core, against a baseline measured in the same run (the frame reader alone: the
//!    least any MAVLink forwarder must do);
//! 2. air→ground bytes per second for a simulated PX4 on its "Normal" profile with: no
//!    filtering, stream limiting only, limiting + filtering, compact telemetry.

use std::hint::black_box;
use std::time::Instant as WallInstant;

use mavlora::Duration;

use harness_sim::profiles::{PX4_COMPACT_TOML, PX4_NORMAL_TOML, stream_only};
use harness_sim::{Direction, PX4_NORMAL, Px4Fc, World};

mod common;
use common::px4_capture;
use mavlora::Instant;
use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::filter::Profile;
use mavlora::quality::LinkQualityConfig;
use mavlora::router::RouterConfig;
use mavlora::schedule::SchedulerConfig;
use mavlora::wire::FrameReader;

fn wide() -> SchedulerConfig {
    SchedulerConfig {
        rate_bytes_per_s: 1_000_000,
        burst_bytes: 100_000,
        max_queued_bytes: 1_000_000,
    }
}

/// Frames per second over `rounds` replays of the capture, shifted in time each round.
fn throughput(
    capture: &[(Instant, Vec<u8>)],
    rounds: u64,
    mut feed: impl FnMut(Instant, &[u8]),
) -> f64 {
    let start = WallInstant::now();
    for r in 0..rounds {
        let shift = Duration::from_secs(60 * r);
        for (t, bytes) in capture {
            feed(*t + shift, bytes);
        }
    }
    (capture.len() as u64 * rounds) as f64 / start.elapsed().as_secs_f64()
}

fn bridge_path(profile: &str, compact: bool) -> impl FnMut(Instant, &[u8]) {
    let profile = Profile::parse(profile, "bench").unwrap();
    let batching = profile.compact().unwrap_or_default();
    let mut config = BridgeConfig::new(profile, wide());
    config.compact = compact.then_some(batching);
    let mut bridge = Bridge::new(config, Instant::ZERO).unwrap();
    move |now, bytes| {
        bridge.handle_fc_bytes(now, bytes);
        bridge.handle_timeout(now);
        while let Some(f) = bridge.poll_radio_transmit(now, usize::MAX) {
            black_box(f);
        }
        while let Some(f) = bridge.poll_fc_transmit(now) {
            black_box(f);
        }
    }
}

/// Bytes the bridge hands to an ideal wire towards the ground, per second.
fn radio_rate(profile: &str, compact: bool) -> f64 {
    let profile = Profile::parse(profile, "bench").unwrap();
    let batching = profile.compact().unwrap_or_default();
    let mut b = BridgeConfig::new(profile, wide());
    b.compact = compact.then_some(batching);
    // Link monitoring paced as on LoRa SF7 (its default), as the simulated Table II does:
    // paced for the wide budget, link-quality reports alone would be ~45 B/s.
    b.quality = LinkQualityConfig::default();
    let mut r = RouterConfig::new(wide());
    r.quality = LinkQualityConfig::default();
    let fc = Px4Fc::new(PX4_NORMAL, Instant::ZERO, 3);
    let mut w = World::new(fc, Some((b, r)), None).unwrap();
    w.run_until(Instant::from_millis(10_000));
    let before = w.sent(Direction::Downlink).total_bytes();
    w.run_until(Instant::from_millis(130_000));
    let after = w.sent(Direction::Downlink).total_bytes();
    (after - before) as f64 / 120.0
}

fn main() {
    let capture = px4_capture(PX4_NORMAL);
    let bytes: usize = capture.iter().map(|(_, b)| b.len()).sum();
    println!(
        "capture: {} frames, {} bytes, 60 s of PX4 Normal at full rate ({:.0} B/s)",
        capture.len(),
        bytes,
        bytes as f64 / 60.0
    );
    let rounds = 400;
    let mut reader = FrameReader::new();
    let baseline = throughput(&capture, rounds, |_, b| {
        reader.push(b);
        while let Some(f) = reader.next_frame() {
            black_box(f);
        }
    });
    let filtered = throughput(&capture, rounds, bridge_path(PX4_NORMAL_TOML, false));
    let compact = throughput(&capture, rounds, bridge_path(PX4_COMPACT_TOML, true));
    println!("frames/s on one core (higher is better):");
    println!("  baseline, frame reader only     {baseline:>12.0}");
    println!(
        "  bridge, px4-normal.toml          {filtered:>12.0}  ({:.2} x baseline)",
        filtered / baseline
    );
    println!(
        "  bridge, px4-compact + compact    {compact:>12.0}  ({:.2} x baseline)",
        compact / baseline
    );

    println!("air->ground B/s, simulated PX4 Normal, 120 s after a 10 s start:");
    println!(
        "  no filtering                     {:>8.1}",
        radio_rate("", false)
    );
    println!(
        "  stream limiting                  {:>8.1}",
        radio_rate(&stream_only(PX4_NORMAL_TOML), false)
    );
    println!(
        "  limiting + filtering             {:>8.1}",
        radio_rate(PX4_NORMAL_TOML, false)
    );
    println!(
        "  compact telemetry                {:>8.1}",
        radio_rate(PX4_COMPACT_TOML, true)
    );
}
