use std::path::Path;
use std::time::Instant as Wall;

use harness_sim::PX4_CONFIG;

use super::*;
use crate::measurement::{Dimension, Measurement, Outcome, RELAY, Selector};
use crate::rigfile::RigFile;

fn rig() -> RigFile {
    RigFile::from_str("[rig]\nname = \"simulated\"\n", "/tmp/simulated.toml").unwrap()
}

/// Runs one scenario as the runner would; its measurements, log and wall time.
fn run_one(name: &str, radios: &Radios, dir: &Path) -> (Vec<Measurement>, Vec<String>, f64) {
    let s = scenarios()
        .into_iter()
        .find(|s| s.name == name)
        .expect("scenario exists");
    let rig = rig();
    let mut declared = Declarations::new();
    let script = (s.plan)(&mut declared, radios);
    let mut ctx = PhaseContext::new(&rig, dir, declared);
    let t0 = Wall::now();
    script(&mut ctx, radios).unwrap();
    let wall = t0.elapsed().as_secs_f64();
    let (ms, log, _) = ctx.into_parts();
    println!("--- {name}: {wall:.2} s wall");
    for m in &ms {
        println!(
            "{} = {} [{}] ({}) {}",
            m.name,
            m.render_value(),
            m.limits.render(&m.unit),
            m.outcome,
            m.note.as_deref().unwrap_or("")
        );
    }
    for l in &log {
        println!("  {l}");
    }
    (ms, log, wall)
}

#[track_caller]
fn assert_all_pass(ms: &[Measurement]) {
    assert!(!ms.is_empty());
    for m in ms {
        assert!(
            m.outcome != Outcome::Unset && m.outcome.is_passing(),
            "{} = {:?} ({}), limits {}",
            m.name,
            m.value,
            m.outcome,
            m.limits.render(&m.unit)
        );
    }
}

/// The value of the one measurement named `base` with these dimensions.
#[track_caller]
fn value(ms: &[Measurement], base: &str, dims: &[(Dimension, &str)]) -> f64 {
    let selector = dims
        .iter()
        .fold(Selector::base(base), |s, (d, v)| s.dim(*d, *v));
    let found: Vec<_> = ms.iter().filter(|m| selector.matches(m)).collect();
    match found[..] {
        [m] => m.value.unwrap_or_else(|| panic!("{} not recorded", m.name)),
        _ => panic!("{base} {dims:?}: {} measurements", found.len()),
    }
}

/// Table II: every mechanism cuts traffic, limiting + filtering stays under the paper's
/// 951 B/s and compact telemetry under the project's 50 B/s (unsigned, a frame a second), and every
/// measurement of the phase passes.
#[test]
fn table_ii_reproduces_the_ordering_and_the_filtered_limit() {
    let (ms, _, _) = run_one("table_ii", &Radios::paper_defaults(), Path::new(""));
    let b = |v: &str| {
        value(
            &ms,
            "bytes_per_s",
            &[
                (Dimension::Autopilot, crate::measurement::PX4),
                (Dimension::Variant, v),
            ],
        )
    };
    assert!(b("wired") > b("limit") && b("limit") > b("limit_filter"));
    assert!(b("limit_filter") > b("compact"));
    assert_all_pass(&ms);
    // the project's target for compact telemetry (here unsigned, as the paper measured)
    assert!((0.0..=50.0).contains(&b("compact")), "{}", b("compact"));
}

