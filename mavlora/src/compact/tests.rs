use std::time::Duration;

use proptest::prelude::*;

use super::*;
use crate::dialect::{
    GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, GpsFixType, HEARTBEAT_DATA, MISSION_CURRENT_DATA,
    MavAutopilot, MavMessage, MavModeFlag, MavState, MavType, SYS_STATUS_DATA,
};
use crate::time::Instant;

fn heartbeat(custom_mode: u32, armed: bool) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode: if armed {
            MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        } else {
            MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        },
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

fn drain(c: &mut Compactor, now: Instant) -> Vec<MavMessage> {
    std::iter::from_fn(|| c.poll(now)).collect()
}

#[test]
fn three_positions_make_one_batch_and_status_goes_on_change() {
    let mut c = Compactor::new(CompactConfig::default());
    assert!(c.observe(&heartbeat(0x0004_0000, false), Instant::ZERO));
    let first = drain(&mut c, Instant::ZERO);
    assert!(matches!(first[..], [MavMessage::MAVLORA_STATUS(_)]));
    let pos = GLOBAL_POSITION_INT_DATA::default();
    // 5 Hz in for 1 s: 3 samples taken, one batch out
    let mut batches = 0;
    for k in 0..5u64 {
        let now = Instant::from_millis(k * 200);
        c.observe(&MavMessage::GLOBAL_POSITION_INT(pos.clone()), now);
        batches += drain(&mut c, now)
            .iter()
            .filter(|m| matches!(m, MavMessage::MAVLORA_POSITION_BATCH(b) if b.count == 3))
            .count();
    }
    assert_eq!(batches, 1);
    // arming is a change: a status goes at once, not at the 10 s period
    let t = Instant::from_millis(900);
    c.observe(&heartbeat(0x0004_0000, true), t);
    assert!(
        drain(&mut c, t)
            .iter()
            .any(|m| matches!(m, MavMessage::MAVLORA_STATUS(s) if s.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)))
    );
    assert!(!c.observe(&MavMessage::ATTITUDE(Default::default()), t));
}

#[test]
fn position_jump_starts_a_new_batch_instead_of_overflowing() {
    let mut c = Compactor::new(CompactConfig::default());
    let a = GLOBAL_POSITION_INT_DATA::default();
    let b = GLOBAL_POSITION_INT_DATA {
        lat: 40_000, // 4.4 km north: does not fit an i16 delta
        time_boot_ms: 400,
        ..a.clone()
    };
    c.observe(&MavMessage::GLOBAL_POSITION_INT(a), Instant::ZERO);
    c.observe(
        &MavMessage::GLOBAL_POSITION_INT(b),
        Instant::from_millis(400),
    );
    let out = drain(&mut c, Instant::from_millis(400));
    let [MavMessage::MAVLORA_POSITION_BATCH(first)] = &out[..] else {
        panic!("{out:?}");
    };
    assert_eq!((first.count, first.lat), (1, 0));
    let out = drain(&mut c, Instant::from_millis(1400));
    let [MavMessage::MAVLORA_POSITION_BATCH(second)] = &out[..] else {
        panic!("{out:?}");
    };
    assert_eq!((second.count, second.lat), (1, 40_000));
}

#[test]
fn keep_alive_status_without_position() {
    // On a bench without GPS there are no positions: the status alone must keep the ground's
    // heartbeat going, once per 1.5 batch periods.
    let mut c = Compactor::new(CompactConfig::default());
    c.observe(&heartbeat(0, false), Instant::ZERO);
    let mut statuses = 0;
    let mut now = Instant::ZERO;
    while now < Instant::from_secs_for_test(10) {
        c.observe(&heartbeat(0, false), now);
        statuses += drain(&mut c, now).len();
        now = c
            .poll_timeout()
            .unwrap()
            .max(now + Duration::from_millis(1));
    }
    assert!((6..=8).contains(&statuses), "{statuses}");
}

#[test]
fn batches_a_little_late_add_no_keep_alive_statuses() {
    // Real clock: the third sample of a batch arrives a few ms after one batch period.
    // Driven as the bridge's loop drives it (positions in, and poll at every
    // poll_timeout): only the first status and the 10 s periodic ones may go in 20 s.
    let mut c = Compactor::new(CompactConfig::default());
    c.observe(&heartbeat(0, false), Instant::ZERO);
    let mut statuses = 0;
    let mut now = Instant::ZERO;
    let mut k = 0u64;
    while k < 60 {
        let next_pos = Instant::from_millis(k * 340); // 2.94 Hz: every batch 1.02 s
        if next_pos <= now {
            let pos = GLOBAL_POSITION_INT_DATA {
                time_boot_ms: (k * 340) as u32,
                ..Default::default()
            };
            c.observe(&MavMessage::GLOBAL_POSITION_INT(pos), now);
            k += 1;
        }
        statuses += drain(&mut c, now)
            .iter()
            .filter(|m| matches!(m, MavMessage::MAVLORA_STATUS(_)))
            .count();
        let wake = c
            .poll_timeout()
            .unwrap_or(next_pos)
            .max(now + Duration::from_millis(1));
        now = wake
            .min(Instant::from_millis(k * 340))
            .max(now + Duration::from_millis(1));
    }
    assert!(statuses <= 3, "{statuses} statuses in 20 s");
}

impl Instant {
    fn from_secs_for_test(s: u64) -> Self {
        Self::from_millis(s * 1000)
    }
}
