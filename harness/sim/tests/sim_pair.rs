//! Virtual-clock runs of the whole chain (simulated PX4, bridge, lossy radio, router,
//! simulated ground station): mission relay under loss, the naive relay's duplicates, and
//! the radio bytes per second of each bandwidth mechanism.

use harness_radio::{Direction, LinkConfig, Preset, RadioSetup};
use harness_sim::{GcsMock, PX4_NORMAL, Px4Fc, StreamSpec, World, scheduler_for};
use mavlora::bridge::BridgeConfig;
use mavlora::dialect::MavMissionResult;
use mavlora::filter::Profile;
use mavlora::quality::LinkQualityConfig;
use mavlora::router::RouterConfig;
use mavlora::schedule::SchedulerConfig;
use mavlora::{Duration, Instant};

const PROFILES: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../firmware/mavlora/profiles/"
);

fn profile(name: &str) -> Profile {
    Profile::load(format!("{PROFILES}{name}")).unwrap()
}

/// The paper's LoRa radio (SF7/125 kHz, 683 B/s raw) with 150 ms one way and every air
/// packet lost with `loss`, independently, each way; the seeds follow `seed`.
fn radio(loss: f64, seed: u64) -> RadioSetup {
    let link = |seed| LinkConfig {
        latency_ms: 150.0,
        packet_loss: loss,
        seed,
        ..LinkConfig::default()
    };
    let mut setup = RadioSetup::builtin("lora-sf7").unwrap();
    setup.downlink = link(seed ^ 0x5555);
    setup.uplink = link(seed ^ 0xAAAA);
    setup
}

/// The engines' budget for that radio: 80 % of one direction's share of the channel.
fn budget() -> SchedulerConfig {
    scheduler_for(Some(&Preset::lora_sf7()))
}

fn relay_world(profile_name: &str, compact: bool, loss: f64, seed: u64) -> World {
    let profile = profile(profile_name);
    let batching = profile.compact().unwrap_or_default();
    let mut b = BridgeConfig::new(profile, budget());
    b.compact = compact.then_some(batching);
    World::new(
        Px4Fc::new(PX4_NORMAL, Instant::ZERO, seed),
        Some((b, RouterConfig::new(budget()))),
        Some(&radio(loss, seed)),
    )
    .unwrap()
}

fn secs(s: u64) -> Instant {
    Instant::from_millis(s * 1000)
}

#[test]
fn fifty_item_mission_completes_under_ten_percent_loss() {
    for seed in 1..=30 {
        let mut w = relay_world("px4-compact.toml", true, 0.10, seed);
        w.run_until(secs(5));
        w.gcs.upload(GcsMock::mission(50), w.now);
        let done = w.run_until_or(secs(300), |w| w.gcs.result.is_some());
        assert!(done, "seed {seed}: no result");
        let (result, at) = w.gcs.result.unwrap();
        assert_eq!(
            result,
            MavMissionResult::MAV_MISSION_ACCEPTED,
            "seed {seed}"
        );
        assert_eq!(w.fc.mission(), &GcsMock::mission(50)[..], "seed {seed}");
        let (b, r) = (w.bridge().unwrap(), w.router().unwrap());
        let m = b.stats().mission;
        println!(
            "seed {seed}: {:.1} s, radio repair requests {}, duplicate items at bridge {}, \
             repaired by the router {}, srtt {:?}, rto {:?}, fc item requests {}",
            at.saturating_duration_since(secs(5)).as_secs_f64(),
            m.radio_requests,
            m.radio_duplicate_items,
            r.stats().mission.items_repaired,
            b.mission_rtt().srtt(),
            b.mission_rtt().rto(),
            w.fc.stats().item_requests,
        );
        // Duplicates only where the protocol needs them (an item received, the next request
        // lost, the ground's 1.5 s retry): about one per lost request, never one per item.
        assert!(m.radio_duplicate_items <= 10, "seed {seed}: {m:?}");
    }
}

/// Telemetry light enough not to saturate the radio, so duplicates come from the retry
/// policy alone.
const LIGHT: &[StreamSpec] = &[
    StreamSpec {
        id: 0,
        hz: 1.0,
        payload_len: 9,
    },
    StreamSpec {
        id: 33,
        hz: 3.0,
        payload_len: 28,
    },
];