/// Counting check: on the wire, UAV→GCS bytes per second must be what the profile's streams
/// make: Σ rate × (payload + 12) for MAVLink 2 frames, computed here from the profile table,
/// not from anything the world counted. Tolerance: each stream may send one frame more or
/// less than rate × time over the flight (phase), so Σ frame / flight time.
#[test]
fn wired_counts_equal_the_profile_rates_times_frame_sizes() {
    let row = table_ii::fly(&Radios::paper_defaults(), "wired").unwrap();
    // VFR_HUD's last field, throttle, is a u16 percentage (≤ 100): its high byte is always
    // zero and MAVLink 2 truncates it.
    let frame = |id: u32, payload: usize| payload + 12 - usize::from(id == 74);
    let expected_bytes: f64 = PX4_CONFIG
        .iter()
        .map(|s| s.hz * frame(s.id, s.payload_len) as f64)
        .sum();
    let expected_msgs: f64 = PX4_CONFIG.iter().map(|s| s.hz).sum();
    let tol_bytes: f64 = PX4_CONFIG
        .iter()
        .map(|s| (s.payload_len + 12) as f64)
        .sum::<f64>()
        / row.flight_s;
    let tol_msgs = PX4_CONFIG.len() as f64 / row.flight_s;
    println!(
        "wired: {:.1} B/s (expected {expected_bytes:.1} ± {tol_bytes:.2}), {:.2} msg/s \
         (expected {expected_msgs:.2} ± {tol_msgs:.3})",
        row.bytes_per_s, row.msgs_per_s
    );
    assert!(
        (row.bytes_per_s - expected_bytes).abs() <= tol_bytes,
        "{} vs {expected_bytes}",
        row.bytes_per_s
    );
    assert!((row.msgs_per_s - expected_msgs).abs() <= tol_msgs);
    // and everything sent on the wire arrived
    assert_eq!(
        row.received_msgs as f64,
        (row.msgs_per_s * row.flight_s).round()
    );
}

/// Both relayed uploads finish; on LoRa, whose round trip is several times PX4's 250 ms
/// retry, the naive link floods duplicates and costs more bytes and time than the relay. (On
/// SiK the round trip is about 250 ms, so PX4's retries rarely duplicate: there the naive
/// link is not worse, and the test does not claim it is.)
/// Over a loss-free radio that the filtered telemetry does not saturate, what the bridge
/// hands the radio is what comes out at the ground, frame for frame and byte for byte.
#[test]
fn table_ii_over_a_clean_radio_counts_the_same_on_both_sides() {
    let radios = Radios {
        table_ii: Some(harness_radio::RadioSetup::builtin("sik-64k").unwrap()),
        ..Radios::paper_defaults()
    };
    let row = table_ii::fly(&radios, "limit_filter").unwrap();
    let sent = (row.msgs_per_s * row.flight_s).round() as u64;
    // frames still in the radio when the flight ends: at most a TDM round's worth
    assert!(
        sent - row.received_msgs <= 10,
        "{sent} vs {}",
        row.received_msgs
    );
    assert!(
        (row.bytes_per_s - 417.0).abs() < 20.0,
        "{}",
        row.bytes_per_s
    );
}

#[test]
fn mission_upload_relay_finishes_and_naive_floods_duplicates_on_lora() {
    let radios = Radios::paper_defaults();
    let (ms, log, _) = run_one("mission_upload", &radios, Path::new(""));
    assert_all_pass(&ms);
    let on = |radio: &str, variant: &str, base: &str| {
        value(
            &ms,
            base,
            &[(Dimension::Radio, radio), (Dimension::Variant, variant)],
        )
    };
    for (key, _) in &radios.mission {
        for (ground, _, _) in mission::GROUNDS {
            let relay = value(
                &ms,
                "mission_upload_s",
                &[
                    (Dimension::Radio, key.as_str()),
                    (Dimension::Variant, RELAY),
                    (Dimension::GroundTimeout, ground),
                ],
            );
            assert!(
                relay > 0.0 && relay <= mission::CUT_OFF_S,
                "{key} {ground}: {relay}"
            );
        }
        assert_eq!(on(key, RELAY, "mission_mismatch_on_accept"), 0.0);
        let e = on(key, RELAY, "mission_efficiency");
        // packed items can beat the bound of standard frames: above 1 is possible
        assert!(e > 0.0 && e.is_finite(), "{key}: efficiency {e}");
    }
    let relay = |base: &str| on("lora_sf7", RELAY, base);
    let naive = |base: &str| on("lora_sf7", "naive", base);
    assert!(naive("duplicate_items") >= 50.0);
    assert!(naive("mission_bytes_on_air") > 2.0 * relay("mission_bytes_on_air"));
    let relay_05 = value(
        &ms,
        "mission_upload_s",
        &[
            (Dimension::Radio, "lora_sf7"),
            (Dimension::Variant, RELAY),
            (Dimension::GroundTimeout, "0_5s"),
        ],
    );
    assert!(naive("mission_upload_s") > relay_05);
    // the relay's own uploads to PX4 never duplicate
    assert!(
        log.iter()
            .any(|l| l.contains("lora_sf7 relay") && l.contains(" 0 duplicates"))
    );
}

