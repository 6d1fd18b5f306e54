use crate::time::Duration;

use super::*;
use crate::time::Instant;

fn link(loss: f64) -> LinkConfig {
    LinkConfig {
        latency: Duration::from_millis(100),
        bytes_per_s: 10_000,
        loss,
    }
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
    let mut w = World::direct(&[], link(0.0), link(0.0), 1);
    w.gcs.start_commands(CommandPlan::default(), w.now);
    w.run_until(Instant::from_millis(21_000));
    let s = w.gcs.command_stats();
    assert!(s.acked >= 9, "{s:?}");
    assert_eq!((s.failed, s.copies), (0, s.started));
    // 45-byte command + 100 ms, 14-byte ack + 100 ms, at 10 kB/s
    for l in &s.latencies {
        assert!((200..=215).contains(&l.as_millis()), "{l:?}");
    }
    assert_eq!(w.fc.stats().commands_acked, s.acked);
}

#[test]
fn unanswered_commands_are_resent_every_1_5_s_then_given_up() {
    let mut w = World::direct(&[], link(0.0), link(1.0), 1);
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
