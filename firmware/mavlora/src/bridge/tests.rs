// MAV_DATA_STREAM / REQUEST_DATA_STREAM are deprecated upstream in favour of
// SET_MESSAGE_INTERVAL; they are used here on purpose, for MAVLink 1 autopilots.
#![allow(deprecated)]

use crate::time::Duration;

use mavlink::MavlinkVersion;

use super::*;
use crate::compact::CompactConfig;
use crate::dialect::{
    ATTITUDE_DATA, COMMAND_ACK_DATA, COMMAND_LONG_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA,
    LINK_QUALITY_DATA, MavAutopilot, MavCmd, MavMessage, MavParamType, MavResult, MavType,
    PARAM_SET_DATA, PARAM_VALUE_DATA,
};
use crate::filter::Profile;
use crate::schedule::SchedulerConfig;
use crate::time::Instant;
use crate::wire::{FrameReader, OwnedFrame, Sender, ids};

const PROFILE: &str = r#"
[messages.ATTITUDE]
stream_hz = 0
radio = "drop"
[messages.GLOBAL_POSITION_INT]
stream_hz = 3
radio = 3
"#;

fn config() -> BridgeConfig {
    BridgeConfig::new(
        Profile::parse(PROFILE, "test").unwrap(),
        SchedulerConfig {
            rate_bytes_per_s: 1000,
            burst_bytes: 300,
            max_queued_bytes: 4000,
        },
    )
}

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

fn fc_heartbeat(s: &mut Sender) -> OwnedFrame {
    s.frame(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        ..HEARTBEAT_DATA::default()
    }))
}

/// Every frame the bridge wants to write to the flight controller, decoded.
fn to_fc(b: &mut Bridge, now: Instant) -> Vec<MavMessage> {
    std::iter::from_fn(|| b.poll_fc_transmit(now))
        .map(|f| f.decode::<MavMessage>().unwrap())
        .collect()
}

fn to_radio(b: &mut Bridge, now: Instant) -> Vec<OwnedFrame> {
    b.handle_timeout(now);
    std::iter::from_fn(|| b.poll_radio_transmit(now, usize::MAX)).collect()
}

fn intervals(msgs: &[MavMessage]) -> Vec<(f32, f32)> {
    msgs.iter()
        .filter_map(|m| match m {
            MavMessage::COMMAND_LONG(c) if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                Some((c.param1, c.param2))
            }
            _ => None,
        })
        .collect()
}

/// One of ArduCopter's 1,396 parameters.
fn param_value(name: &str, index: u16, v: f32) -> MavMessage {
    MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
        param_id: name.into(),
        param_value: v,
        param_index: index,
        param_count: 1396,
        ..Default::default()
    })
}

fn ack() -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        result: MavResult::MAV_RESULT_ACCEPTED,
        ..Default::default()
    })
}

#[test]
fn configures_stream_rates_on_first_heartbeat_and_consumes_acks() {
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    assert!(
        to_fc(&mut b, ms(0)).is_empty(),
        "nothing before the FC is seen"
    );
    b.handle_fc_bytes(ms(100), fc_heartbeat(&mut fc).as_bytes());
    let sent = to_fc(&mut b, ms(100));
    assert_eq!(intervals(&sent), vec![(30.0, -1.0), (33.0, 333_333.0)]);
    for msg in &sent {
        let MavMessage::COMMAND_LONG(c) = msg else {
            panic!()
        };
        assert_eq!((c.target_system, c.target_component), (1, 1));
    }
    b.handle_fc_bytes(ms(150), fc.frame(&ack()).as_bytes());
    b.handle_fc_bytes(ms(160), fc.frame(&ack()).as_bytes());
    // acks are ours, not the ground's; fully acked means no retry
    let radio = to_radio(&mut b, ms(3000));
    assert!(radio.iter().all(|f| f.message_id() != 77));
    assert!(to_fc(&mut b, ms(3000)).is_empty());
    assert_eq!(b.stats().config_acks, 2);
}

#[test]
fn unacknowledged_configuration_is_retried_then_given_up() {
    let mut c = config();
    c.config_attempts = 3;
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let mut sends = 0;
    let mut now = ms(0);
    while now < ms(20_000) {
        // heartbeats keep coming: no reboot
        b.handle_fc_bytes(now, fc_heartbeat(&mut fc).as_bytes());
        b.handle_timeout(now);
        sends += intervals(&to_fc(&mut b, now)).len();
        now += Duration::from_millis(500);
    }
    assert_eq!(sends, 3 * 2);
}

#[test]
fn reboot_by_silence_and_by_uptime_going_back_reconfigures() {
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(0), fc_heartbeat(&mut fc).as_bytes());
    assert_eq!(intervals(&to_fc(&mut b, ms(0))).len(), 2);
    // regular heartbeats: nothing new
    b.handle_fc_bytes(ms(1000), fc_heartbeat(&mut fc).as_bytes());
    assert!(intervals(&to_fc(&mut b, ms(1000))).is_empty());
    // 5 s of silence, then a heartbeat: rebooted
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(6000), fc_heartbeat(&mut fc).as_bytes());
    assert_eq!(intervals(&to_fc(&mut b, ms(6000))).len(), 2);
    assert_eq!(b.stats().fc_reboots, 1);
    // a fast reboot: uptime goes from 60 s back to 2 s while heartbeats never stopped
    let att = |t| {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: t,
            ..Default::default()
        })
    };
    b.handle_fc_bytes(ms(6100), fc.frame(&att(60_000)).as_bytes());
    b.handle_fc_bytes(ms(6200), fc.frame(&att(2_000)).as_bytes());
    assert_eq!(intervals(&to_fc(&mut b, ms(6200))).len(), 2);
    assert_eq!(b.stats().fc_reboots, 2);
}