/// The efficiency's bound is the items as the ground sends them, one 49-byte MISSION_ITEM_INT
/// per air packet (what the uplink carried before the relay packed items: the average item
/// frame it measured then), not what the relay puts on the radio.
#[test]
fn mission_airtime_bound_is_the_grounds_standard_frames() {
    let items = harness_sim::GcsMock::mission(mission::ITEMS);
    assert_eq!(mission::item_frame_len(&items), 49);
    let radios = Radios::paper_defaults();
    for (_, setup) in &radios.mission {
        let preset = setup.preset.resolve().unwrap();
        let u = mission::upload(&radios, &radios.seeded(setup), true, None).unwrap();
        assert_eq!(
            u.needed_airtime,
            preset.time_on_air(49) * u32::from(mission::ITEMS)
        );
        assert!(u.mission_bytes < 100 * 49, "packed: {}", u.mission_bytes);
    }
}

/// The bursty loss the mission scenario configures averages 10 % of the time, as the radio
/// counts it per packet. Fades step in time, so a packet is lost when a fade overlaps any of
/// its airtime: at most 0.1 + 0.9 · (1 − e^(−T/9 s)) for a packet of airtime T with 1 s fades
/// 10 % of the time (mean good spell 9 s): 0.139 for LoRa SF7's longest packet (~0.4 s), plus
/// 0.03 for sampling over a few hundred packets. One upload is a few seconds of a chain
/// whose fades last a second: the share is averaged over 5 seeds.
#[test]
fn mission_radios_lose_ten_percent_on_average() {
    for (key, setup) in &Radios::paper_defaults().mission {
        let (mut down, mut up) = (0.0, 0.0);
        for seed in 1..=5 {
            let radios = Radios {
                seed,
                ..Radios::paper_defaults()
            };
            let u = mission::upload(&radios, &radios.seeded(setup), true, None).unwrap();
            down += u.loss.0 / 5.0;
            up += u.loss.1 / 5.0;
        }
        for (dir, loss) in [("down", down), ("up", up)] {
            assert!(
                (0.06..=0.17).contains(&loss),
                "{key} {dir}: measured loss {loss}"
            );
        }
    }
}

/// Issue 22's target: MAVSDK (0.5 s per step, 5 tries, every repeated request one of
/// them) uploading through router and bridge at 10 % bursty loss, 100 seeds on SiK 64k and
/// on LoRa SF7: at least 99 % of uploads succeed at the ground, and in none do the ground
/// and the vehicle disagree (ACCEPTED for a plan the vehicle does not hold, or a failure
/// while the vehicle took the plan).
#[test]
fn mavsdk_uploads_at_ten_percent_bursty_loss_succeed_and_never_disagree() {
    let defaults = Radios::paper_defaults();
    for (key, setup) in defaults.mission.iter().rev() {
        let (mut ok, mut disagree, mut failed) = (0, Vec::new(), Vec::new());
        for seed in 1..=100 {
            let radios = Radios {
                seed,
                ..defaults.clone()
            };
            let mavsdk = harness_sim::GcsMock::new(mavlora::Instant::ZERO)
                .with_mission_timeouts(timebase::Duration::from_millis(500), 5)
                .with_mavsdk_retry_counting();
            let u =
                mission::upload_with(&radios, &radios.seeded(setup), true, Some(mavsdk)).unwrap();
            let accepted = matches!(
                u.result,
                Some((mavlora::dialect::MavMissionResult::MAV_MISSION_ACCEPTED, _))
            );
            if accepted != u.stored {
                disagree.push((seed, u.result));
            }
            if accepted && u.stored {
                ok += 1;
            } else {
                failed.push((seed, u.result));
            }
        }
        eprintln!("{key}: MAVSDK uploads {ok} of 100 at 10 % bursty loss; failed {failed:?}");
        assert!(
            disagree.is_empty(),
            "{key}: ground and vehicle disagree: {disagree:?}"
        );
        assert!(ok >= 99, "{key}: {ok} of 100 uploads succeeded: {failed:?}");
    }
}

