//! Property over the simulated world (PX4-like autopilot, bridge, LoRa SF7 with 10 % loss
//! each way, router, a ground station with 0.5 s timeouts and 3 retries): whatever the ground
//! does (upload, restart with another plan of the same length, cancel, a fence upload), the
//! ground hears ACCEPTED exactly when the autopilot holds exactly its last plan of that type,
//! and no upload touches a plan of another type. 40 seeds.

use harness_radio::{Direction, GilbertElliott, LinkConfig, Preset, RadioSetup};
use harness_sim::{GcsMock, PX4_NORMAL, Px4Fc, World, scheduler_for};
use mavlora::bridge::BridgeConfig;
use mavlora::compact::CompactConfig;
use mavlora::dialect::{MISSION_ITEM_INT_DATA, MavMissionResult, MavMissionType};
use mavlora::filter::Profile;
use mavlora::mission::plan::same_plan;
use mavlora::router::RouterConfig;
use mavlora::{Duration, Instant};

const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;
const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;

fn world(seed: u64) -> World {
    // Bursty loss, about 10 % of packets: fades 300 ms long on average (three LoRa SF7
    // packets of ~100 ms airtime), 7.5 % of the time; a packet is also lost to a fade that
    // starts while it is on air. The chain steps in time (1 ms), so its parameters are per
    // millisecond; `packet_loss_is_about_ten_percent` checks the resulting share.
    let link = |seed| LinkConfig {
        latency_ms: 150.0,
        burst: Some(GilbertElliott::with_mean(0.075, 300.0).unwrap()),
        seed,
        ..LinkConfig::default()
    };
    let mut setup = RadioSetup::builtin("lora-sf7").unwrap();
    setup.downlink = link(seed ^ 0x5555);
    setup.uplink = link(seed ^ 0xAAAA);
    let budget = scheduler_for(Some(&Preset::lora_sf7()));
    let profile = Profile::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../firmware/mavlora/profiles/px4-compact.toml"
    ))
    .unwrap();
    let mut b = BridgeConfig::new(profile, budget);
    b.compact = Some(CompactConfig::default());
    let mut w = World::new(
        Px4Fc::new(PX4_NORMAL, Instant::ZERO, seed),
        Some((b, RouterConfig::new(budget))),
        Some(&setup),
    )
    .unwrap();
    w.gcs = GcsMock::new(Instant::ZERO).with_mission_timeouts(Duration::from_millis(500), 3);
    w
}

fn plan(n: u16, salt: i32) -> Vec<MISSION_ITEM_INT_DATA> {
    GcsMock::mission(n)
        .into_iter()
        .map(|i| MISSION_ITEM_INT_DATA { x: i.x + salt, ..i })
        .collect()
}

fn finish(w: &mut World, limit_s: u64) -> Option<MavMissionResult> {
    let until = w.now + Duration::from_secs(limit_s);
    w.run_until_or(until, |w| w.gcs.result.is_some());
    w.gcs.result.map(|r| r.0)
}

/// The invariant after an upload of `t` ended with `result`.
fn check(w: &World, t: MavMissionType, result: Option<MavMissionResult>, seed: u64) {
    let (ty, last) = w.gcs.last_upload.clone().unwrap();
    assert_eq!(ty, t);
    let holds = same_plan(w.fc.plan(t), &last);
    let accepted = result == Some(MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(
        accepted, holds,
        "seed {seed}: ground told {result:?}, autopilot holds the ground's last {t:?} plan: {holds}"
    );
}

#[test]
fn ground_accepted_iff_the_autopilot_holds_its_last_plan_and_types_stay_apart() {
    let mut accepted = 0;
    for seed in 1..=40u64 {
        let mut w = world(seed);
        w.run_until(Instant::from_millis(5000));
        let n = 5 + (seed % 20) as u16;
        let first = plan(n, 0);
        w.gcs.upload(first.clone(), w.now);
        match seed % 4 {
            // A second MISSION_COUNT with the same count mid-upload, another plan.
            1 => {
                let at = w.now + Duration::from_millis(300 + 97 * seed);
                w.run_until_or(at, |w| w.gcs.result.is_some());
                w.gcs.upload(plan(n, 1_000), w.now);
            }
            // The ground cancels mid-upload: the autopilot keeps its previous mission.
            2 => {
                let at = w.now + Duration::from_millis(200 + 50 * seed);
                w.run_until_or(at, |w| w.gcs.result.is_some());
                if w.gcs.cancel() {
                    let until = w.now + Duration::from_secs(60);
                    w.run_until(until);
                    assert!(
                        w.fc.mission().is_empty() || same_plan(w.fc.mission(), &first),
                        "seed {seed}: a cancelled upload left a mixed plan"
                    );
                    continue;
                }
            }
            _ => {}
        }
        let result = finish(&mut w, 300);
        check(&w, MISSION, result, seed);
        accepted += usize::from(result == Some(MavMissionResult::MAV_MISSION_ACCEPTED));
        if seed % 4 == 3 {
            // A fence upload: the mission stays what it was.
            let mission_before = w.fc.mission().to_vec();
            w.gcs.upload_typed(FENCE, plan(4, 7), w.now);
            let result = finish(&mut w, 300);
            check(&w, FENCE, result, seed);
            assert!(
                same_plan(w.fc.mission(), &mission_before),
                "seed {seed}: the fence upload touched the mission"
            );
        }
    }
    // Not a vacuous property: at 10 % loss with a 0.5 s ground, uploads do complete.
    assert!(accepted >= 28, "{accepted} of 30 uploads accepted");
}

/// The property is exercised at the loss it names: over two minutes of telemetry and
/// heartbeats on each of 8 seeds, each direction loses 6-15 % of its packets. Pooled: the
/// uplink carries ~15 packets a minute, too few for one seed's share to say anything.
#[test]
fn packet_loss_is_about_ten_percent() {
    for direction in [Direction::Downlink, Direction::Uplink] {
        let (mut sent, mut lost) = (0, 0);
        for seed in 1..=8 {
            let mut w = world(seed);
            w.run_until(Instant::from_millis(120_000));
            let s = w.link_stats(direction).unwrap();
            sent += s.packets_sent;
            lost += s.packets_lost;
        }
        let share = lost as f64 / sent.max(1) as f64;
        println!("{direction:?}: {share:.3} of {sent} packets lost");
        assert!(sent >= 200, "{direction:?}: only {sent} packets");
        assert!((0.06..=0.15).contains(&share), "{direction:?}: {share:.3}");
    }
}