#[test]
fn telemetry_is_filtered_limited_and_commands_go_first() {
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let pos = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA::default());
    for k in 0..50u64 {
        let now = ms(k * 20);
        b.handle_fc_bytes(
            now,
            fc.frame(&MavMessage::ATTITUDE(Default::default()))
                .as_bytes(),
        );
        b.handle_fc_bytes(now, fc.frame(&pos).as_bytes());
    }
    let s = b.stats();
    assert_eq!(s.filter.filtered, 50);
    assert_eq!(s.filter.passed, 3);
    // a command queued behind periodic frames leaves first
    b.handle_fc_bytes(
        ms(1000),
        fc.frame(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA::default()))
            .as_bytes(),
    );
    let out = to_radio(&mut b, ms(1000));
    assert_eq!(out.first().map(|f| f.message_id()), Some(76));
}

/// Real PX4 1.16 on LoRa SF7: at each mode change PX4 sends its camera and gimbal commands
/// (MAV_CMD 2003, 1000, 1001, target its own system, component 0) and repeats them
/// unanswered; as commands they went before everything and held position and the new mode
/// back for 2.6 s. Nothing of the vehicle's own system is beyond the radio: they stay on the
/// vehicle. A command to the ground station still goes.
#[test]
fn the_autopilots_commands_to_its_own_components_stay_off_the_radio() {
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut fc = Sender::new(7, 1, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(0), fc_heartbeat(&mut fc).as_bytes());
    to_radio(&mut b, ms(0));
    let command = |target_system, command| {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system,
            target_component: 0,
            command,
            ..Default::default()
        })
    };
    for k in 0..5 {
        let own = command(7, MavCmd::MAV_CMD_IMAGE_STOP_CAPTURE);
        b.handle_fc_bytes(ms(10 + k), fc.frame(&own).as_bytes());
    }
    let to_ground = command(255, MavCmd::MAV_CMD_REQUEST_MESSAGE);
    b.handle_fc_bytes(ms(20), fc.frame(&to_ground).as_bytes());
    let out: Vec<MavMessage> = to_radio(&mut b, ms(100))
        .iter()
        .filter_map(|f| f.decode::<MavMessage>().ok())
        .filter(|m| matches!(m, MavMessage::COMMAND_LONG(_)))
        .collect();
    assert_eq!(out, [to_ground]);
    assert_eq!(b.stats().fc_own_commands_dropped, 5);
}

/// Issue 21: real ArduPilot behind compact MavLora: a PARAM_SET sent while a parameter list
/// was in flight was echoed to the ground after 7.2 s (8.3 s on LoRa, three sends): the echo
/// waited behind the list in the parameter queue. The answer to the ground's own question
/// goes first; the list keeps its order.
#[test]
fn a_param_set_echo_overtakes_the_parameter_list_in_flight() {
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(0), fc_heartbeat(&mut fc).as_bytes());
    to_fc(&mut b, ms(0));
    // A list in flight: 200 values queued at 1000 B/s (~10 s of them).
    for i in 0..200u16 {
        b.handle_fc_bytes(
            ms(10),
            fc.frame(&param_value("LIST_PARAM", i, 0.0)).as_bytes(),
        );
    }
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    let set = MavMessage::PARAM_SET(PARAM_SET_DATA {
        target_system: 1,
        target_component: 1,
        param_id: "RTL_ALT".into(),
        param_value: 2500.0,
        param_type: MavParamType::MAV_PARAM_TYPE_INT32,
    });
    b.handle_radio_bytes(ms(20), ground.frame(&set).as_bytes());
    assert!(matches!(
        to_fc(&mut b, ms(20))[..],
        [MavMessage::PARAM_SET(_)]
    ));
    // ArduPilot's echo: index 65535.
    b.handle_fc_bytes(
        ms(30),
        fc.frame(&param_value("RTL_ALT", 65535, 2500.0)).as_bytes(),
    );
    let mut echoed_at = None;
    let mut now = ms(30);
    while now < ms(12_000) && echoed_at.is_none() {
        for f in to_radio(&mut b, now) {
            if let Ok(MavMessage::PARAM_VALUE(v)) = f.decode::<MavMessage>()
                && v.param_index == 65535
            {
                echoed_at = Some(now);
            }
        }
        now += Duration::from_millis(50);
    }
    let at = echoed_at.expect("the echo left");
    assert!(at <= ms(1030), "the echo left at {at:?}, behind the list");
    // The list's values are not given priority.
    let mut b2 = Bridge::new(config(), Instant::ZERO).unwrap();
    b2.handle_fc_bytes(ms(0), fc_heartbeat(&mut fc).as_bytes());
    b2.handle_radio_bytes(ms(1), ground.frame(&set).as_bytes());
    b2.handle_fc_bytes(ms(2), fc.frame(&param_value("OTHER", 3, 1.0)).as_bytes());
    assert_eq!(b2.stats().param_answers, 0);
}