/// At 10 % loss each way a command gets through with 0.9 probability and its ack, which the
/// bridge sends twice on a lossy link, with 0.99: a copy's round trip fails for about 11 % of
/// commands. A ground station that resends after 1.5 s on its own needs a third copy when
/// two round trips fail, for about 1.2 % of commands, which then take 3 s plus a round trip:
/// without the router's resends some commands miss SORA's medium 3 s. With them the 99th
/// percentile meets it.
#[test]
fn c2_latency_meets_sora_medium_only_with_the_routers_resends() {
    let radios = Radios::paper_defaults();
    let (ms, log, _) = run_one("c2_latency", &radios, Path::new(""));
    // the SORA measurements (no radio dimension; the `sik_64k` ones are the project's target)
    let named = |n: &str| {
        ms.iter()
            .find(|m| m.name == n)
            .and_then(|m| m.value)
            .unwrap_or_else(|| panic!("{n} not recorded"))
    };
    let p50 = named("mavlora.c2_latency_p50_ms");
    let p99 = named("mavlora.c2_latency_p99_ms");
    assert!(p50 < 500.0, "p50 {p50}: one round trip expected");
    assert!(p99 <= 3000.0, "p99 {p99} with the command relay");
    let (lat, stats) = c2_latency::measure(&radios).unwrap();
    assert!(stats.started >= c2_latency::COMMANDS);
    assert!(lat.iter().all(|l| l.is_finite()), "a command was given up");
    // Three seeds, 600 commands: at 1.2 % about 7 need a third copy.
    let mut lat = Vec::new();
    for k in 0..3 {
        let seeded = Radios {
            seed: radios.seed + k,
            ..radios.clone()
        };
        let (more, _) =
            c2_latency::measure_with(&seeded, harness_sim::CommandPlan::default(), Some(1))
                .unwrap();
        lat.extend(more);
    }
    let n = lat.len() as f64;
    let above = |ms: f64| lat.iter().filter(|&&l| l > ms).count() as f64;
    // The first copy's round trip failed: the command waited for the ground's 1.5 s resend.
    let first_failed = above(1500.0);
    let p_fail = first_failed / n;
    assert!(
        (0.07..=0.15).contains(&p_fail),
        "{first_failed} of {n} commands needed a second copy: 11 % expected"
    );
    // The second copy fails as often as the first did, no more (a retry path that loses
    // or holds the ground's resend shows here) and no less (binomial, three sigma).
    let second_failed = above(3000.0);
    let expected = first_failed * p_fail;
    let sigma = (first_failed * p_fail * (1.0 - p_fail)).sqrt();
    assert!(
        second_failed >= 1.0 && (second_failed - expected).abs() <= 3.0 * sigma,
        "{second_failed} of the {first_failed} resent commands needed a third copy: \
         {expected:.1} ± {:.1} expected",
        3.0 * sigma
    );
    assert!(
        log.iter()
            .any(|l| l.contains("without the router's resends"))
    );
}

