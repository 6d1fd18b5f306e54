use crate::time::Duration;

use proptest::prelude::*;

use super::*;
use crate::dialect::{
    GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, GpsFixType, HEARTBEAT_DATA,
    MAVLORA_POSITION_BATCH_DATA, MISSION_CURRENT_DATA, MavAutopilot, MavMessage, MavModeFlag,
    MavState, MavType, SYS_STATUS_DATA,
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
fn six_positions_make_one_batch_and_status_goes_on_change() {
    let mut c = Compactor::new(CompactConfig::default());
    assert!(c.observe(&heartbeat(0x0004_0000, false), Instant::ZERO));
    let first = drain(&mut c, Instant::ZERO);
    assert!(matches!(first[..], [MavMessage::MAVLORA_STATUS(_)]));
    let pos = GLOBAL_POSITION_INT_DATA::default();
    // 5 Hz in for 2 s: 6 samples taken (3 Hz), one batch out
    let mut batches = 0;
    for k in 0..10u64 {
        let now = Instant::from_millis(k * 200);
        c.observe(&MavMessage::GLOBAL_POSITION_INT(pos.clone()), now);
        batches += drain(&mut c, now)
            .iter()
            .filter(|m| matches!(m, MavMessage::MAVLORA_POSITION_BATCH(b) if b.count == 6))
            .count();
    }
    assert_eq!(batches, 1);
    assert_eq!(
        MAX_BATCH_SAMPLES,
        1 + MAVLORA_POSITION_BATCH_DATA::default().dlat.len()
    );
    // arming is a change: a status goes at once, not at the 10 s period
    let t = Instant::from_millis(1900);
    c.observe(&heartbeat(0x0004_0000, true), t);
    assert!(
        drain(&mut c, t)
            .iter()
            .any(|m| matches!(m, MavMessage::MAVLORA_STATUS(s) if s.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)))
    );
    assert!(!c.observe(&MavMessage::ATTITUDE(Default::default()), t));
}

#[test]
fn coalesced_frames_leave_together_after_the_hold() {
    // one-second batches of three: two of them are ready within each 1.5 s hold
    let mut c = Compactor::new(CompactConfig {
        coalesce: Duration::from_millis(1500),
        batch_samples: 3,
        batch_period: Duration::from_secs(1),
        ..CompactConfig::default()
    });
    c.observe(&heartbeat(0, false), Instant::ZERO);
    let mut groups: Vec<(u64, usize, usize)> = Vec::new();
    // 10 s of 5 Hz position: every 200 ms observe, then poll
    for k in 0..=50u64 {
        let now = Instant::from_millis(k * 200);
        let pos = GLOBAL_POSITION_INT_DATA {
            time_boot_ms: (k * 200) as u32,
            lat: 553_700_000 + k as i32 * 20,
            ..Default::default()
        };
        c.observe(&MavMessage::GLOBAL_POSITION_INT(pos), now);
        let out = drain(&mut c, now);
        if !out.is_empty() {
            let batches = out
                .iter()
                .filter(|m| matches!(m, MavMessage::MAVLORA_POSITION_BATCH(_)))
                .count();
            groups.push((k * 200, batches, out.len() - batches));
        }
        // nothing is due before the next release
        if let Some(t) = c.poll_timeout() {
            assert!(
                t > now || !drain(&mut c, now).is_empty(),
                "{t:?} at {now:?}"
            );
        }
    }
    // the first status waits too; afterwards two batches per release, every ~2 s
    assert!(groups.len() >= 4, "{groups:?}");
    for pair in groups.windows(2).skip(1) {
        let gap = pair[1].0 - pair[0].0;
        assert!((1800..=2200).contains(&gap), "{groups:?}");
    }
    assert!(groups.iter().skip(1).all(|&(_, b, _)| b == 2), "{groups:?}");
    // none lost: what was made left, but for at most two still held at the end
    let released: usize = groups.iter().map(|g| g.1).sum();
    assert!((0..=2).contains(&(c.stats().batches as usize - released)));
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
    let out = drain(&mut c, Instant::from_millis(2400));
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
    while now < Instant::from_secs(10) {
        c.observe(&heartbeat(0, false), now);
        statuses += drain(&mut c, now).len();
        now = c
            .poll_timeout()
            .unwrap()
            .max(now + Duration::from_millis(1));
    }
    // t = 0, 3, 6 and 9 s (batch period 2 s)
    assert!((4..=5).contains(&statuses), "{statuses}");
}