/// Issue 21, LoRa SF7 at 10 % bursty loss: a ground reading many values by index (10 in
/// flight, again every second) had every answer sent ahead of everything else; they wanted
/// twice the budget and position at the ground fell to 0.03 Hz. Answers to reads go first
/// within a quarter of the budget, the rest with the list's share; position keeps its rate,
/// every answer still leaves, and a set's echo still goes first.
#[test]
fn many_answers_to_reads_do_not_starve_position_and_a_set_echo_still_goes_first() {
    use crate::dialect::PARAM_REQUEST_READ_DATA;
    let mut c = config();
    c.scheduler = SchedulerConfig::for_radio(250, 600);
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(0), fc_heartbeat(&mut fc).as_bytes());
    to_fc(&mut b, ms(0));
    let (mut positions, mut answers, mut echo_at) = (0, 0, None);
    let mut now = ms(0);
    let mut index = 0u16;
    while now < ms(20_000) {
        // the autopilot's position at 3 Hz
        if now.as_millis().is_multiple_of(333) {
            let pos = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                time_boot_ms: now.as_millis() as u32,
                ..Default::default()
            });
            b.handle_fc_bytes(now, fc.frame(&pos).as_bytes());
        }
        // the ground reads 10 values a second, the autopilot answers each
        if now.as_millis().is_multiple_of(100) {
            let read = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                target_system: 1,
                target_component: 1,
                param_index: index as i16,
                ..Default::default()
            });
            b.handle_radio_bytes(now, ground.frame(&read).as_bytes());
            to_fc(&mut b, now);
            b.handle_fc_bytes(now, fc.frame(&param_value("READ", index, 1.0)).as_bytes());
            index += 1;
        }
        if now == ms(10_000) {
            let set = MavMessage::PARAM_SET(PARAM_SET_DATA {
                target_system: 1,
                target_component: 1,
                param_id: "RTL_ALT".into(),
                param_value: 2500.0,
                param_type: MavParamType::MAV_PARAM_TYPE_INT32,
            });
            b.handle_radio_bytes(now, ground.frame(&set).as_bytes());
            to_fc(&mut b, now);
            b.handle_fc_bytes(
                now,
                fc.frame(&param_value("RTL_ALT", 65535, 2500.0)).as_bytes(),
            );
        }
        for f in to_radio(&mut b, now) {
            match f.decode::<MavMessage>() {
                Ok(MavMessage::GLOBAL_POSITION_INT(_)) => positions += 1,
                Ok(MavMessage::PARAM_VALUE(v)) if v.param_index == 65535 => {
                    echo_at.get_or_insert(now);
                }
                Ok(MavMessage::PARAM_VALUE(_)) => answers += 1,
                _ => {}
            }
        }
        now += Duration::from_millis(1);
    }
    // 20 s at 3 Hz: 60 positions; answers want twice the budget
    assert!(positions >= 50, "{positions} positions in 20 s");
    assert!(answers >= 60, "{answers} answers left");
    let echo = echo_at
        .expect("echoed")
        .saturating_duration_since(ms(10_000));
    assert!(echo <= Duration::from_millis(1000), "echo after {echo:?}");
    let s = b.stats();
    assert!(s.param_answers_paced > 0, "{s:?}");
}

#[test]
fn radio_traffic_reaches_the_fc_and_link_quality_goes_both_ways() {
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    let cmd = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA::default());
    let lq = MavMessage::LINK_QUALITY(LINK_QUALITY_DATA::default());
    b.handle_radio_bytes(ms(10), ground.frame(&cmd).as_bytes());
    b.handle_radio_bytes(ms(20), ground.frame(&lq).as_bytes());
    let fc = to_fc(&mut b, ms(20));
    assert_eq!(fc.len(), 1, "the command, not the report: {fc:?}");
    assert!(b.quality().peer().is_some());
    // our own report leaves every period (from the radio budget)
    let period = config().quality.period;
    let out = to_radio(&mut b, Instant::ZERO + period);
    assert!(out.iter().any(|f| f.message_id() == ids::LINK_QUALITY));
    let mut r = FrameReader::new();
    r.push(out[0].as_bytes());
    let MavMessage::LINK_QUALITY(report) = r.next_frame().unwrap().frame.decode().unwrap() else {
        panic!()
    };
    assert_eq!(report.rx_packets, 2);
}

#[test]
fn ground_heartbeat_is_regenerated_while_the_ground_is_heard() {
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        ..Default::default()
    });
    b.handle_radio_bytes(ms(0), ground.frame(&hb).as_bytes());
    let mut heartbeats = 0;
    let mut seqs = Vec::new();
    for t in (0..20_000).step_by(100) {
        b.handle_timeout(ms(t));
        while let Some(f) = b.poll_fc_transmit(ms(t)) {
            if f.message_id() == ids::HEARTBEAT {
                heartbeats += 1;
                seqs.push(f.sequence());
            }
        }
    }
    // the original plus one per second for the 7 s hold
    assert_eq!(heartbeats, 1 + 7);
    assert!(
        seqs.windows(2).all(|w| w[1] == w[0].wrapping_add(1)),
        "{seqs:?}"
    );
}

