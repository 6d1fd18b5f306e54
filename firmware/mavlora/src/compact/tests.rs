use crate::time::Duration;

use proptest::prelude::*;

use super::*;
use crate::dialect::{
    CURRENT_MODE_DATA, GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, GpsFixType, HEARTBEAT_DATA,
    LINK_QUALITY_DATA, MISSION_CURRENT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState,
    MavSysStatusSensor, MavType, MissionState, SYS_STATUS_DATA, VFR_HUD_DATA,
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

/// A position 100 m above a home 489 m above sea level, flying north at 10 m/s.
fn position(ms: u32) -> MavMessage {
    MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        time_boot_ms: ms,
        lat: 553_700_000 + (ms / 10) as i32 * 9,
        lon: 103_900_000,
        alt: 589_000,
        relative_alt: 100_000,
        vx: 1000,
        vy: 0,
        vz: 0,
        hdg: 0,
    })
}

fn drain(c: &mut Compactor, now: Instant) -> Vec<MavMessage> {
    std::iter::from_fn(|| c.poll(now)).collect()
}

fn decoded(m: &MavMessage) -> CompactFrame {
    let MavMessage::MAVLORA_COMPACT(data) = m else {
        panic!("{m:?}")
    };
    CompactFrame::decode(data).unwrap()
}

/// Runs a compactor fed by `feed` (called at each wake-up) from 0 to `until`, every frame
/// through `keep` (false: lost on the radio) to an expander; returns what the ground got, with
/// when. Wakes at the compactor's and expander's deadlines and every 10 ms.
fn fly(
    c: &mut Compactor,
    e: &mut Expander,
    until: Instant,
    mut feed: impl FnMut(&mut Compactor, Instant),
    mut keep: impl FnMut(usize, Instant) -> bool,
) -> Vec<(Instant, MavMessage)> {
    let mut got = Vec::new();
    let mut now = Instant::ZERO;
    let mut frames = 0;
    while now < until {
        feed(c, now);
        for m in drain(c, now) {
            frames += 1;
            if keep(frames - 1, now) {
                got.extend(e.expand(now, 1, &m).messages.into_iter().map(|m| (now, m)));
            }
        }
        while let Some((_, m)) = e.poll_heartbeat(now) {
            got.push((now, m));
        }
        let next = [c.poll_timeout(), e.poll_timeout()]
            .into_iter()
            .flatten()
            .min()
            .unwrap_or(now + Duration::from_millis(10))
            .min(now + Duration::from_millis(10));
        now = next.max(now + Duration::from_micros(1));
    }
    got
}

/// A PX4-like feed: HEARTBEAT at 1 Hz with `mode(now)`, position at 3 Hz, SYS_STATUS and
/// GPS_RAW_INT at 1 Hz (no VFR_HUD).
fn px4_feed(mode: impl Fn(Instant) -> (u32, bool)) -> impl FnMut(&mut Compactor, Instant) {
    let mut next = [Instant::ZERO; 3];
    move |c, now| {
        if now >= next[0] {
            let (m, armed) = mode(now);
            c.observe(&heartbeat(m, armed), now);
            c.observe(
                &MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                    voltage_battery: 15_800,
                    battery_remaining: 80,
                    onboard_control_sensors_present:
                        MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO,
                    onboard_control_sensors_enabled:
                        MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO,
                    onboard_control_sensors_health:
                        MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO,
                    ..Default::default()
                }),
                now,
            );
            c.observe(
                &MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                    fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
                    satellites_visible: 14,
                    eph: 80,
                    epv: 120,
                    ..Default::default()
                }),
                now,
            );
            next[0] += Duration::from_secs(1);
        }
        if now >= next[1] {
            // the autopilot booted a minute before the world's clock started
            c.observe(&position(60_000 + now.as_micros() as u32 / 1000), now);
            next[1] += Duration::from_micros(333_333);
        }
    }
}

#[test]
fn three_positions_make_one_frame_a_second_and_a_change_goes_at_once() {
    let mut c = Compactor::new(CompactConfig::default());
    let mut e = Expander::new();
    let arm_at = Instant::from_millis(5_500);
    let got = fly(
        &mut c,
        &mut e,
        Instant::from_secs(12),
        px4_feed(|now| (0x0004_0000, now >= Instant::from_millis(5_500))),
        |_, _| true,
    );
    // 3 positions a second at the ground, arriving a second apart at most
    let positions: Vec<Instant> = got
        .iter()
        .filter(|(_, m)| matches!(m, MavMessage::GLOBAL_POSITION_INT(_)))
        .map(|(t, _)| *t)
        .collect();
    assert!((34..=37).contains(&positions.len()), "{}", positions.len());
    for pair in positions.windows(2).skip(3) {
        assert!(
            pair[1] - pair[0] <= Duration::from_millis(1010),
            "{positions:?}"
        );
    }
    // arming reaches the ground in the heartbeat at once (the FC's heartbeat at 6 s)
    let armed = got.iter().find(|(_, m)| {
        matches!(m, MavMessage::HEARTBEAT(h) if h.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED))
    });
    let at = armed.expect("armed heartbeat").0;
    assert!(at >= arm_at && at <= Instant::from_millis(6_001), "{at:?}");
    assert!(!c.observe(&MavMessage::ATTITUDE(Default::default()), at));
}