#[test]
fn batches_a_little_late_add_no_keep_alive_statuses() {
    // Real clock: the samples of a batch come a little slower than 3 Hz, so batches leave a
    // little more than one batch period apart.
    // Driven as the bridge's loop drives it (positions in, and poll at every
    // poll_timeout): only the first status and the 10 s periodic ones may go in 20 s.
    let mut c = Compactor::new(CompactConfig::default());
    c.observe(&heartbeat(0, false), Instant::ZERO);
    let mut statuses = 0;
    let mut now = Instant::ZERO;
    let mut k = 0u64;
    while k < 60 {
        let next_pos = Instant::from_millis(k * 340); // 2.94 Hz: every batch 2.04 s
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

/// Position samples in the batches among `out`.
fn batched_samples(out: &[MavMessage]) -> usize {
    out.iter()
        .map(|m| match m {
            MavMessage::MAVLORA_POSITION_BATCH(b) => usize::from(b.count),
            _ => 0,
        })
        .sum()
}

#[test]
fn a_jittered_4_hz_autopilot_gives_3_hz_of_samples() {
    // ArduPilot streams position at 4 Hz with a few ms of jitter either way; the compactor
    // must still take 3 samples a second (60 in 20 s, one more or less at the ends).
    let mut c = Compactor::new(CompactConfig::default());
    let mut samples = 0usize;
    for k in 0..80u64 {
        let jitter = [0i64, -3, 2, -2, 3, -1][k as usize % 6];
        let t = Instant::from_micros((k as i64 * 250_000 + jitter * 1000) as u64 + 10_000);
        let pos = GLOBAL_POSITION_INT_DATA {
            time_boot_ms: (t.as_micros() / 1000) as u32,
            ..Default::default()
        };
        c.observe(&MavMessage::GLOBAL_POSITION_INT(pos), t);
        samples += batched_samples(&drain(&mut c, t));
    }
    samples += batched_samples(&drain(&mut c, Instant::from_secs(30)));
    assert!((59..=61).contains(&samples), "{samples} samples in 20 s");
}

#[test]
fn heartbeat_goes_on_at_1_hz_between_batches_and_stops_with_them() {
    // A batch every ~2 s, then the radio is cut at 12 s: the ground gets a HEARTBEAT at
    // least each second (a batch brings one of its own) until HEARTBEAT_HOLD after the last
    // compact frame it heard, then none.
    let cut = Instant::from_secs(12);
    let mut c = Compactor::new(CompactConfig::default());
    let mut e = Expander::new();
    let mut beats = Vec::new();
    let mut heard = Instant::ZERO;
    let mut now = Instant::ZERO;
    let mut k = 0u64;
    while now < Instant::from_secs(20) {
        if now >= Instant::from_millis(k * 340) {
            c.observe(&heartbeat(0, false), now);
            let pos = GLOBAL_POSITION_INT_DATA {
                time_boot_ms: (k * 340) as u32,
                ..Default::default()
            };
            c.observe(&MavMessage::GLOBAL_POSITION_INT(pos), now);
            k += 1;
        }
        for m in drain(&mut c, now).iter().filter(|_| now < cut) {
            heard = now;
            let out = e.expand(now, 7, m);
            let hb = out.iter().filter(|m| matches!(m, MavMessage::HEARTBEAT(_)));
            beats.extend(hb.map(|_| now));
        }
        while let Some((system, m)) = e.poll_heartbeat(now) {
            assert_eq!(system, 7);
            assert!(matches!(m, MavMessage::HEARTBEAT(_)));
            beats.push(now);
        }
        let next = [c.poll_timeout(), e.poll_timeout()]
            .into_iter()
            .flatten()
            .chain([Instant::from_millis(k * 340)])
            .min()
            .unwrap();
        now = next.max(now + Duration::from_millis(1));
    }
    for pair in beats.windows(2) {
        let gap = pair[1].saturating_duration_since(pair[0]);
        assert!(gap <= Duration::from_millis(1100), "{beats:?}");
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

proptest! {
    /// expand(compact(x)) == x within the precision table of the module doc.
    #[test]
    fn expansion_is_exact_within_precision(
        lat in -900_000_000i32..900_000_000, lon in -1_800_000_000i32..1_800_000_000,
        dlat in prop::collection::vec(-3_000i32..3_000, 5),
        dlon in prop::collection::vec(-6_000i32..6_000, 5),
        rel in -1_000_000i32..1_000_000, drel in prop::collection::vec(-10_000i32..10_000, 5),
        home in -100_000i32..3_000_000,
        t0 in 0u32..4_000_000_000, dt in prop::collection::vec(340u32..600, 5),
        hdg in 0u16..36_000, vx in -1_700i16..1_700, vy in -1_700i16..1_700, vz in -1_200i16..1_200,
        custom_mode: u32, armed: bool, voltage: u16, remaining in -1i8..=100,
        fix in 0u8..=8, sats: u8, seq: u16,
    ) {
        let mut c = Compactor::new(CompactConfig::default());
        let mut now = Instant::ZERO;
        let hb = heartbeat(custom_mode, armed);
        let sys = MavMessage::SYS_STATUS(SYS_STATUS_DATA { voltage_battery: voltage, battery_remaining: remaining, ..Default::default() });
        let gps = MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
            fix_type: [GpsFixType::GPS_FIX_TYPE_NO_GPS, GpsFixType::GPS_FIX_TYPE_NO_FIX, GpsFixType::GPS_FIX_TYPE_2D_FIX,
                GpsFixType::GPS_FIX_TYPE_3D_FIX, GpsFixType::GPS_FIX_TYPE_RTK_FIXED][usize::from(fix) % 5],
            satellites_visible: sats, ..Default::default() });
        let mc = MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA { seq, ..Default::default() });
        let mut positions = Vec::new();
        let mut t = t0;
        for i in 0..MAX_BATCH_SAMPLES {
            let (dl, dn, dr) = if i == 0 { (0, 0, 0) } else { (dlat[i - 1], dlon[i - 1], drel[i - 1]) };
            if i > 0 { t = t.wrapping_add(dt[i - 1]); }
            positions.push(GLOBAL_POSITION_INT_DATA {
                time_boot_ms: t, lat: lat + dl, lon: lon + dn,
                relative_alt: rel + dr, alt: rel + dr + home, vx, vy, vz, hdg,
            });
        }
        let mut compact = Vec::new();
        for m in [&hb, &sys, &gps, &mc] {
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
            compact.iter().flat_map(|m| e.expand(now, 1, m)).collect();
        let got: Vec<_> = expanded.iter().filter_map(|m| match m {
            MavMessage::GLOBAL_POSITION_INT(p) => Some(p.clone()), _ => None }).collect();
        prop_assert_eq!(got.len(), MAX_BATCH_SAMPLES);
        for (g, x) in got.iter().zip(&positions) {
            prop_assert_eq!((g.lat, g.lon, g.hdg), (x.lat, x.lon, x.hdg));
            prop_assert!((g.relative_alt - x.relative_alt).abs() <= 50);
            prop_assert!((g.alt - x.alt).abs() <= 100, "{} vs {}", g.alt, x.alt);
            prop_assert!((i64::from(g.time_boot_ms.wrapping_sub(x.time_boot_ms) as i32)).abs() <= 5);
            prop_assert!((i32::from(g.vz) - i32::from(x.vz)).abs() <= 5);
        }
        let speed = f64::from(vx).hypot(f64::from(vy));
        let mut saw = [false; 4];
        for m in &expanded {
            match m {
                MavMessage::HEARTBEAT(h) => {
                    let MavMessage::HEARTBEAT(x) = &hb else { unreachable!() };
                    prop_assert_eq!(h, x);
                    saw[0] = true;
                }
                MavMessage::SYS_STATUS(s) => {
                    prop_assert_eq!((s.voltage_battery, s.battery_remaining), (voltage, remaining));
                    saw[1] = true;
                }
                MavMessage::GPS_RAW_INT(g) => {
                    let MavMessage::GPS_RAW_INT(x) = &gps else { unreachable!() };
                    prop_assert_eq!((g.fix_type, g.satellites_visible), (x.fix_type, sats));
                    saw[2] = true;
                }
                MavMessage::VFR_HUD(v) => {
                    prop_assert!((f64::from(v.groundspeed) * 100.0 - speed).abs() <= 5.01);
                    prop_assert!((f64::from(v.climb) * 100.0 + f64::from(vz)).abs() <= 5.01);
                    prop_assert_eq!(v.heading, (hdg / 100) as i16);
                }
                MavMessage::MISSION_CURRENT(m) => { prop_assert_eq!(m.seq, seq); saw[3] = true; }
                _ => {}
            }
        }
        prop_assert_eq!(saw, [true; 4]);
    }
}