#[test]
fn compact_mode_replaces_position_and_heartbeat() {
    let mut c = config();
    c.compact = Some(CompactConfig::default());
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let mut ids = Vec::new();
    for k in 0..50u64 {
        let now = ms(k * 200);
        if k % 5 == 0 {
            b.handle_fc_bytes(now, fc_heartbeat(&mut fc).as_bytes());
        }
        let pos = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: k as u32 * 200,
            ..Default::default()
        });
        b.handle_fc_bytes(now, fc.frame(&pos).as_bytes());
        ids.extend(to_radio(&mut b, now).iter().map(|f| f.message_id()));
    }
    assert!(!ids.contains(&0) && !ids.contains(&33), "{ids:?}");
    // 10 s of position: a frame a second, and the first status's three copies
    let frames = ids.iter().filter(|&&i| i == ids::MAVLORA_COMPACT).count();
    assert!((10..=13).contains(&frames), "{ids:?}");
    assert_eq!(frames, ids.len(), "nothing else: {ids:?}");
}

#[test]
fn compact_mode_carries_the_link_report_in_its_frames() {
    // LINK_QUALITY of its own costs 25 bytes of framing and signature each (11.6 B/s on SiK's
    // budget, measured): in compact mode the report rides in the next compact frame.
    let mut c = config();
    c.compact = Some(CompactConfig::default());
    c.quality.period = Duration::from_secs(2);
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let mut frames = Vec::new();
    for k in 0..50u64 {
        let now = ms(k * 200);
        if k % 5 == 0 {
            b.handle_fc_bytes(now, fc_heartbeat(&mut fc).as_bytes());
        }
        // flying north at 10 m/s
        let pos = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: (k * 200) as u32,
            lat: 553_700_000 + k as i32 * 180,
            vx: 1000,
            ..Default::default()
        });
        b.handle_fc_bytes(now, fc.frame(&pos).as_bytes());
        frames.extend(to_radio(&mut b, now));
    }
    assert!(
        frames
            .iter()
            .all(|f| f.message_id() == ids::MAVLORA_COMPACT)
    );
    let reports = frames
        .iter()
        .filter_map(|f| match f.decode::<MavMessage>().unwrap() {
            MavMessage::MAVLORA_COMPACT(d) => {
                crate::compact::CompactFrame::decode(&d).unwrap().link
            }
            _ => None,
        })
        .count();
    assert!((4..=5).contains(&reports), "{reports} reports in 10 s");
    assert_eq!(b.stats().link_quality_sent as usize, reports);
    // what they cost: a dozen bytes each, no framing
    let c = b.stats().compact;
    assert_eq!(c.link_reports as usize, reports);
    assert!((5..=14).contains(&(c.link_bytes / c.link_reports)), "{c:?}");
}

#[test]
fn compact_profile_drops_unlisted_telemetry_and_counts_it_by_id() {
    // Regression (issue 22, item F): px4-compact.toml let through what it does not list, and
    // PX4 v1.16 sends OPEN_DRONE_ID_LOCATION, OPEN_DRONE_ID_SYSTEM, LINK_NODE_STATUS,
    // DISTANCE_SENSOR and more: 310 B/s instead of the promised < 68. What it drops is counted
    // by message id.
    use crate::dialect::{
        DISTANCE_SENSOR_DATA, LINK_NODE_STATUS_DATA, OPEN_DRONE_ID_LOCATION_DATA,
        OPEN_DRONE_ID_SYSTEM_DATA, STATUSTEXT_DATA,
    };
    use mavlink::Message as _;
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/profiles/px4-compact.toml"
    ))
    .unwrap();
    let mut c = BridgeConfig::new(
        Profile::parse(&text, "px4-compact.toml").unwrap(),
        SchedulerConfig {
            rate_bytes_per_s: 3000,
            burst_bytes: 600,
            max_queued_bytes: 8000,
        },
    );
    c.compact = Some(CompactConfig::default());
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let unlisted = [
        MavMessage::OPEN_DRONE_ID_LOCATION(OPEN_DRONE_ID_LOCATION_DATA {
            latitude: 553_700_000,
            ..Default::default()
        }),
        MavMessage::OPEN_DRONE_ID_SYSTEM(OPEN_DRONE_ID_SYSTEM_DATA {
            operator_latitude: 553_700_000,
            ..Default::default()
        }),
        MavMessage::LINK_NODE_STATUS(LINK_NODE_STATUS_DATA {
            timestamp: 1,
            ..Default::default()
        }),
        MavMessage::DISTANCE_SENSOR(DISTANCE_SENSOR_DATA {
            current_distance: 120,
            ..Default::default()
        }),
    ];
    let mut out = Vec::new();
    let mut offered = 0;
    for k in 0..20u64 {
        let now = ms(k * 500);
        if k % 2 == 0 {
            b.handle_fc_bytes(now, fc_heartbeat(&mut fc).as_bytes());
        }
        for m in &unlisted {
            let frame = fc.frame(m);
            offered += frame.as_bytes().len() as u64;
            b.handle_fc_bytes(now, frame.as_bytes());
        }
        out.extend(to_radio(&mut b, now).iter().map(|f| f.message_id()));
    }
    // a STATUSTEXT is not telemetry: it still goes
    let text = MavMessage::STATUSTEXT(STATUSTEXT_DATA::default());
    b.handle_fc_bytes(ms(10_000), fc.frame(&text).as_bytes());
    out.extend(to_radio(&mut b, ms(10_000)).iter().map(|f| f.message_id()));
    for m in &unlisted {
        assert!(
            !out.contains(&m.message_id()),
            "{} on the radio",
            m.message_name()
        );
    }
    assert!(out.contains(&ids::STATUSTEXT));
    let s = b.stats();
    assert_eq!(s.unlisted_dropped, 80);
    assert_eq!(s.unlisted_dropped_bytes, offered);
    let by_id: Vec<(u32, u64)> = s.unlisted_dropped_by_id.into_iter().collect();
    let mut want: Vec<(u32, u64)> = unlisted.iter().map(|m| (m.message_id(), 20)).collect();
    want.sort();
    assert_eq!(by_id, want);
}