#[test]
fn a_lost_frame_does_not_delay_a_mode_change_past_half_a_second() {
    // Regression (issue 22, item 15): the status went once, on change, and a lost one left the
    // ground showing the old mode until the next 10 s status. Now the change goes in three
    // frames 150 ms apart; with the first two lost, the third is at the ground 0.3 s after
    // the bridge heard the change.
    let change = Instant::from_secs(8);
    let mut c = Compactor::new(CompactConfig::default());
    let mut e = Expander::new();
    let mut first_after_change = None;
    let got = fly(
        &mut c,
        &mut e,
        Instant::from_secs(12),
        px4_feed(|now| {
            (
                if now >= change {
                    0x0003_0000
                } else {
                    0x0004_0000
                },
                true,
            )
        }),
        |n, now| {
            if now >= change && first_after_change.is_none() {
                first_after_change = Some(n);
            }
            // the first two frames after the change are lost
            first_after_change.is_none_or(|f| n >= f + 2)
        },
    );
    let shown = got
        .iter()
        .find(|(_, m)| matches!(m, MavMessage::HEARTBEAT(h) if h.custom_mode == 0x0003_0000))
        .expect("new mode at the ground")
        .0;
    assert!(
        shown - change <= Duration::from_millis(500),
        "new mode at the ground {:?} after the change",
        shown - change
    );
    // and no heartbeat after it shows the old mode
    assert!(!got.iter().any(|(t, m)| *t > shown
        && matches!(m, MavMessage::HEARTBEAT(h) if h.custom_mode != 0x0003_0000)));
}

/// PX4 on the bridge's link: HEARTBEAT at 1 Hz (PX4 keeps it there) and CURRENT_MODE at 5 Hz
/// (as the bridge asks); LOITER until `change`, then MISSION, whose HEARTBEAT also carries
/// AUTO's flag in base_mode when `auto_flag`.
fn px4_with_current_mode(change: Instant, auto_flag: bool) -> impl FnMut(&mut Compactor, Instant) {
    let mode = move |now: Instant| {
        if now >= change {
            0x0404_0000
        } else {
            0x0304_0000
        }
    };
    let mut next = [Instant::ZERO; 3];
    move |c, now| {
        if now >= next[0] {
            let mut hb = heartbeat(mode(now), true);
            if let MavMessage::HEARTBEAT(h) = &mut hb
                && auto_flag
                && now >= change
            {
                h.base_mode |= MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED;
            }
            c.observe(&hb, now);
            next[0] += Duration::from_secs(1);
        }
        if now >= next[1] {
            let current = CURRENT_MODE_DATA {
                custom_mode: mode(now),
                intended_custom_mode: mode(now),
                ..Default::default()
            };
            assert!(
                c.observe(&MavMessage::CURRENT_MODE(current), now),
                "kept off the radio"
            );
            next[1] += Duration::from_millis(200);
        }
        if now >= next[2] {
            c.observe(&position(60_000 + now.as_micros() as u32 / 1000), now);
            next[2] += Duration::from_micros(333_333);
        }
    }
}

#[test]
fn a_mode_change_reaches_the_ground_from_current_mode_before_the_next_heartbeat() {
    // Regression (the sitl suite, real PX4 1.16): PX4 heartbeats at 1 Hz, so a change of mode
    // reached the bridge up to 1 s late and the ground 0.7-1 s after the vehicle's own link
    // showed it, or never (a LOITER of 0.56 s between TAKEOFF and MISSION). CURRENT_MODE at
    // 5 Hz brings it within 0.2 s; the HEARTBEAT's new flags after it are not a second change.
    let change = Instant::from_millis(8_100);
    let run = |auto_flag: bool| {
        let mut c = Compactor::new(CompactConfig::default());
        let mut e = Expander::new();
        let got = fly(
            &mut c,
            &mut e,
            Instant::from_secs(16),
            px4_with_current_mode(change, auto_flag),
            |_, _| true,
        );
        (got, c.stats().statuses)
    };
    let (got, statuses) = run(true);
    let shown = got
        .iter()
        .find(|(_, m)| matches!(m, MavMessage::HEARTBEAT(h) if h.custom_mode == 0x0404_0000))
        .expect("new mode at the ground")
        .0;
    assert!(
        shown >= change && shown - change <= Duration::from_millis(200),
        "new mode at the ground {shown:?}, the vehicle changed at {change:?}"
    );
    let (_, statuses_without_flags) = run(false);
    assert_eq!(
        statuses, statuses_without_flags,
        "the HEARTBEAT's flags after CURRENT_MODE's change sent the status again"
    );
}