#[test]
fn naive_relay_with_px4_retries_floods_duplicates() {
    // Same radio and loss, no bridge: PX4 re-requests every 250 ms across a radio whose round
    // trip is ~400 ms, so nearly every item crosses twice.
    let mut naive = World::new(
        Px4Fc::new(LIGHT, Instant::ZERO, 7),
        None,
        Some(&radio(0.10, 7)),
    )
    .unwrap();
    naive.run_until(secs(5));
    naive.gcs.upload(GcsMock::mission(50), naive.now);
    naive.run_until_or(secs(120), |w| w.gcs.result.is_some());
    let naive_dups = naive.fc.stats().duplicate_items;

    let profile = profile("px4-compact.toml");
    let batching = profile.compact();
    let mut b = BridgeConfig::new(profile, budget());
    b.compact = Some(batching.unwrap_or_default());
    let mut relay = World::new(
        Px4Fc::new(LIGHT, Instant::ZERO, 7),
        Some((b, RouterConfig::new(budget()))),
        Some(&radio(0.10, 7)),
    )
    .unwrap();
    relay.run_until(secs(5));
    relay.gcs.upload(GcsMock::mission(50), relay.now);
    relay.run_until_or(secs(120), |w| w.gcs.result.is_some());
    let relay_dups = relay
        .bridge()
        .unwrap()
        .stats()
        .mission
        .radio_duplicate_items;
    println!(
        "duplicates over the radio: naive {naive_dups} (items sent {}, result {:?}), relay {relay_dups} (items sent {})",
        naive.gcs.items_sent, naive.gcs.result, relay.gcs.items_sent
    );
    assert!(
        // at least every other item crossed twice
        naive_dups >= 25,
        "naive relay sent only {naive_dups} duplicates"
    );
    assert!(relay_dups * 5 <= naive_dups, "{relay_dups} vs {naive_dups}");
    assert_eq!(relay.fc.mission(), &GcsMock::mission(50)[..]);
}

/// Air→ground bytes per second between 10 s and 70 s of steady flight.
fn steady_rate(mut w: World) -> (f64, World) {
    w.run_until(secs(10));
    let before = w.sent(Direction::Downlink).total_bytes();
    w.run_until(secs(70));
    let after = w.sent(Direction::Downlink).total_bytes();
    ((after - before) as f64 / 60.0, w)
}

#[test]
fn compact_telemetry_stays_under_50_bytes_per_second() {
    let wide = SchedulerConfig {
        rate_bytes_per_s: 100_000,
        burst_bytes: 10_000,
        max_queued_bytes: 100_000,
    };
    // An ideal wire: what the bridge sends is all that is measured.
    let run = |profile_text: &str, compact: bool| {
        let p = Profile::parse(profile_text, "inline").unwrap();
        let batching = p.compact().unwrap_or_default();
        let mut b = BridgeConfig::new(p, wide);
        b.compact = compact.then_some(batching);
        // Link monitoring as on the LoRa channel compact is for: the wire's nominal
        // 100 kB/s would buy a report every 0.5 s (as in the Table II scenario).
        b.quality = LinkQualityConfig::default();
        let mut r = RouterConfig::new(wide);
        r.quality = LinkQualityConfig::default();
        let fc = Px4Fc::new(PX4_NORMAL, Instant::ZERO, 3);
        let w = World::new(fc, Some((b, r)), None).unwrap();
        steady_rate(w)
    };
    let read = |name: &str| std::fs::read_to_string(format!("{PROFILES}{name}")).unwrap();
    let stream_only: String = read("px4-normal.toml")
        .lines()
        .filter(|l| !l.trim_start().starts_with("radio"))
        .collect::<Vec<_>>()
        .join("\n");
    let (none, _) = run("", false);
    let (limited, _) = run(&stream_only, false);
    let (filtered, _) = run(&read("px4-normal.toml"), false);
    let (compact, w) = run(&read("px4-compact.toml"), true);
    println!(
        "PX4 Normal air->ground B/s: none {none:.1}, stream limiting {limited:.1}, \
         limiting+filtering {filtered:.1}, compact {compact:.1}; compact by id {:?}",
        w.sent(Direction::Downlink).bytes
    );
    assert!(none > limited && limited > filtered && filtered > compact);
    assert!(compact <= 50.0, "compact telemetry at {compact:.1} B/s");
    // the ground station still receives the standard messages
    for id in [0, 1, 24, 33, 74] {
        assert!(
            w.gcs.received.get(&id).copied().unwrap_or(0) > 0,
            "no {id} at the GCS"
        );
    }
    // A lossless radio reads as lossless on both sides, although the bridge filters and the
    // router thins heartbeats: both renumber what they send.
    let (b, r) = (w.bridge().unwrap(), w.router().unwrap());
    assert_eq!(r.stats().radio_reader.lost, 0);
    assert_eq!(b.stats().radio_reader.lost, 0);
    let positions = w.gcs.received[&33] as f64 / 70.0;
    assert!(positions > 2.8, "{positions:.2} positions/s at the GCS");
}