#[test]
fn unlisted_drops_are_counted_by_id_for_a_bounded_number_of_ids() {
    let mut c = config();
    c.profile = Profile::parse(
        "[defaults]\nunlisted = \"drop\"\n[messages.HEARTBEAT]\nradio = \"pass\"\n",
        "p",
    )
    .unwrap();
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(0), fc_heartbeat(&mut fc).as_bytes());
    // 100 made-up telemetry ids (checked as unknown ids: the reader lets them through)
    for id in 0..100u32 {
        let id = 60_000 + id;
        let mut bytes = vec![
            0xFD,
            1,
            0,
            0,
            0,
            1,
            1,
            id as u8,
            (id >> 8) as u8,
            (id >> 16) as u8,
            7,
        ];
        let crc = mavlink::calculate_crc(&bytes[1..], 0);
        bytes.extend_from_slice(&crc.to_le_bytes());
        b.handle_fc_bytes(ms(10), &bytes);
    }
    let s = b.stats();
    assert_eq!(s.unlisted_dropped, 100);
    assert_eq!(s.unlisted_dropped_by_id.len(), UNLISTED_IDS_KEPT);
}

#[test]
fn a_silent_reboot_seen_first_in_the_uptime_counts_once() {
    // Regression: after a 4 s reboot an ATTITUDE arrived before the HEARTBEAT; both the
    // uptime and the silence rule fired, and the configuration went out twice.
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let att = |t| {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: t,
            ..Default::default()
        })
    };
    b.handle_fc_bytes(ms(0), fc_heartbeat(&mut fc).as_bytes());
    b.handle_fc_bytes(ms(100), fc.frame(&att(30_000)).as_bytes());
    to_fc(&mut b, ms(100));
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(4100), fc.frame(&att(5)).as_bytes());
    b.handle_fc_bytes(ms(4150), fc_heartbeat(&mut fc).as_bytes());
    assert_eq!(intervals(&to_fc(&mut b, ms(4150))).len(), 2);
    assert_eq!(b.stats().fc_reboots, 1);
}

const PROFILE_WITH_STREAMS: &str = r#"
[messages.GLOBAL_POSITION_INT]
stream_hz = 3
radio = 3
[data_streams]
all = 0
position = 3
"#;

fn data_streams(msgs: &[MavMessage]) -> Vec<(u32, u16, u8)> {
    msgs.iter()
        .filter_map(|m| match m {
            MavMessage::REQUEST_DATA_STREAM(r) => {
                Some((r.req_stream_id as u32, r.req_message_rate, r.start_stop))
            }
            _ => None,
        })
        .collect()
}

#[test]
fn mavlink1_autopilot_is_configured_with_request_data_stream_in_mavlink1() {
    let mut c = config();
    c.profile = Profile::parse(PROFILE_WITH_STREAMS, "test").unwrap();
    c.config_attempts = 2;
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V1);
    b.handle_fc_bytes(ms(100), fc_heartbeat(&mut fc).as_bytes());
    let frames: Vec<_> = std::iter::from_fn(|| b.poll_fc_transmit(ms(100))).collect();
    assert!(
        frames.iter().all(|f| f.version() == MavlinkVersion::V1),
        "a MAVLink 1 autopilot gets MAVLink 1 frames"
    );
    let msgs: Vec<_> = frames.iter().map(|f| f.decode().unwrap()).collect();
    assert!(intervals(&msgs).is_empty());
    assert_eq!(data_streams(&msgs), vec![(0, 0, 0), (6, 3, 1)]);
    // no ack exists: sent again at each attempt, then no more
    let mut later = Vec::new();
    let mut now = ms(100);
    while now < ms(10_000) {
        now += Duration::from_millis(500);
        b.handle_fc_bytes(now, fc_heartbeat(&mut fc).as_bytes());
        b.handle_timeout(now);
        later.extend(to_fc(&mut b, now));
    }
    assert_eq!(data_streams(&later).len(), 2);
    assert_eq!(b.stats().data_stream_fallbacks, 1);
}

#[test]
fn set_message_interval_refused_as_unsupported_falls_back_to_data_streams() {
    let mut c = config();
    c.profile = Profile::parse(PROFILE_WITH_STREAMS, "test").unwrap();
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(100), fc_heartbeat(&mut fc).as_bytes());
    assert_eq!(intervals(&to_fc(&mut b, ms(100))), vec![(33.0, 333_333.0)]);
    let refused = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        result: MavResult::MAV_RESULT_UNSUPPORTED,
        ..Default::default()
    });
    b.handle_fc_bytes(ms(150), fc.frame(&refused).as_bytes());
    assert_eq!(
        data_streams(&to_fc(&mut b, ms(150))),
        vec![(0, 0, 0), (6, 3, 1)]
    );
    // and SET_MESSAGE_INTERVAL is not retried afterwards
    b.handle_timeout(ms(2200));
    assert!(intervals(&to_fc(&mut b, ms(2200))).is_empty());
}

