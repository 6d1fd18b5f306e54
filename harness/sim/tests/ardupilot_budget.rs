//! An ArduPilot-like autopilot (MAVLink 1, ~30 message types at 4 Hz,
//! ardupilotmega-only ids, a parameter stream, stream requests ignored) through the bridge
//! and the LoRa SF7 radio. The profile's messages must keep their rate and a short lag
//! whatever else the autopilot sends; commands must never be dropped; a parameter stream is
//! paced, not lost.

use harness_radio::{Direction, Preset, RadioSetup};
use harness_sim::{ArduPilotConfig, ArduPilotFc, CommandPlan, World, scheduler_for};
use mavlora::bridge::BridgeConfig;
use mavlora::filter::Profile;
use mavlora::param::{ParamPackConfig, pack};
use mavlora::router::RouterConfig;
use mavlora::wire::ids;
use mavlora::{Duration, Instant};

const PROFILES: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../firmware/mavlora/profiles/"
);

fn secs(s: f64) -> Instant {
    Instant::from_micros((s * 1e6) as u64)
}

/// The paper's LoRa radio, loss-free: what is late or missing is the scheduler's doing.
fn lora() -> RadioSetup {
    RadioSetup::builtin("lora-sf7").unwrap()
}

fn world(profile: &str, compact: bool, ap: ArduPilotConfig) -> World<ArduPilotFc> {
    let profile = Profile::load(format!("{PROFILES}{profile}")).unwrap();
    world_with(profile, compact, ap)
}

fn world_with(profile: Profile, compact: bool, ap: ArduPilotConfig) -> World<ArduPilotFc> {
    let budget = scheduler_for(Some(&Preset::lora_sf7()));
    let batching = profile.compact().unwrap_or_default();
    let mut b = BridgeConfig::new(profile, budget);
    b.compact = compact.then_some(batching);
    World::new(
        ArduPilotFc::new(ap, Instant::ZERO, 7),
        Some((b, RouterConfig::new(budget))),
        Some(&lora()),
    )
    .unwrap()
}

/// An autopilot that ignores the stream configuration and streams its 1000 parameters at
/// boot: everything it has, at once.
fn stubborn() -> ArduPilotConfig {
    ArduPilotConfig {
        obey_stream_requests: false,
        params_at_boot: true,
        ..ArduPilotConfig::default()
    }
}

/// Positions the ground received after `from`: (rate in Hz, p99 lag).
fn positions(w: &World<ArduPilotFc>, from: Instant) -> (f64, Duration) {
    let got: Vec<_> = w.gcs.positions.iter().filter(|(t, _)| *t >= from).collect();
    let span = w.now.saturating_duration_since(from).as_secs_f64();
    let mut lags: Vec<Duration> = got
        .iter()
        .map(|(t, ms)| t.saturating_duration_since(Instant::from_millis(u64::from(*ms))))
        .collect();
    lags.sort();
    let p99 = lags
        .get((lags.len() * 99).div_ceil(100).saturating_sub(1))
        .copied()
        .unwrap_or(Duration::MAX);
    (got.len() as f64 / span, p99)
}

/// A profile that names only what the ground needs and lets everything else through: the
/// autopilot's other ~3.4 kB/s all competes for the 546 B/s budget.
const NAMES_ONLY_POSITION: &str = r#"
[data_streams]
all = 0
position = 3
[defaults]
radio = "pass"
unlisted = "share"
[messages.HEARTBEAT]
radio = "pass"
[messages.GLOBAL_POSITION_INT]
radio = 3
[messages.SYS_STATUS]
radio = 1
"#;

#[test]
fn stubborn_ardupilot_does_not_starve_position_or_drop_commands() {
    let profile = Profile::parse(NAMES_ONLY_POSITION, "names-only-position").unwrap();
    let mut w = world_with(profile, false, stubborn());
    w.gcs.start_commands(CommandPlan::default(), secs(5.0));
    w.run_until(secs(120.0));
    // the profile's 3 Hz position, with a lag of at most 1.5 of its periods
    let (hz, p99) = positions(&w, secs(10.0));
    eprintln!("position {hz:.3} Hz, lag p99 {p99:?}");
    assert!(hz >= 2.8, "position at {hz:.2} Hz, profile asks 3 Hz");
    assert!(
        p99 <= Duration::from_millis(500),
        "position lag p99 {p99:?} > 1.5 periods of 3 Hz"
    );
    let s = w.bridge().unwrap().stats().scheduler;
    assert_eq!(
        (s.dropped_command, s.dropped_protocol, s.dropped_status),
        (0, 0, 0),
        "{s:?}"
    );
    let c = w.gcs.command_stats();
    assert_eq!(c.failed, 0, "{c:?}");
    assert!(c.acked >= 10, "{c:?}");
}