#[test]
fn nothing_the_vehicle_did_not_report_reaches_the_ground() {
    // Regression (issue 22, item D): before the vehicle sent any, the router made up
    // SYS_STATUS (no sensors, 65535 mV), GPS_RAW_INT (no fix, 255 satellites) and
    // MISSION_CURRENT 65535. An autopilot that sent only its HEARTBEAT gets only HEARTBEATs.
    let mut c = Compactor::new(CompactConfig::default());
    let mut e = Expander::new();
    let got = fly(
        &mut c,
        &mut e,
        Instant::from_secs(10),
        |c, now| {
            if now.as_micros() % 1_000_000 == 0 {
                c.observe(&heartbeat(0x0004_0000, false), now);
            }
        },
        |_, _| true,
    );
    assert!(got.len() >= 8, "{got:?}");
    for (_, m) in &got {
        assert!(matches!(m, MavMessage::HEARTBEAT(_)), "made up: {m:?}");
    }
    // Once it sends SYS_STATUS, the ground gets exactly that.
    c.observe(
        &MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            voltage_battery: 12_600,
            current_battery: 1_234,
            battery_remaining: 71,
            load: 300,
            onboard_control_sensors_present: MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO
                | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS,
            onboard_control_sensors_enabled: MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO,
            onboard_control_sensors_health: MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS,
            ..Default::default()
        }),
        Instant::from_secs(10),
    );
    let now = Instant::from_secs(21);
    let out: Vec<MavMessage> = drain(&mut c, now)
        .iter()
        .flat_map(|m| e.expand(now, 1, m).messages)
        .collect();
    let sys = out
        .iter()
        .find_map(|m| match m {
            MavMessage::SYS_STATUS(s) => Some(s),
            _ => None,
        })
        .expect("SYS_STATUS");
    assert_eq!(
        (
            sys.voltage_battery,
            sys.current_battery,
            sys.battery_remaining,
            sys.load
        ),
        (12_600, 1_234, 71, 300)
    );
    assert_eq!(
        sys.onboard_control_sensors_enabled,
        MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO
    );
    assert_eq!(
        sys.onboard_control_sensors_health,
        MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS
    );
    assert!(!out.iter().any(|m| matches!(
        m,
        MavMessage::GPS_RAW_INT(_) | MavMessage::MISSION_CURRENT(_)
    )));
}

#[test]
fn the_first_positions_have_the_true_altitude_and_gps_waits_for_a_position() {
    // Regression (issue 22, item G): the first batch expanded with an altitude of ~0 m above
    // sea level (the offset came only with a status sent before any position), and
    // GPS_RAW_INT said a 3D fix at 0°, 0° with time 0 before any position.
    let mut c = Compactor::new(CompactConfig::default());
    let mut e = Expander::new();
    let got = fly(
        &mut c,
        &mut e,
        Instant::from_secs(5),
        px4_feed(|_| (0x0004_0000, true)),
        |_, _| true,
    );
    let mut positions = got.iter().filter_map(|(_, m)| match m {
        MavMessage::GLOBAL_POSITION_INT(p) => Some(p),
        _ => None,
    });
    let first = positions.next().expect("a position");
    assert_eq!((first.alt, first.relative_alt), (589_000, 100_000));
    for (_, m) in &got {
        if let MavMessage::GPS_RAW_INT(g) = m {
            assert!(g.lat != 0 && g.lon != 0 && g.time_usec != 0, "{g:?}");
            assert_eq!(g.fix_type, GpsFixType::GPS_FIX_TYPE_3D_FIX);
        }
    }
    assert!(
        got.iter()
            .any(|(_, m)| matches!(m, MavMessage::GPS_RAW_INT(_)))
    );
}

#[test]
fn msl_altitude_is_not_clamped_by_a_16_bit_field() {
    // Regression (issue 22, item 15): an i16 of decimetres clamped 3,700 m to 3,276.7 m.
    let mut c = Compactor::new(CompactConfig::default());
    c.observe(&heartbeat(0, true), Instant::ZERO);
    for k in 0..3u32 {
        let t = Instant::from_millis(u64::from(k) * 333);
        let pos = GLOBAL_POSITION_INT_DATA {
            time_boot_ms: k * 333,
            alt: 3_700_000,
            relative_alt: 40_000,
            ..Default::default()
        };
        c.observe(&MavMessage::GLOBAL_POSITION_INT(pos), t);
    }
    let now = Instant::from_secs(1);
    let mut e = Expander::new();
    let alts: Vec<(i32, i32)> = drain(&mut c, now)
        .iter()
        .flat_map(|m| e.expand(now, 1, m).messages)
        .filter_map(|m| match m {
            MavMessage::GLOBAL_POSITION_INT(p) => Some((p.alt, p.relative_alt)),
            _ => None,
        })
        .collect();
    assert_eq!(alts, vec![(3_700_000, 40_000); 3]);
}

#[test]
fn an_altitude_offset_on_a_rounding_boundary_does_not_cut_batches_short() {
    // alt - relative_alt flickering between 488.95 m and 489.05 m: three samples a frame
    // still; a new home (the offset moving 30 m) starts a new frame.
    let mut c = Compactor::new(CompactConfig::default());
    let mut counts = Vec::new();
    for k in 0..30u32 {
        let t = Instant::from_millis(u64::from(k) * 333);
        let offset = if k >= 20 {
            519_000
        } else if k % 2 == 0 {
            488_950
        } else {
            489_050
        };
        let pos = GLOBAL_POSITION_INT_DATA {
            time_boot_ms: k * 333,
            relative_alt: 100_000,
            alt: 100_000 + offset,
            ..Default::default()
        };
        c.observe(&MavMessage::GLOBAL_POSITION_INT(pos), t);
        for m in drain(&mut c, t) {
            let p = decoded(&m).positions.unwrap();
            counts.push((p.samples.len(), p.alt_offset_dm));
        }
    }
    // 20 samples before the new home: 6 frames of 3 and one of 2 (cut by the new home)
    assert_eq!(
        &counts[..6],
        &[
            (3, 4890),
            (3, 4891),
            (3, 4890),
            (3, 4891),
            (3, 4890),
            (3, 4891)
        ][..]
    );
    assert_eq!(counts[6], (2, 4891));
    assert!(
        counts[7..].iter().all(|&(n, o)| n == 3 && o == 5190),
        "{counts:?}"
    );
}