/// Issue 22 B: ArduPilot 4.x speaks MAVLink 2 and both shipped ArduPilot profiles name their
/// streams only by group: the bridge sent nothing at all ("configuring stream rates", then
/// `config_acks=0`), and a ground station that does not ask for streams itself never saw a
/// position. ArduPilot takes REQUEST_DATA_STREAM in either MAVLink version.
#[test]
fn a_mavlink2_autopilot_gets_the_data_streams_of_a_profile_that_names_streams_only_by_group() {
    let mut c = config();
    c.profile = Profile::parse(
        "[data_streams]\nall = 0\nposition = 3\n[defaults]\nradio = \"pass\"\n",
        "groups-only",
    )
    .unwrap();
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(100), fc_heartbeat(&mut fc).as_bytes());
    let msgs = to_fc(&mut b, ms(100));
    assert!(intervals(&msgs).is_empty());
    assert_eq!(data_streams(&msgs), vec![(0, 0, 0), (6, 3, 1)]);
}

#[test]
fn without_data_streams_a_mavlink1_autopilot_still_gets_set_message_interval() {
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V1);
    b.handle_fc_bytes(ms(100), fc_heartbeat(&mut fc).as_bytes());
    assert_eq!(
        intervals(&to_fc(&mut b, ms(100))),
        vec![(30.0, -1.0), (33.0, 333_333.0)]
    );
}

#[test]
fn a_resent_command_reaches_the_fc_once_and_its_copy_gets_the_cached_ack() {
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    b.handle_fc_bytes(ms(0), fc_heartbeat(&mut fc).as_bytes());
    to_fc(&mut b, ms(0));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let cmd = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        param1: 1.0,
        ..Default::default()
    });
    let is_cmd = |m: &MavMessage| matches!(m, MavMessage::COMMAND_LONG(c) if c.command == MavCmd::MAV_CMD_DO_SET_MODE);
    // as the router sends it: tagged with its run and the copy's radio confirmation
    let radio = |gcs: &mut Sender, msg: &MavMessage, confirmation: u8| {
        let tag = crate::command::CommandTag {
            epoch: 1,
            confirmation,
            age: Duration::ZERO,
        };
        crate::command::ack_tag::tag_command(&gcs.frame(msg), msg, tag)
    };
    b.handle_radio_bytes(ms(100), radio(&mut gcs, &cmd, 0).as_bytes());
    assert_eq!(
        to_fc(&mut b, ms(100)).iter().filter(|m| is_cmd(m)).count(),
        1
    );
    let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        result: MavResult::MAV_RESULT_ACCEPTED,
        ..Default::default()
    });
    b.handle_fc_bytes(ms(120), fc.frame(&ack).as_bytes());
    let acks = |frames: Vec<OwnedFrame>| {
        frames
            .iter()
            .filter(|f| f.message_id() == ids::COMMAND_ACK)
            .count()
    };
    assert_eq!(acks(to_radio(&mut b, ms(120))), 1);
    // the link's loss is not measured yet: the ack goes again half a TDM round later, in
    // another air packet
    assert_eq!(acks(to_radio(&mut b, ms(244))), 0);
    assert_eq!(acks(to_radio(&mut b, ms(245))), 1);
    // both were lost on the radio and the router resends the command (confirmation 1)
    let MavMessage::COMMAND_LONG(mut copy) = cmd.clone() else {
        unreachable!()
    };
    copy.confirmation = 1;
    let copy = MavMessage::COMMAND_LONG(copy);
    b.handle_radio_bytes(ms(1100), radio(&mut gcs, &copy, 1).as_bytes());
    assert_eq!(
        to_fc(&mut b, ms(1100)).iter().filter(|m| is_cmd(m)).count(),
        0,
        "executed once"
    );
    assert_eq!(
        acks(to_radio(&mut b, ms(1100))),
        1,
        "answered from the cache"
    );
    assert_eq!(b.stats().commands.replayed, 1);
    assert_eq!(b.stats().commands.repeated, 1);
}

#[test]
fn compact_mode_keeps_replaced_messages_off_the_radio_before_the_fc_is_known() {
    let mut c = config();
    c.compact = Some(CompactConfig::default());
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let pos = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA::default());
    b.handle_fc_bytes(ms(0), fc.frame(&pos).as_bytes());
    assert!(
        to_radio(&mut b, ms(10))
            .iter()
            .all(|f| f.message_id() != ids::GLOBAL_POSITION_INT)
    );
    assert_eq!(b.stats().held_before_fc, 1);
    // without compact telemetry the same frame goes (the filter allows 3 Hz)
    let mut b = Bridge::new(config(), Instant::ZERO).unwrap();
    b.handle_fc_bytes(ms(0), fc.frame(&pos).as_bytes());
    assert!(
        to_radio(&mut b, ms(10))
            .iter()
            .any(|f| f.message_id() == ids::GLOBAL_POSITION_INT)
    );
}