#[test]
fn shipped_ardupilot_profile_keeps_position_at_3_hz_from_a_stubborn_ardupilot() {
    let mut w = world("ardupilot-mavlink1.toml", false, stubborn());
    w.run_until(secs(120.0));
    let (hz, p99) = positions(&w, secs(10.0));
    eprintln!("position {hz:.3} Hz, lag p99 {p99:?}");
    assert!(hz >= 2.8, "position at {hz:.2} Hz, profile asks 3 Hz");
    assert!(p99 <= Duration::from_millis(500), "lag p99 {p99:?}");
    let s = w.bridge().unwrap().stats().scheduler;
    assert_eq!((s.dropped_command, s.dropped_protocol), (0, 0), "{s:?}");
}

#[test]
fn parameter_stream_is_paced_to_the_ground_not_dropped() {
    let ap = ArduPilotConfig {
        params: 300,
        ..stubborn()
    };
    let mut w = world("ardupilot-mavlink1.toml", false, ap);
    // Paced, not a speed target: until the bridge has handed all 300 to the radio (packed
    // several to a frame; at worst at the stream's floor share, 1/9 of the budget beside telemetry; link
    // monitoring and commands share the same budget), then 10 s for the radio to deliver the
    // last.
    let sent = |w: &World<ArduPilotFc>| w.bridge().unwrap().stats().params.values_packed;
    w.run_until_or(secs(300.0), |w| sent(w) >= 300);
    let until = w.now + Duration::from_secs(10);
    w.run_until(until);
    // The bridge hands every one to the radio, none dropped from its queues.
    let b = w.bridge().unwrap().stats();
    let s = b.scheduler;
    assert_eq!(
        (b.params.values_packed, b.params.dropped),
        (300, 0),
        "{:?}",
        b.params
    );
    assert_eq!(s.dropped_param, 0, "{s:?}");
    assert_eq!(
        (s.dropped_command, s.dropped_protocol, s.dropped_status),
        (0, 0, 0),
        "{s:?}"
    );
    let params = w.gcs.received.get(&ids::PARAM_VALUE).copied().unwrap_or(0);
    let radio = w.link_stats(Direction::Downlink).unwrap();
    let r = w.router().unwrap().stats();
    let cut = b.params.frames - r.param_frames_expanded;
    eprintln!(
        "{params} PARAM_VALUE at the ground; radio buffer overflow: {} bytes, {cut} packed \
         frame(s) cut",
        radio.bytes_dropped
    );
    // Every value the bridge sent reached the ground, except those of a frame the radio's
    // buffer cut (its 256 bytes overflow once at boot, when the scheduler's first burst meets
    // everything the autopilot sends at once): the ground reads those again.
    assert_eq!(
        params, r.param_values_expanded,
        "all of them from packed frames"
    );
    assert!(
        cut == 0 || (cut <= 1 && radio.bytes_dropped > 0),
        "{cut} frames lost, {} bytes dropped by the radio",
        radio.bytes_dropped
    );
    // values a frame of this budget carries at most
    let rate = scheduler_for(Some(&Preset::lora_sf7())).rate_bytes_per_s;
    let per_frame = (ParamPackConfig::for_rate(rate).data_bytes / pack::MIN_VALUE_BYTES) as u64;
    assert!(params + per_frame * cut >= 300, "{params} received");
    let (hz, _) = positions(&w, secs(10.0));
    assert!(
        hz >= 2.8,
        "position at {hz:.2} Hz during the parameter stream"
    );
}

#[test]
fn compact_profile_drops_what_it_does_not_name_even_from_a_stubborn_ardupilot() {
    let mut w = world("ardupilot-compact.toml", true, stubborn());
    w.run_until(secs(60.0));
    let before = w.sent(Direction::Downlink).clone();
    w.run_until(secs(360.0));
    let sent = w.sent(Direction::Downlink).since(&before);
    // every parameter went, packed
    let params = w.bridge().unwrap().stats().params;
    assert_eq!(params.values_packed, 1000, "{params:?}");
    let periodic =
        sent.total_bytes() - sent.bytes_of(&[ids::PARAM_VALUE, ids::MAVLORA_PARAM_VALUES]);
    let bps = periodic as f64 / 300.0;
    assert!(bps <= 50.0, "{bps:.1} B/s of telemetry: {:?}", sent.bytes);
    // nothing the compact profile does not name reaches the radio
    for id in [164, 163, 178, 182, 165, 152, 193, 27, 30] {
        assert!(!sent.frames.contains_key(&id), "id {id} on the radio");
    }
}