#[test]
fn speeds_over_25_m_s_climb_and_track_are_carried() {
    // Regression (issue 22, item 15): ground speed saturated at 25.5 m/s and vx/vy were
    // rebuilt from the heading, not the track: 30 m/s north came out as 25.5 m/s east for a
    // vehicle pointing east. Climb saturated at 12.7 m/s.
    let mut c = Compactor::new(CompactConfig::default());
    c.observe(&heartbeat(0, true), Instant::ZERO);
    c.observe(
        &MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
            fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
            ..Default::default()
        }),
        Instant::ZERO,
    );
    c.observe(
        &MavMessage::VFR_HUD(VFR_HUD_DATA {
            airspeed: 28.5,
            throttle: 63,
            ..Default::default()
        }),
        Instant::ZERO,
    );
    for k in 0..3u32 {
        let t = Instant::from_millis(u64::from(k) * 333);
        let pos = GLOBAL_POSITION_INT_DATA {
            time_boot_ms: k * 333,
            lat: 1_000 * k as i32,
            vx: 3_000,
            vy: 0,
            vz: -1_500,
            hdg: 9_000, // pointing east, flying north
            ..Default::default()
        };
        c.observe(&MavMessage::GLOBAL_POSITION_INT(pos), t);
    }
    let now = Instant::from_secs(1);
    let mut e = Expander::new();
    let out: Vec<MavMessage> = drain(&mut c, now)
        .iter()
        .flat_map(|m| e.expand(now, 1, m).messages)
        .collect();
    for m in &out {
        match m {
            MavMessage::GLOBAL_POSITION_INT(p) => {
                assert_eq!((p.vx, p.vy, p.vz, p.hdg), (3_000, 0, -1_500, 9_000));
            }
            MavMessage::VFR_HUD(v) => {
                assert_eq!((v.groundspeed, v.climb, v.heading), (30.0, 15.0, 90));
                assert_eq!((v.airspeed, v.throttle), (28.5, 63), "the autopilot's own");
            }
            MavMessage::GPS_RAW_INT(g) => assert_eq!((g.vel, g.cog), (3_000, 0)),
            _ => {}
        }
    }
    assert!(out.iter().any(|m| matches!(m, MavMessage::VFR_HUD(_))));
}

#[test]
fn airspeed_and_throttle_ride_when_they_move_and_the_ground_keeps_the_last() {
    // Regression (issue 22, item 15): VFR_HUD's airspeed and throttle were always 0. They are
    // the autopilot's own, sent when they moved by the deadband (or with a status).
    let mut c = Compactor::new(CompactConfig::default());
    let mut e = Expander::new();
    // 10 m/s; after 20 s creeping up by 0.1 m/s a second; at 25 s a jump of 2 m/s
    let airspeed = |now: Instant| {
        let t = now.as_secs_f64();
        let creep = ((t - 20.0).clamp(0.0, 5.0) * 10.0).floor() / 100.0;
        10.0 + creep as f32 + if t >= 25.0 { 2.0 } else { 0.0 }
    };
    let got = fly(
        &mut c,
        &mut e,
        Instant::from_secs(30),
        {
            let mut px4 = px4_feed(|_| (0, true));
            move |c: &mut Compactor, now: Instant| {
                c.observe(
                    &MavMessage::VFR_HUD(VFR_HUD_DATA {
                        airspeed: airspeed(now),
                        throttle: 55,
                        ..Default::default()
                    }),
                    now,
                );
                px4(c, now);
            }
        },
        |_, _| true,
    );
    let huds: Vec<(Instant, f32)> = got
        .iter()
        .filter_map(|(t, m)| match m {
            MavMessage::VFR_HUD(v) => Some((*t, v.airspeed)),
            _ => None,
        })
        .collect();
    assert!(huds.len() >= 25, "{}", huds.len());
    for (t, a) in &huds {
        assert!(
            (a - airspeed(*t)).abs() <= 0.5 + 1e-3,
            "{a} at {t:?}: {huds:?}"
        );
    }
    // it moved: not only the first value was sent
    assert!(huds.last().unwrap().1 > 12.0, "{huds:?}");
}