#[test]
fn with_signing_on_the_local_radios_unsigned_status_still_reaches_the_link_report() {
    // SiK injects RADIO_STATUS into its serial output itself: it cannot be signed, and
    // dropping it with the unsigned air frames would blind the link monitor to the noise
    // floor. It feeds the report, and is not counted as a frame from the peer (nor is an
    // unsigned frame from the air).
    use crate::dialect::RADIO_STATUS_DATA;
    use crate::quality::RssiScale;
    use crate::signing::{SigningConfig, SigningKey};
    let mut config = config();
    config.signing = Some(SigningConfig {
        key: SigningKey([9; 32]),
        link_id: 1,
        epoch: 3_000_000_000,
        state: Default::default(),
    });
    let mut b = Bridge::new(config.clone(), Instant::ZERO).unwrap();
    let status = MavMessage::RADIO_STATUS(RADIO_STATUS_DATA {
        rssi: RssiScale::Sik.from_dbm(Some(-80)),
        noise: RssiScale::Sik.from_dbm(Some(-104)),
        remrssi: 255,
        remnoise: 255,
        ..RADIO_STATUS_DATA::default()
    });
    let mut sik = Sender::new(51, 68, MavlinkVersion::V1);
    b.handle_radio_bytes(ms(10), sik.frame(&status).as_bytes());
    // An unsigned frame from the air is still refused.
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    let cmd = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA::default());
    b.handle_radio_bytes(ms(20), ground.frame(&cmd).as_bytes());
    assert!(to_fc(&mut b, ms(20)).is_empty());
    assert_eq!(b.quality().noise(), Some(-104));
    let out = to_radio(&mut b, Instant::ZERO + config.quality.period);
    let report = out
        .iter()
        .find(|f| f.message_id() == ids::LINK_QUALITY)
        .expect("our report");
    let mut r = FrameReader::new();
    r.push(report.as_bytes());
    let MavMessage::LINK_QUALITY(report) = r.next_frame().unwrap().frame.decode().unwrap() else {
        panic!()
    };
    assert_eq!((report.noise, report.rssi), (-104, -80));
    assert_eq!(
        report.rx_packets, 0,
        "neither the refused command nor the radio's status is a frame of the peer's"
    );
}

/// Compact mode asks the autopilot for its mode and arming at `state_hz` on either way of
/// configuring it (ArduPilot's groups, PX4's intervals): a 1 Hz HEARTBEAT let the ground see a
/// change up to 1 s after the vehicle's own link did (real ArduPilot and PX4, the sitl suite).
/// ArduPilot gets HEARTBEAT only (it answers CURRENT_MODE with a STATUSTEXT that would take
/// the radio), PX4 CURRENT_MODE only (it refuses a HEARTBEAT interval), others both.
#[test]
fn compact_mode_asks_for_heartbeat_or_current_mode_at_state_hz() {
    let heartbeat = (0.0, 200_000.0);
    let current_mode = (436.0, 200_000.0);
    for (autopilot, wanted, unwanted) in [
        (
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            vec![heartbeat],
            Some(current_mode),
        ),
        (
            MavAutopilot::MAV_AUTOPILOT_PX4,
            vec![current_mode],
            Some(heartbeat),
        ),
        (
            MavAutopilot::MAV_AUTOPILOT_GENERIC,
            vec![heartbeat, current_mode],
            None,
        ),
    ] {
        for (profile, streams) in [
            ("[data_streams]\nall = 0\nposition = 3\n", 2),
            ("[messages.33]\nstream_hz = 3\n", 0),
        ] {
            let mut c = config();
            c.profile = Profile::parse(profile, "p").unwrap();
            c.compact = Some(CompactConfig::default());
            let mut b = Bridge::new(c, Instant::ZERO).unwrap();
            let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
            let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot,
                ..HEARTBEAT_DATA::default()
            });
            b.handle_fc_bytes(ms(100), fc.frame(&hb).as_bytes());
            let msgs = to_fc(&mut b, ms(100));
            assert_eq!(data_streams(&msgs).len(), streams, "{profile}");
            let asked = intervals(&msgs);
            assert!(
                wanted.iter().all(|w| asked.contains(w))
                    && unwanted.is_none_or(|u| !asked.contains(&u)),
                "{autopilot:?}, {profile}: {asked:?}"
            );
            // Their acks are the bridge's, whichever way it configured (REQUEST_DATA_STREAM
            // has none): none reaches the radio (the simulated ArduPilot's leaked 4 a second).
            for _ in 0..asked.len() {
                b.handle_fc_bytes(ms(150), fc.frame(&ack()).as_bytes());
            }
            let radio = to_radio(&mut b, ms(200));
            assert!(
                radio.iter().all(|f| f.message_id() != ids::COMMAND_ACK),
                "{autopilot:?}, {profile}: an ack of the bridge's own request went to the radio"
            );
        }
    }
    // not in compact mode, or state_hz = 0: the autopilot's own rates
    for compact in [
        None,
        Some(CompactConfig {
            state_hz: 0.0,
            ..CompactConfig::default()
        }),
    ] {
        let mut c = config();
        c.compact = compact;
        let mut b = Bridge::new(c, Instant::ZERO).unwrap();
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        b.handle_fc_bytes(ms(100), fc_heartbeat(&mut fc).as_bytes());
        let asked = intervals(&to_fc(&mut b, ms(100)));
        assert!(
            asked.iter().all(|(id, _)| *id != 0.0 && *id != 436.0),
            "{asked:?}"
        );
    }
}

