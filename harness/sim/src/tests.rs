use harness_radio::{Access, Direction, LinkConfig, RadioSetup};
use mavlora::{Duration, Instant};

use super::*;

/// DMD DL1 (100 kbit/s, burst access) with 100 ms latency each way, every packet lost with
/// `uplink_loss` on the uplink (ground → air); no loss on the downlink.
fn dmd(uplink_loss: f64) -> RadioSetup {
    let mut setup = RadioSetup::builtin("dmd-dl1").unwrap();
    for link in [&mut setup.uplink, &mut setup.downlink] {
        link.latency_ms = 100.0;
    }
    setup.uplink = LinkConfig {
        packet_loss: uplink_loss,
        ..setup.uplink
    };
    setup
}

fn plain_radio_world(setup: &RadioSetup) -> World {
    World::new(Px4Fc::new(&[], Instant::ZERO, 1), None, Some(setup)).unwrap()
}

#[test]
fn the_papers_route_takes_513_s_and_comes_home() {
    let r = Route::PAPER;
    assert!((r.duration().as_secs_f64() - 513.33).abs() < 0.01);
    let top = r.at(r.altitude_m / r.climb_m_s + 200.0);
    assert!((top.north.hypot(top.east) - 2000.0).abs() < 1.0, "{top:?}");
    assert!((top.up - 100.0).abs() < 1e-9);
    assert!((top.vn.hypot(top.ve) - 10.0).abs() < 1e-9);
    let end = r.at(r.duration().as_secs_f64() + 1.0);
    assert_eq!(end, Kinematics::default());
}

#[test]
fn commands_are_acked_after_one_round_trip_on_a_clean_link() {
    let setup = dmd(0.0);
    let mut w = plain_radio_world(&setup);
    w.gcs.start_commands(CommandPlan::default(), w.now);
    w.run_until(Instant::from_millis(21_000));
    let s = w.gcs.command_stats();
    assert!(s.acked >= 9, "{s:?}");
    assert_eq!((s.failed, s.copies), (0, s.started));
    // One round trip: each way the radio's idle wait, the packet's airtime (a command frame
    // is at most 45 bytes, its ack shorter) and the latency; nothing resent.
    let preset = setup.preset.resolve().unwrap();
    let Access::Burst(burst) = preset.access else {
        unreachable!("DMD DL1 is a burst radio")
    };
    let one_way_min = Duration::from_secs_f64((100.0 + burst.idle_ms) / 1e3);
    let one_way_max =
        one_way_min + preset.time_on_air(45) + Duration::from_secs_f64(preset.gap_ms / 1e3);
    for l in &s.latencies {
        assert!(
            (2 * one_way_min..=2 * one_way_max).contains(l),
            "{l:?} outside {:?}..={:?}",
            2 * one_way_min,
            2 * one_way_max
        );
    }
    assert_eq!(w.fc.stats().commands_acked, s.acked);
    assert_eq!(w.link_stats(Direction::Uplink).unwrap().packets_lost, 0);
}

#[test]
fn unanswered_commands_are_resent_every_1_5_s_then_given_up() {
    let mut w = plain_radio_world(&dmd(1.0));
    w.gcs.start_commands(CommandPlan::default(), w.now);
    w.run_until(Instant::from_millis(9_000));
    let s = w.gcs.command_stats();
    // first copy at 0, four more 1.5 s apart, given up at 7.5 s
    assert_eq!((s.started, s.copies, s.failed, s.acked), (1, 5, 1, 0));
}

#[test]
fn the_usb_profile_is_px4s_config_rates() {
    let msgs: f64 = PX4_CONFIG.iter().map(|s| s.hz).sum();
    assert!((msgs - 347.5).abs() < 1e-9);
    let rate = |id| PX4_CONFIG.iter().find(|s| s.id == id).map(|s| s.hz);
    assert_eq!(rate(30), Some(50.0)); // ATTITUDE
    assert_eq!(rate(105), Some(50.0)); // HIGHRES_IMU
    assert_eq!(rate(26), Some(25.0)); // SCALED_IMU
    assert_eq!(rate(32), Some(30.0)); // LOCAL_POSITION_NED
}