/// Over SiK at 10 % loss each way, a command mix with ground retries, new parameters under
/// the same id and target component 0 or 1 reaches the autopilot exactly once per command,
/// and every execution is of a command the ground sent.
#[test]
fn c2_command_mix_runs_each_command_exactly_once() {
    // The target's ground (0.5 s retries: on this seed every ack comes sooner, so no retry)
    // and an impatient one (0.15 s, near the 131 ms median round trip: it retries every slow
    // command, so the retry path is exercised whatever the seed).
    let radios = Radios::paper_defaults();
    for retry_ms in [500, 150] {
        let retry = timebase::Duration::from_millis(retry_ms);
        let (lat, stats, integrity) = c2_latency::measure_mix(&radios, retry).unwrap();
        eprintln!(
            "sik c2, ground retry {retry_ms} ms: p50 {} p99 {} max {} ms; {} commands, {} \
             copies; {integrity:?}",
            quantile(&lat, 0.5),
            quantile(&lat, 0.99),
            lat.last().unwrap(),
            stats.started,
            stats.copies
        );
        assert_eq!(
            integrity,
            c2_latency::Integrity {
                lost: 0,
                executed_twice: 0,
                unknown: 0
            },
            "ground retry {retry_ms} ms"
        );
        if retry_ms == 150 {
            assert!(
                stats.copies > stats.started,
                "{} copies of {} commands: the impatient ground must retry",
                stats.copies,
                stats.started
            );
        }
    }
}