#[test]
fn each_vehicle_is_expanded_from_its_own_status() {
    // Regression (issue 22, item 15): one state for all vehicles: vehicle 1 was shown with
    // vehicle 2's mode and battery.
    let mut e = Expander::new();
    let mut frames = Vec::new();
    for (system, mode, volts) in [(1u8, 0x0004_0000u32, 15_000u16), (2, 0x0003_0000, 11_000)] {
        let mut c = Compactor::new(CompactConfig::default());
        c.observe(&heartbeat(mode, system == 1), Instant::ZERO);
        c.observe(
            &MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                voltage_battery: volts,
                ..Default::default()
            }),
            Instant::ZERO,
        );
        for m in drain(&mut c, Instant::ZERO) {
            frames.push((system, m));
        }
    }
    // vehicle 1's first status, then vehicle 2's, at 0 s; then a position-only frame of
    // vehicle 1 at 1 s
    let mut c = Compactor::new(CompactConfig::default());
    for k in 0..3u32 {
        c.observe(&position(k * 333), Instant::from_millis(u64::from(k) * 333));
    }
    let later_frames = drain(&mut c, Instant::from_secs(1));
    let mut seen = Vec::new();
    let mut record = |system: u8, out: Vec<MavMessage>| {
        for m in out {
            match m {
                MavMessage::HEARTBEAT(h) => seen.push((system, h.custom_mode)),
                MavMessage::SYS_STATUS(s) => seen.push((system, u32::from(s.voltage_battery))),
                _ => {}
            }
        }
    };
    for (system, m) in &frames {
        record(*system, e.expand(Instant::ZERO, *system, m).messages);
    }
    let now = Instant::from_secs(1);
    for m in &later_frames {
        record(1, e.expand(now, 1, m).messages);
    }
    // vehicle 2's heartbeat between frames, due at 1 s
    while let Some((system, m)) = e.poll_heartbeat(now) {
        record(system, vec![m]);
    }
    for (system, value) in &seen {
        let own = if *system == 1 {
            [0x0004_0000, 15_000]
        } else {
            [0x0003_0000, 11_000]
        };
        assert!(
            own.contains(value),
            "vehicle {system} shown with {value:#x}: {seen:?}"
        );
    }
    assert!(seen.contains(&(1, 0x0004_0000)) && seen.contains(&(2, 0x0003_0000)));
    // at 2 s only vehicle 1's heartbeat goes on: vehicle 2 sent nothing since 0 s
    let t = now + HEARTBEAT_PERIOD;
    let later: Vec<(u8, u32)> = std::iter::from_fn(|| e.poll_heartbeat(t))
        .map(|(system, m)| {
            let MavMessage::HEARTBEAT(h) = m else {
                unreachable!()
            };
            (system, h.custom_mode)
        })
        .collect();
    assert_eq!(later, vec![(1, 0x0004_0000)]);
}

#[test]
fn the_expander_keeps_at_most_max_vehicles() {
    // Signed frames only reach it, but a key holder cycling system ids must not grow it.
    let mut c = Compactor::new(CompactConfig::default());
    c.observe(&heartbeat(0, true), Instant::ZERO);
    let frame = drain(&mut c, Instant::ZERO).remove(0);
    let mut e = Expander::new();
    for system in 0..=255u8 {
        let now = Instant::from_millis(u64::from(system));
        assert!(!e.expand(now, system, &frame).messages.is_empty());
    }
    let t = Instant::from_millis(1_300);
    let beating: Vec<u8> = std::iter::from_fn(|| e.poll_heartbeat(t).map(|(s, _)| s)).collect();
    assert_eq!(beating.len(), MAX_VEHICLES, "{beating:?}");
    assert!(
        beating.iter().all(|s| *s >= 240),
        "the most recent kept: {beating:?}"
    );
}

#[test]
fn no_heartbeat_at_the_ground_once_the_autopilots_stopped() {
    // The autopilot's heartbeat stops at 5 s while the bridge still sends (link reports):
    // the ground's HEARTBEATs stop too, within HEARTBEAT_STALE and the hold.
    let mut c = Compactor::new(CompactConfig::default());
    let mut e = Expander::new();
    let got = fly(
        &mut c,
        &mut e,
        Instant::from_secs(15),
        |c, now| {
            if now < Instant::from_secs(5) && now.as_micros() % 1_000_000 == 0 {
                c.observe(&heartbeat(0, true), now);
            }
            if now.as_micros() % 2_000_000 == 0 {
                c.link_report(LINK_QUALITY_DATA::default(), now);
            }
        },
        |_, _| true,
    );
    let last = got
        .iter()
        .filter(|(_, m)| matches!(m, MavMessage::HEARTBEAT(_)))
        .map(|(t, _)| *t)
        .max()
        .unwrap();
    assert!(
        last <= Instant::from_secs(4) + HEARTBEAT_STALE + HEARTBEAT_HOLD,
        "{last:?}"
    );
}