/// Regression: a bridge that lost its signing state, its clock a day behind, ran a ground ARM
/// recorded ten minutes before: a stream it had not seen, stamped far "after" its clock. A
/// live command from a ground whose clock agrees with the bridge's still goes through, once
/// the live router answered the bridge's challenge.
#[test]
fn a_bridge_without_signing_state_and_a_clock_a_day_behind_does_not_run_a_recorded_arm() {
    use crate::signing::{LinkSigner, SigningConfig, SigningKey, answer_to};
    let key = SigningKey([9; 32]);
    let real = 300_000_000_000u64; // now, 10 us units since 2015
    let (day, ten_minutes) = (86_400 * 100_000, 600 * 100_000);
    let arm = crate::testutil::arm_command();
    let mut pilot = Sender::new(255, 190, MavlinkVersion::V2);
    let mut router_then = LinkSigner::new(key.clone(), 2, real - ten_minutes);
    let recorded = router_then.sign(&pilot.frame(&arm), ms(0)).unwrap();
    let arms = |msgs: &[MavMessage]| {
        msgs.iter()
            .filter(|m| matches!(m, MavMessage::COMMAND_LONG(c) if c.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM))
            .count()
    };
    for (clock, live) in [(real - day, false), (real, true)] {
        let mut config = config();
        config.signing = Some(SigningConfig {
            key: key.clone(),
            link_id: 1,
            epoch: clock,
            state: Default::default(),
        });
        let mut b = Bridge::new(config, Instant::ZERO).unwrap();
        b.handle_radio_bytes(ms(10), recorded.as_bytes());
        assert_eq!(arms(&to_fc(&mut b, ms(10))), 0, "the recorded ARM ran");
        if live {
            let mut router_now = LinkSigner::new(key.clone(), 2, clock);
            let mut router = Sender::new(255, 191, MavlinkVersion::V2);
            let answer = to_radio(&mut b, ms(15))
                .iter()
                .find_map(|f| answer_to(f, 1))
                .expect("the bridge challenges");
            let answer = router_now.sign(&router.frame(&answer), ms(15)).unwrap();
            b.handle_radio_bytes(ms(15), answer.as_bytes());
            let fresh = router_now.sign(&pilot.frame(&arm), ms(20)).unwrap();
            b.handle_radio_bytes(ms(20), fresh.as_bytes());
            assert_eq!(arms(&to_fc(&mut b, ms(20))), 1, "a live ARM was refused");
        }
    }
}

/// Issue 21: with real PX4 on LoRa SF7 a mode change reached the ground 1.5 s late: three
/// older compact frames saying the old mode waited ahead of it, first in the radio, then in
/// the scheduler. A radio that is behind now holds one compact frame at most, folded with
/// each new one, and a change goes with the commands: the first status out says the new mode,
/// none after it the old one, and no position is lost on the way.
#[test]
fn a_mode_change_behind_a_busy_radio_leaves_first_and_nothing_older_follows_it() {
    const OLD: u32 = 0x0003_0000;
    const NEW: u32 = 0x0404_0000;
    let mut c = config();
    c.compact = Some(CompactConfig::default());
    let mut b = Bridge::new(c, Instant::ZERO).unwrap();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let heartbeat = |fc: &mut Sender, custom_mode| {
        fc.frame(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode,
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            ..HEARTBEAT_DATA::default()
        }))
    };
    let mut fed = Vec::new();
    let mut out = Vec::new();
    for k in 0..=60u64 {
        let now = ms(k * 100);
        if k % 10 == 0 {
            let mode = if k >= 40 { NEW } else { OLD };
            b.handle_fc_bytes(now, heartbeat(&mut fc, mode).as_bytes());
        }
        // 2.5 Hz: under the compactor's 3 Hz, so it takes every one
        if k % 4 == 0 {
            let t = (k * 100) as u32;
            fed.push(t);
            let pos = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                time_boot_ms: t,
                lat: 553_700_000 + k as i32 * 90,
                ..Default::default()
            });
            b.handle_fc_bytes(now, fc.frame(&pos).as_bytes());
        }
        b.handle_timeout(now);
        // the radio takes the first status, then nothing from 0.5 s to 4 s (it is behind)
        let room = if (5..40).contains(&k) { 0 } else { usize::MAX };
        out.extend(std::iter::from_fn(|| b.poll_radio_transmit(now, room)).map(|f| (k, f)));
    }
    let frames: Vec<(u64, crate::compact::CompactFrame)> = out
        .iter()
        .filter_map(|(k, f)| match f.decode::<MavMessage>().unwrap() {
            MavMessage::MAVLORA_COMPACT(d) => {
                Some((*k, crate::compact::CompactFrame::decode(&d).unwrap()))
            }
            _ => None,
        })
        .collect();
    let modes_after: Vec<u32> = frames
        .iter()
        .filter(|(k, _)| *k >= 40)
        .filter_map(|(_, f)| f.status.and_then(|s| s.heartbeat).map(|h| h.custom_mode))
        .collect();
    assert!(!modes_after.is_empty(), "{frames:?}");
    assert!(
        modes_after.iter().all(|&m| m == NEW),
        "a frame saying the old mode after the change: {modes_after:?}"
    );
    let first = frames.iter().find(|(k, _)| *k >= 40).unwrap();
    assert_eq!(first.0, 40, "the change leaves at once");
    // every position fed, once and in order (the merged frames carry them all)
    let times: Vec<u32> = frames
        .iter()
        .filter_map(|(_, f)| f.positions.as_ref())
        .flat_map(|p| p.samples.iter().map(|s| s.time_boot_ms))
        .collect();
    let sent: Vec<u32> = fed.iter().copied().filter(|t| times.contains(t)).collect();
    assert_eq!(times, sent, "in order, no repeats");
    // all but the last batch, still being filled at the end
    assert!(
        fed.iter()
            .filter(|&&t| t <= 4800)
            .all(|t| times.contains(t)),
        "positions lost: fed {fed:?}, sent {times:?}"
    );
    assert!(b.stats().compact_merged > 0);
}