#[test]
fn attenuation_sweep_finds_the_papers_edges_and_writes_its_csv() {
    let dir = tempfile::tempdir().unwrap();
    let (ms, _, _) = run_one("attenuation_sweep", &Radios::paper_defaults(), dir.path());
    assert_all_pass(&ms);
    let csv = std::fs::read_to_string(dir.path().join("attenuation_sweep.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 3 * 15, "{csv}");
    assert!(csv.lines().any(|l| l.starts_with("lora-sf7,120,")));
}

#[test]
fn blind_drone_is_seen_from_the_ground() {
    // Every seed: no false alarm before the onset, an alarm during the noise, restored after.
    for seed in 1..=5 {
        let radios = Radios {
            seed,
            ..Radios::paper_defaults()
        };
        // Radios that report their noise floor: within the project's 5 s, both ways.
        let d = blind_drone::detect(&radios, true).unwrap();
        assert_eq!(d.false_alarms, 0, "seed {seed}: {d:?}");
        assert!(
            d.detect_s.is_some_and(|s| s < blind_drone::DETECT_TARGET_S),
            "seed {seed}: {d:?}"
        );
        assert!(
            d.restore_s
                .is_some_and(|s| s < blind_drone::RESTORE_TARGET_S),
            "seed {seed}: {d:?}"
        );
        // Radios that do not: counted from the uplink's frames, still while it is deaf.
        let d = blind_drone::detect(&radios, false).unwrap();
        assert_eq!(d.false_alarms, 0, "seed {seed}: {d:?}");
        assert!(
            d.detect_s.is_some_and(|s| s < blind_drone::NOISE_S),
            "seed {seed}: {d:?}"
        );
        assert!(d.restore_s.is_some(), "seed {seed}: {d:?}");
    }
    // The steady cost fits LoRa SF7 (the monitoring budget: 3 B/s each way).
    let (up, down) = blind_drone::monitoring_cost(&Radios::paper_defaults()).unwrap();
    assert!(
        up <= blind_drone::COST_LIMIT_BPS && down <= blind_drone::COST_LIMIT_BPS,
        "{up} {down}"
    );
    assert!(up > 0.0 && down > 0.0, "reports do flow: {up} {down}");
}

/// The airtime the radio reports is the airtime of the frames the bridge sent, one packet
/// each, by the LoRa time-on-air formula (checked in `radio::airtime` against Semtech's):
/// compact telemetry's ~32 B/s costs ~7 % of an SF7/125 kHz channel, under the EU 10 %
/// (11 % when a batch went every second).
#[test]
fn duty_cycle_is_the_airtime_of_the_frames_sent() {
    let radios = Radios::paper_defaults();
    let (ms, _, _) = run_one("duty_cycle", &radios, Path::new(""));
    let coalesced = duty_cycle::measure(&radios).unwrap();
    let on_lora = [(Dimension::Radio, "lora_sf7")];
    assert_eq!(value(&ms, "duty_cycle_pct", &on_lora), coalesced.down_pct);
    // Each frame when ready: the airtime is that of one packet per frame.
    let d = duty_cycle::measure_with(&radios, None, timebase::Duration::ZERO).unwrap();
    let lora = harness_radio::Preset::lora_sf7();
    let expected: f64 = d
        .downlink_sent
        .frames
        .iter()
        .map(|(id, n)| {
            let len = d.downlink_sent.bytes[id] as f64 / *n as f64;
            *n as f64 * lora.time_on_air(len.round() as usize).as_secs_f64()
        })
        .sum::<f64>()
        / d.flight_s
        * 100.0;
    // one frame per packet, but for the odd two that left within the radio's 5 ms idle time
    let frames = d.downlink_sent.total_frames();
    assert!(d.down.packets_sent <= frames && d.down.packets_sent * 100 >= frames * 99);
    assert!(
        (d.down_pct - expected).abs() < 0.05 * expected,
        "{} vs {expected}",
        d.down_pct
    );
    // Unsigned, a frame a second fits the EU 433 MHz 10 % even one frame per packet.
    assert!(d.down_pct < 10.0, "{}", d.down_pct);
    // Coalesced for 1.5 s: the same bytes in fewer packets (the status and the link-quality
    // report ride with a batch), so less airtime.
    let same_bytes =
        coalesced.downlink_sent.total_bytes() as f64 / d.downlink_sent.total_bytes() as f64;
    assert!((0.97..1.03).contains(&same_bytes), "{same_bytes}");
    assert!(
        coalesced.down.packets_sent < d.down.packets_sent,
        "{} packets coalesced, {} not",
        coalesced.down.packets_sent,
        d.down.packets_sent
    );
    assert!(coalesced.down_pct < d.down_pct, "{}", coalesced.down_pct);
    assert!(value(&ms, "uplink_duty_cycle_pct", &on_lora) < coalesced.down_pct);
}

/// Same seed, same numbers; another seed, other numbers (the seed reaches the draws).
#[test]
fn runs_are_deterministic_for_a_seed() {
    let radios = Radios::paper_defaults();
    let a = blind_drone::detect(&radios, false).unwrap();
    let b = blind_drone::detect(&radios, false).unwrap();
    assert_eq!(a, b);
    let other = Radios {
        seed: 2,
        ..radios.clone()
    };
    let c = blind_drone::detect(&other, false).unwrap();
    assert_ne!(a.views, c.views);
    let m1 = mission::upload(&radios, &radios.seeded(&radios.mission[0].1), true, None).unwrap();
    let m2 = mission::upload(&radios, &radios.seeded(&radios.mission[0].1), true, None).unwrap();
    assert_eq!(m1, m2);
}

#[test]
fn quantile_is_nearest_rank() {
    let v: Vec<f64> = (1..=200).map(f64::from).collect();
    assert_eq!(quantile(&v, 0.5), 100.0);
    assert_eq!(quantile(&v, 0.99), 198.0);
    assert!(quantile(&[], 0.5).is_nan());
    assert_eq!(quantile(&[1.0, f64::INFINITY], 0.99), f64::INFINITY);
}

/// A rig file can carry the radios: the built-ins round-trip through TOML, unknown keys
/// are refused.
#[test]
fn radios_round_trip_through_toml() {
    let radios = Radios::paper_defaults();
    let text = toml::to_string(&radios).unwrap();
    let back: Radios = toml::from_str(&text).unwrap();
    assert_eq!(back, radios);
    let partial: Radios = toml::from_str("seed = 7\n").unwrap();
    assert_eq!(partial.seed, 7);
    assert_eq!(partial.mission, radios.mission);
    assert!(toml::from_str::<Radios>("sede = 7\n").is_err());
}

/// Declared once with dimensions, the measurements keep the flat names reports, rig files'
/// `[limits]` and readers of results.json have always used.
#[test]
fn flat_names_are_the_ones_readers_know() {
    let radios = Radios::paper_defaults();
    let mut declared = Declarations::new();
    for s in scenarios() {
        let _ = (s.plan)(&mut declared, &radios);
    }
    let names: Vec<&str> = declared
        .measurements()
        .iter()
        .map(|m| m.name.as_str())
        .collect();
    let mut expected: Vec<String> = Vec::new();
    for v in ["wired", "limit", "limit_filter", "compact"] {
        expected.extend([
            format!("mavlora.{v}.bytes_per_s"),
            format!("mavlora.{v}.msgs_per_s"),
        ]);
    }
    // The ArduPilot-like autopilot's rows (dimension autopilot = ardupilot; px4 stays out of
    // the names), with the position rate and lag where the radio filters.
    for v in ["wired", "limit", "limit_filter", "compact"] {
        expected.extend([
            format!("mavlora.ardupilot.{v}.bytes_per_s"),
            format!("mavlora.ardupilot.{v}.msgs_per_s"),
        ]);
        if matches!(v, "limit_filter" | "compact") {
            expected.extend([
                format!("mavlora.ardupilot.{v}.position_hz"),
                format!("mavlora.ardupilot.{v}.position_lag_p99_s"),
            ]);
        }
    }
    for r in ["lora_sf7", "sik_64k"] {
        for what in [
            "0_5s.mission_upload_s",
            "1_5s.mission_upload_s",
            "mission_mismatch_on_accept",
            "mission_bytes_on_air",
            "mission_efficiency",
            "naive.mission_upload_s",
            "naive.mission_bytes_on_air",
            "naive.duplicate_items",
        ] {
            expected.push(format!("mavlora.{r}.{what}"));
        }
    }
    expected.extend([
        "mavlora.c2_latency_p50_ms".into(),
        "mavlora.c2_latency_p99_ms".into(),
        "mavlora.sik_64k.c2_latency_p50_ms".into(),
        "mavlora.sik_64k.c2_latency_p99_ms".into(),
        "mavlora.sik_64k.commands_lost".into(),
        "mavlora.sik_64k.commands_executed_twice".into(),
    ]);
    for r in ["sik_64k", "lora_sf7", "dmd_dl1"] {
        expected.extend([
            format!("mavlora.{r}.nominal_edge_db"),
            format!("mavlora.{r}.nominal_range_m"),
        ]);
    }
    expected.extend([
        "mavlora.blind_drone.detect_p50_s".into(),
        "mavlora.blind_drone.detect_p95_s".into(),
        "mavlora.blind_drone.detect_p95_counting_only_s".into(),
        "mavlora.blind_drone.restore_p95_s".into(),
        "mavlora.lora_sf7.monitor_uplink_bytes_per_s".into(),
        "mavlora.lora_sf7.monitor_downlink_bytes_per_s".into(),
        "mavlora.lora_sf7.duty_cycle_pct".into(),
        "mavlora.lora_sf7.uplink_duty_cycle_pct".into(),
        "mavlora.soak_heap_growth_pct".into(),
        "mavlora.soak_heap_footprint_kib".into(),
        "mavlora.soak_commands_acked_not_executed".into(),
        "mavlora.soak_commands_given_up".into(),
        "mavlora.soak_commands_executed_twice".into(),
        "mavlora.soak_commands_sent".into(),
        "mavlora.soak_mission_mismatch_on_accept".into(),
        "mavlora.soak_missions_accepted".into(),
        "mavlora.soak_radio_unbalanced_bytes".into(),
        "mavlora.soak_last_position_age_s".into(),
    ]);
    assert_eq!(names, expected);
    let simulated = Selector::any()
        .dim(Dimension::Device, "mavlora")
        .dim(Dimension::Transport, SIMULATED);
    assert!(declared.measurements().iter().all(|m| simulated.matches(m)));
}