#[test]
fn a_link_report_rides_the_next_frame() {
    let mut c = Compactor::new(CompactConfig::default());
    let report = LINK_QUALITY_DATA {
        time_boot_ms: 1234,
        rx_packets: 99,
        rx_lost: 2,
        rssi: -70,
        remote_rssi: i8::MAX,
        noise: -100,
        ..Default::default()
    };
    c.link_report(report.clone(), Instant::ZERO);
    // no frame of its own right away: it waits for positions (within a batch period)
    c.observe(&position(0), Instant::ZERO);
    assert!(drain(&mut c, Instant::ZERO).is_empty());
    c.observe(&position(333), Instant::from_millis(333));
    c.observe(&position(666), Instant::from_millis(666));
    let out = drain(&mut c, Instant::from_millis(666));
    assert_eq!(out.len(), 1);
    let f = decoded(&out[0]);
    assert_eq!(f.positions.unwrap().samples.len(), 3);
    assert_eq!(f.link, Some(report.clone()));
    // alone, it goes after a batch period
    c.link_report(report, Instant::from_secs(2));
    assert!(drain(&mut c, Instant::from_millis(2_900)).is_empty());
    assert_eq!(c.poll_timeout(), Some(Instant::from_secs(3)));
    let out = drain(&mut c, Instant::from_secs(3));
    assert!(decoded(&out[0]).link.is_some());
}

#[test]
fn coalesced_frames_leave_together_after_the_hold() {
    let mut c = Compactor::new(CompactConfig {
        coalesce: Duration::from_millis(1500),
        ..CompactConfig::default()
    });
    c.observe(&heartbeat(0, false), Instant::ZERO);
    let mut groups: Vec<(u64, usize)> = Vec::new();
    // 10 s of 5 Hz position: every 200 ms observe, then poll (heartbeats unchanged)
    for k in 0..=50u64 {
        let now = Instant::from_millis(k * 200);
        if k % 5 == 0 {
            c.observe(&heartbeat(0, false), now);
        }
        c.observe(&position((k * 200) as u32), now);
        let out = drain(&mut c, now);
        if !out.is_empty() {
            groups.push((k * 200, out.len()));
        }
        // nothing is due before the next release
        if let Some(t) = c.poll_timeout() {
            assert!(
                t > now || !drain(&mut c, now).is_empty(),
                "{t:?} at {now:?}"
            );
        }
    }
    // the first status goes at once (urgent: a new vehicle, three copies); afterwards a
    // second's frames wait and leave in groups of two, every ~2 s
    assert!(groups.len() >= 6, "{groups:?}");
    assert_eq!(&groups[..3], &[(0, 1), (200, 1), (400, 1)]);
    assert!(groups[3..].iter().all(|g| g.1 == 2), "{groups:?}");
    for pair in groups.windows(2).skip(3) {
        let gap = pair[1].0 - pair[0].0;
        assert!((1400..=2200).contains(&gap), "{groups:?}");
    }
}

#[test]
fn keep_alive_status_without_position() {
    // On a bench without GPS there are no positions: the status alone must keep the ground's
    // heartbeat going, once per 1.5 batch periods.
    let mut c = Compactor::new(CompactConfig::default());
    let mut frames = 0;
    let mut now = Instant::ZERO;
    while now < Instant::from_secs(10) {
        if now.as_micros().is_multiple_of(1_000_000) {
            c.observe(&heartbeat(0, false), now);
        }
        frames += drain(&mut c, now).len();
        now = c
            .poll_timeout()
            .unwrap_or(Instant::from_secs(10))
            .min(Instant::from_secs(now.as_secs_f64() as u64 + 1))
            .max(now + Duration::from_millis(1));
    }
    // the three urgent copies at start, then one every 1.5 s
    assert!((8..=10).contains(&frames), "{frames}");
}

#[test]
fn batches_a_little_late_add_no_keep_alive_statuses() {
    // Real clock: the samples of a batch come a little slower than 3 Hz, so frames leave a
    // little more than one batch period apart. Only the first status (three copies and the
    // frames of the next URGENT_FOLLOW) and the 10 s periodic ones may go in 20 s.
    let mut c = Compactor::new(CompactConfig::default());
    c.observe(&heartbeat(0, false), Instant::ZERO);
    let mut statuses = 0;
    let mut now = Instant::ZERO;
    let mut k = 0u64;
    while k < 60 {
        let next_pos = Instant::from_millis(k * 340); // 2.94 Hz
        if next_pos <= now {
            if k.is_multiple_of(3) {
                c.observe(&heartbeat(0, false), now);
            }
            c.observe(&position((k * 340) as u32), now);
            k += 1;
        }
        statuses += drain(&mut c, now)
            .iter()
            .filter(|m| decoded(m).status.is_some())
            .count();
        let wake = c.poll_timeout().unwrap_or(next_pos);
        now = wake
            .min(Instant::from_millis(k * 340))
            .max(now + Duration::from_millis(1));
    }
    let follow = URGENT_FOLLOW.as_secs_f64().ceil() as usize;
    assert!(
        statuses <= URGENT_COPIES as usize + follow + 2,
        "{statuses} statuses in 20 s"
    );
}

#[test]
fn a_jittered_4_hz_autopilot_gives_3_hz_of_samples() {
    // ArduPilot streams position at 4 Hz with a few ms of jitter either way; the compactor
    // must still take 3 samples a second (60 in 20 s, one more or less at the ends).
    let mut c = Compactor::new(CompactConfig::default());
    let mut samples = 0usize;
    let count = |out: &[MavMessage]| {
        out.iter()
            .map(|m| decoded(m).positions.map_or(0, |p| p.samples.len()))
            .sum::<usize>()
    };
    for k in 0..80u64 {
        let jitter = [0i64, -3, 2, -2, 3, -1][k as usize % 6];
        let t = Instant::from_micros((k as i64 * 250_000 + jitter * 1000) as u64 + 10_000);
        c.observe(&position((t.as_micros() / 1000) as u32), t);
        samples += count(&drain(&mut c, t));
    }
    samples += count(&drain(&mut c, Instant::from_secs(30)));
    assert!((59..=61).contains(&samples), "{samples} samples in 20 s");
}