#[test]
fn signed_radio_link_carries_a_mission_and_rejects_forged_and_replayed_frames() {
    use mavlora::dialect::{COMMAND_LONG_DATA, MavMessage};
    use mavlora::signing::{SigningConfig, SigningKey};
    use mavlora::wire::Sender;

    let signing = |link_id| SigningConfig {
        key: SigningKey([42; 32]),
        link_id,
        epoch: 3_000_000_000,
        state: Default::default(),
    };
    let profile = profile("px4-compact.toml");
    let batching = profile.compact();
    let mut b = BridgeConfig::new(profile, budget());
    b.compact = Some(batching.unwrap_or_default());
    b.signing = Some(signing(1));
    let mut r = RouterConfig::new(budget());
    r.signing = Some(signing(2));
    let mut w = World::new(
        Px4Fc::new(PX4_NORMAL, Instant::ZERO, 11),
        Some((b, r)),
        Some(&radio(0.05, 11)),
    )
    .unwrap();
    w.run_until(secs(5));
    w.gcs.upload(GcsMock::mission(50), w.now);
    assert!(w.run_until_or(secs(200), |w| w.gcs.result.is_some()));
    assert_eq!(w.fc.mission(), &GcsMock::mission(50)[..]);
    // 15 s of flight whatever the upload took (packed, it takes about 2 s)
    w.run_until(w.now.max(secs(20)));
    assert!(
        w.gcs.received.get(&33).copied().unwrap_or(0) > 30,
        "telemetry expanded"
    );

    // An attacker on the radio: an unsigned command, then a replay of a captured signed frame
    // (injected at the bridge's radio input, not through the lossy link, so they arrive).
    let mut forger = Sender::new(255, 190, mavlink::MavlinkVersion::V2);
    let cmd = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA::default());
    let mut victim = mavlora::signing::LinkSigner::new(SigningKey([42; 32]), 2, 3_000_000_000);
    let captured = victim.sign(&forger.frame(&cmd), Instant::ZERO).unwrap();
    let now = w.now;
    let b = w.bridge_mut().unwrap();
    b.handle_radio_bytes(now, forger.frame(&cmd).as_bytes());
    b.handle_radio_bytes(now, captured.as_bytes());
    let s = b.stats().signing;
    let router = w.router().unwrap().stats().signing;
    println!("bridge signing {s:?}, router signing {router:?}");
    assert!(s.unsigned >= 1 && s.replayed >= 1, "{s:?}");
    // Signed frames flow both ways (the upload goes as a handful of packed frames and asks
    // for nothing per item: the bridge hears ~10 frames of the router; the router hears a
    // position batch every 2 s for 20 s, the statuses and the mission's answers).
    assert!(s.accepted >= 5 && router.accepted >= 10, "{s:?} {router:?}");
    assert_eq!(s.bad_signature, 0);
}

#[test]
fn download_and_clear_pass_through_under_loss() {
    let mut w = relay_world("px4-compact.toml", true, 0.10, 21);
    w.run_until(secs(5));
    w.gcs.upload(GcsMock::mission(20), w.now);
    assert!(w.run_until_or(secs(120), |w| w.gcs.result.is_some()));
    let start = w.now;
    w.gcs.download(w.now);
    assert!(
        w.run_until_or(secs(300), |w| w.gcs.downloaded.is_some()),
        "download"
    );
    println!(
        "download of 20 items: {:.1} s",
        w.now.saturating_duration_since(start).as_secs_f64()
    );
    let mut want = GcsMock::mission(20);
    for item in &mut want {
        (item.target_system, item.target_component) = (255, 190);
    }
    assert_eq!(w.gcs.downloaded.as_deref(), Some(&want[..]));
    // clear: one command, one ack; the spec'd 1.5 s retry is the ground's business
    for _ in 0..5 {
        w.gcs.clear();
        let until = w.now + Duration::from_secs(3);
        if w.run_until_or(until, |w| w.gcs.result.is_some()) {
            break;
        }
    }
    assert_eq!(
        w.gcs.result.map(|r| r.0),
        Some(MavMissionResult::MAV_MISSION_ACCEPTED)
    );
    assert!(w.fc.mission().is_empty());
}