#[test]
fn heartbeat_goes_on_at_1_hz_between_frames_and_stops_with_them() {
    // Frames every ~1 s, then the radio is cut at 12 s: the ground gets a HEARTBEAT at
    // least each second until HEARTBEAT_HOLD after the last frame it heard, then none.
    let cut = Instant::from_secs(12);
    let mut c = Compactor::new(CompactConfig::default());
    let mut e = Expander::new();
    let mut heard = Instant::ZERO;
    let got = fly(
        &mut c,
        &mut e,
        Instant::from_secs(20),
        px4_feed(|_| (0, false)),
        |_, now| {
            if now < cut {
                heard = now;
            }
            now < cut
        },
    );
    let beats: Vec<Instant> = got
        .iter()
        .filter(|(_, m)| matches!(m, MavMessage::HEARTBEAT(_)))
        .map(|(t, _)| *t)
        .collect();
    for pair in beats.windows(2) {
        assert!(
            pair[1] - pair[0] <= Duration::from_millis(1100),
            "{beats:?}"
        );
    }
    let last = *beats.last().unwrap();
    assert!(
        last <= heard + HEARTBEAT_HOLD,
        "{last:?}, last frame {heard:?}"
    );
    assert!(
        last + HEARTBEAT_PERIOD > heard + HEARTBEAT_HOLD,
        "{beats:?}"
    );
}

#[test]
fn a_cruise_second_costs_at_most_55_bytes_signed() {
    // What the shipped batching's byte budget is planned on: 3 samples at 10 m/s, level,
    // heading known; 25 bytes of framing and signature per frame.
    let mut c = Compactor::new(CompactConfig::default());
    let mut e = Expander::new();
    let _ = fly(
        &mut c,
        &mut e,
        Instant::from_millis(9_990),
        px4_feed(|_| (0, true)),
        |_, _| true,
    );
    for k in 0..3u32 {
        let t = Instant::from_millis(10_000 + u64::from(k) * 333);
        c.observe(&position(10_000 + k * 333), t);
        c.observe(&heartbeat(0, true), t);
    }
    let out = drain(&mut c, Instant::from_millis(10_666));
    let f = decoded(&out[0]);
    assert!(f.status.is_none() && f.link.is_none(), "{f:?}");
    let len = f.encoded_len().unwrap();
    assert!(25 + len <= 55, "{len} bytes of data");
}

proptest! {
    /// expand(compact(x)) == x within the precision table of the module doc.
    #[test]
    fn expansion_is_exact_within_precision(
        lat in -900_000_000i32..900_000_000, lon in -1_800_000_000i32..1_800_000_000,
        dlat in prop::collection::vec(-30_000i32..30_000, 2),
        dlon in prop::collection::vec(-60_000i32..60_000, 2),
        rel in -10_000_000i32..10_000_000, drel in prop::collection::vec(-100_000i32..100_000, 2),
        home in -1_000_000i32..9_000_000,
        t0 in 0u32..4_000_000_000, dt in prop::collection::vec(334u32..450, 2),
        hdg in 0u16..36_000, vx: i16, vy: i16, vz: i16,
        custom_mode: u32, armed: bool, voltage: u16, current: i16, remaining in -1i8..=100,
        airspeed in -100.0f32..100.0, throttle in 0u16..=100,
        fix in 0u8..=8, sats: u8, eph: u16, seq: u16, total: u16,
    ) {
        let mut c = Compactor::new(CompactConfig::default());
        let mut now = Instant::ZERO;
        let hb = heartbeat(custom_mode, armed);
        let sys = MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            voltage_battery: voltage, current_battery: current, battery_remaining: remaining,
            ..Default::default()
        });
        let gps = MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
            fix_type: [GpsFixType::GPS_FIX_TYPE_NO_GPS, GpsFixType::GPS_FIX_TYPE_NO_FIX, GpsFixType::GPS_FIX_TYPE_2D_FIX,
                GpsFixType::GPS_FIX_TYPE_3D_FIX, GpsFixType::GPS_FIX_TYPE_RTK_FIXED][usize::from(fix) % 5],
            satellites_visible: sats, eph, epv: eph / 2, ..Default::default() });
        let mc = MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
            seq, total, mission_state: MissionState::MISSION_STATE_ACTIVE, ..Default::default()
        });
        let mut positions = Vec::new();
        let mut t = t0;
        for i in 0..3 {
            let (dl, dn, dr) = if i == 0 { (0, 0, 0) } else { (dlat[i - 1], dlon[i - 1], drel[i - 1]) };
            if i > 0 { t = t.wrapping_add(dt[i - 1]); }
            positions.push(GLOBAL_POSITION_INT_DATA {
                time_boot_ms: t, lat: lat + dl, lon: lon + dn,
                relative_alt: rel + dr, alt: rel + dr + home, vx, vy, vz, hdg,
            });
        }
        let hud = MavMessage::VFR_HUD(VFR_HUD_DATA { airspeed, throttle, ..Default::default() });
        let mut compact = Vec::new();
        for m in [&hb, &sys, &gps, &mc, &hud] {
            prop_assert!(c.observe(m, now));
        }
        for (i, p) in positions.iter().enumerate() {
            if i > 0 { now += Duration::from_millis(u64::from(dt[i - 1])); }
            c.observe(&MavMessage::GLOBAL_POSITION_INT(p.clone()), now);
            compact.extend(std::iter::from_fn(|| c.poll(now)));
        }
        now += Duration::from_secs(2);
        compact.extend(std::iter::from_fn(|| c.poll(now)));
        let mut e = Expander::new();
        let expanded: Vec<MavMessage> =
            compact.iter().flat_map(|m| e.expand(now, 1, m).messages).collect();
        let got: Vec<_> = expanded.iter().filter_map(|m| match m {
            MavMessage::GLOBAL_POSITION_INT(p) => Some(p.clone()), _ => None }).collect();
        prop_assert_eq!(got.len(), 3);
        for (g, x) in got.iter().zip(&positions) {
            prop_assert_eq!((g.lat, g.lon, g.hdg, g.vx, g.vy, g.vz), (x.lat, x.lon, x.hdg, vx, vy, vz));
            prop_assert!((g.relative_alt - x.relative_alt).abs() <= 50);
            prop_assert!((g.alt - x.alt).abs() <= 100, "{} vs {}", g.alt, x.alt);
            prop_assert!((i64::from(g.time_boot_ms.wrapping_sub(x.time_boot_ms) as i32)).abs() <= 5);
        }
        let mut saw = [false; 5];
        for m in &expanded {
            match m {
                MavMessage::HEARTBEAT(h) => {
                    let MavMessage::HEARTBEAT(x) = &hb else { unreachable!() };
                    prop_assert_eq!(h, x);
                    saw[0] = true;
                }
                MavMessage::SYS_STATUS(s) => {
                    prop_assert_eq!((s.voltage_battery, s.current_battery, s.battery_remaining), (voltage, current, remaining));
                    saw[1] = true;
                }
                MavMessage::GPS_RAW_INT(g) => {
                    let MavMessage::GPS_RAW_INT(x) = &gps else { unreachable!() };
                    prop_assert_eq!((g.fix_type, g.satellites_visible, g.eph, g.epv), (x.fix_type, sats, eph, eph / 2));
                    saw[2] = true;
                }
                MavMessage::VFR_HUD(v) => {
                    let speed = f64::from(vx).hypot(f64::from(vy)) / 100.0;
                    prop_assert!((f64::from(v.groundspeed) - speed).abs() <= 1e-3);
                    prop_assert!((f64::from(v.climb) + f64::from(vz) / 100.0).abs() <= 1e-3);
                    prop_assert_eq!(v.heading, (hdg / 100) as i16);
                    // Half the 1 cm/s step, and f32 rounding (14.655 is stored as 14.654999...).
                    prop_assert!((v.airspeed - airspeed).abs() <= 0.005 + 1e-5, "{} vs {airspeed}", v.airspeed);
                    prop_assert_eq!(v.throttle, throttle);
                    saw[4] = true;
                }
                MavMessage::MISSION_CURRENT(m) => {
                    prop_assert_eq!((m.seq, m.total, m.mission_state), (seq, total, MissionState::MISSION_STATE_ACTIVE));
                    saw[3] = true;
                }
                _ => {}
            }
        }
        prop_assert_eq!(saw, [true; 5]);
    }
}

/// Regression (CI, ArduCopter SITL over SiK): an autopilot sending positions at the sample
/// rate (3 Hz, 330-340 ms apart on its clock) reached the bridge with the loaded host's
/// jitter; a sample that came more than 41 ms early by the bridge's clock lost its slot, and
/// the ground saw 670 ms gaps (2.83 Hz). Slots are on the vehicle's clock: every sample
/// goes, whatever the arrival jitter.
#[test]
fn samples_at_the_sample_rate_all_go_whatever_their_arrival_jitter() {
    let mut c = Compactor::new(CompactConfig::default());
    let mut sent = Vec::new();
    for k in 0..60u32 {
        let vehicle_ms = 10_000 + k * 335;
        // arrival up to 90 ms late, alternating: some 90 ms early against the one before
        let jitter = if k % 2 == 0 { 90 } else { 0 };
        let now = Instant::from_millis(u64::from(vehicle_ms + jitter));
        c.observe(&position(vehicle_ms), now);
        for m in drain(&mut c, now) {
            if let Some(p) = decoded(&m).positions {
                sent.extend(p.samples.iter().map(|s| s.time_boot_ms));
            }
        }
    }
    let gaps: Vec<u32> = sent.windows(2).map(|w| w[1] - w[0]).collect();
    // (the frame carries times in 10 ms steps from its first)
    assert!(gaps.iter().all(|&g| g.abs_diff(335) <= 5), "{gaps:?}");
    assert!(sent.len() >= 57, "{} samples", sent.len());
}
