use mavlink::MavlinkVersion;

use super::*;
use crate::compact::{CompactConfig, Compactor};
use crate::dialect::{
    COMMAND_ACK_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, MISSION_COUNT_DATA, MavAutopilot,
    MavMessage, MavType,
};
use crate::router::{GroundPolicy, GroundRejection};
use crate::schedule::SchedulerConfig;
use crate::time::Instant;
use crate::wire::{FrameReader, OwnedFrame, Sender, ids, known};

fn router() -> Router {
    Router::new(
        RouterConfig::new(SchedulerConfig {
            rate_bytes_per_s: 1000,
            burst_bytes: 300,
            max_queued_bytes: 4000,
        }),
        Instant::ZERO,
    )
    .unwrap()
}

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

fn gcs_out(r: &mut Router) -> Vec<OwnedFrame> {
    std::iter::from_fn(|| r.poll_gcs_transmit()).collect()
}

#[test]
fn compact_frames_expand_into_one_gap_free_vehicle_stream() {
    use crate::dialect::{
        GPS_RAW_INT_DATA, GpsFixType, MISSION_CURRENT_DATA, SYS_STATUS_DATA, VFR_HUD_DATA,
    };
    let mut c = Compactor::new(CompactConfig::default());
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        ..Default::default()
    });
    let status = [
        hb.clone(),
        MavMessage::SYS_STATUS(SYS_STATUS_DATA::default()),
        MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
            fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
            ..Default::default()
        }),
        MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA::default()),
        MavMessage::VFR_HUD(VFR_HUD_DATA::default()),
    ];
    // samples on the vehicle's clock, one per 340 ms
    let pos = |k: u64| {
        MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: 1000 + k as u32 * 340,
            ..Default::default()
        })
    };
    let mut bridge = Sender::new(1, 191, MavlinkVersion::V2);
    let mut radio = Vec::new();
    let mut frames = 0;
    for k in 0..9u64 {
        for m in &status {
            c.observe(m, ms(k * 340));
        }
        c.observe(&pos(k), ms(k * 340));
        while let Some(m) = c.poll(ms(k * 340)) {
            radio.extend_from_slice(bridge.frame(&m).as_bytes());
            frames += 1;
        }
    }
    // a frame the autopilot sent itself, forwarded through the bridge, with its own sequence
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    fc.set_next_sequence(77);
    let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA::default());
    radio.extend_from_slice(fc.frame(&ack).as_bytes());

    let mut r = router();
    r.handle_radio_bytes(ms(3000), &radio);
    let out = gcs_out(&mut r);
    let mut reader = FrameReader::new();
    for f in &out {
        reader.push(f.as_bytes());
    }
    let frames_out: Vec<_> = std::iter::from_fn(|| reader.next_frame()).collect();
    assert_eq!(frames_out.len(), out.len(), "every frame checks");
    let ids: Vec<u32> = frames_out.iter().map(|f| f.frame.message_id()).collect();
    assert_eq!(ids.iter().filter(|&&i| i == 33).count(), 9, "{ids:?}");
    for id in [0, 1, 24, 42, 74, 77] {
        assert!(ids.contains(&id), "{id} missing from {ids:?}");
    }
    assert!(
        frames_out
            .iter()
            .all(|f| (f.frame.system_id(), f.frame.component_id()) == (1, 1))
    );
    assert_eq!(reader.stats().lost, 0, "renumbered stream has no gaps");
    assert_eq!(r.stats().expanded_frames, frames);
}

#[test]
fn the_bridges_link_report_in_a_compact_frame_feeds_the_monitor_and_reaches_the_ground() {
    use crate::dialect::LINK_QUALITY_DATA;
    let mut c = Compactor::new(CompactConfig::default());
    let report = LINK_QUALITY_DATA {
        time_boot_ms: 5_000,
        rx_packets: 40,
        rx_lost: 10,
        rssi: -80,
        remote_rssi: -82,
        noise: -101,
        ..Default::default()
    };
    c.link_report(report.clone(), ms(0));
    let mut bridge = Sender::new(7, 191, MavlinkVersion::V2);
    let frame = c
        .poll(ms(1000))
        .expect("the report alone after a batch period");
    let mut r = router();
    r.handle_radio_bytes(ms(1000), bridge.frame(&frame).as_bytes());
    assert_eq!(
        r.quality().peer().map(|p| p.report.clone()),
        Some(report.clone())
    );
    let out = gcs_out(&mut r);
    let lq: Vec<_> = out
        .iter()
        .filter(|f| f.message_id() == ids::LINK_QUALITY)
        .collect();
    assert_eq!(lq.len(), 1);
    assert_eq!((lq[0].system_id(), lq[0].component_id()), (7, 191));
    assert_eq!(
        lq[0].decode::<MavMessage>().unwrap(),
        MavMessage::LINK_QUALITY(report)
    );
    // a report alone is the link, not the vehicle: no heartbeat is made of it
    assert!(out.iter().all(|f| f.message_id() != ids::HEARTBEAT));
}

#[test]
fn ground_heartbeats_are_thinned_towards_the_radio() {
    let mut config = RouterConfig::new(SchedulerConfig {
        rate_bytes_per_s: 1000,
        burst_bytes: 300,
        max_queued_bytes: 4000,
    });
    config.gcs_heartbeat_period = crate::time::Duration::from_secs(5);
    let mut r = Router::new(config, Instant::ZERO).unwrap();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_GCS,
        ..Default::default()
    });
    let mut sent = 0;
    for t in 0..20 {
        r.handle_gcs_bytes(ms(t * 1000), gcs.frame(&hb).as_bytes());
        while let Some(f) = r.poll_radio_transmit(ms(t * 1000), usize::MAX) {
            sent += usize::from(f.message_id() == ids::HEARTBEAT);
        }
    }
    assert_eq!(sent, 4);
    assert_eq!(r.stats().filter.rate_limited, 16);
}

#[test]
fn ground_upload_ends_at_the_router_and_the_plan_goes_out_as_one_stream() {
    use crate::dialect::MISSION_ITEM_INT_DATA;
    let mut r = router();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut bridge = Sender::new(1, 191, MavlinkVersion::V2);
    let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: 3,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    });
    let item = |seq: u16| {
        MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
            seq,
            target_system: 1,
            target_component: 1,
            x: i32::from(seq),
            ..Default::default()
        })
    };
    let asked = |r: &mut Router| -> Vec<u16> {
        gcs_out(r)
            .into_iter()
            .filter(|f| f.message_id() == ids::MISSION_REQUEST_INT)
            .map(|f| {
                // the router asks the ground for every item itself, as the vehicle (1, 1)
                assert_eq!((f.system_id(), f.component_id()), (1, 1));
                match f.decode::<MavMessage>().unwrap() {
                    MavMessage::MISSION_REQUEST_INT(q) => q.seq,
                    other => panic!("{other:?}"),
                }
            })
            .collect()
    };
    let mission = |m: &MavMessage| {
        matches!(
            m,
            MavMessage::MISSION_COUNT(_)
                | MavMessage::MISSION_ITEM_INT(_)
                | MavMessage::MAVLORA_MISSION_ITEMS(_)
        )
    };
    r.handle_gcs_bytes(ms(0), gcs.frame(&count).as_bytes());
    // The count leaves at once: the plan streams while the ground sends it.
    let mut radio: Vec<MavMessage> = radio_out(&mut r, ms(0))
        .into_iter()
        .filter(mission)
        .collect();
    assert_eq!(asked(&mut r), vec![0]);
    r.handle_gcs_bytes(ms(10), gcs.frame(&item(0)).as_bytes());
    // The tail (items 1 and 2) is held back: item 0 goes out with a poll behind it.
    let mut t = 10;
    while radio
        .iter()
        .filter(|m| matches!(m, MavMessage::MAVLORA_MISSION_ITEMS(p) if p.items == 0))
        .count()
        < 1
    {
        t += 50;
        radio.extend(radio_out(&mut r, ms(t)).into_iter().filter(mission));
    }
    assert!(asked(&mut r).is_empty(), "the tail waits for the bridge");
    // The bridge answers the poll: it misses only the tail, items 1..=2. The ground is
    // asked for it.
    let range = MavMessage::MISSION_REQUEST_PARTIAL_LIST(
        crate::dialect::MISSION_REQUEST_PARTIAL_LIST_DATA {
            start_index: 1,
            end_index: 2,
            target_system: 255,
            target_component: 191,
            ..Default::default()
        },
    );
    r.handle_radio_bytes(ms(t), bridge.frame(&range).as_bytes());
    for seq in 1..3u16 {
        assert_eq!(asked(&mut r), vec![seq]);
        t += 10;
        r.handle_gcs_bytes(ms(t), gcs.frame(&item(seq)).as_bytes());
    }
    // paced at the radio budget: collect over a few seconds
    for step in 0..100 {
        radio.extend(
            radio_out(&mut r, ms(t + step * 50))
                .into_iter()
                .filter(mission),
        );
    }
    t += 5000;
    assert!(matches!(&radio[0], MavMessage::MISSION_COUNT(c) if c.count == 3 && c.opaque_id != 0));
    // items packed several to a frame (the frames without items are polls; the last one
    // names the plan, which the count could not)
    let seqs: Vec<u16> = radio[1..]
        .iter()
        .flat_map(|m| match m {
            MavMessage::MISSION_ITEM_INT(i) => vec![i.seq],
            MavMessage::MAVLORA_MISSION_ITEMS(p) if p.items > 0 => crate::mission::pack::unpack(p)
                .unwrap()
                .iter()
                .map(|i| i.seq)
                .collect(),
            _ => vec![],
        })
        .collect();
    assert_eq!(
        &seqs[..],
        &[0, 1, 2],
        "each item streamed once, without waiting for requests"
    );
    let named = radio.iter().rev().find_map(|m| match m {
        MavMessage::MAVLORA_MISSION_ITEMS(p) if p.items == 0 => {
            Some(crate::mission::pack::poll_plan(p))
        }
        _ => None,
    });
    assert!(
        matches!(named, Some(Some(_))),
        "the last poll names the plan"
    );
    assert_eq!(known::message_name(44), Some("MISSION_COUNT"));
    // The bridge asks for items 1..=2 again by range: the router answers, the ground never
    // sees the request.
    let now = ms(t);
    r.handle_radio_bytes(now, bridge.frame(&range).as_bytes());
    assert!(
        gcs_out(&mut r)
            .iter()
            .all(|f| f.message_id() != ids::MISSION_REQUEST_PARTIAL_LIST)
    );
    let again: Vec<u16> = radio_out(&mut r, now)
        .iter()
        .flat_map(|m| match m {
            MavMessage::MAVLORA_MISSION_ITEMS(p) if p.items > 0 => crate::mission::pack::unpack(p)
                .unwrap()
                .iter()
                .map(|i| i.seq)
                .collect(),
            _ => vec![],
        })
        .collect();
    assert_eq!(again, vec![1, 2]);
}

/// Packed mission items are the router's own, on the radio leg only: a ground station's
/// never reaches the radio (it would put items into the bridge's transfer).
#[test]
fn packed_mission_items_from_the_ground_never_reach_the_radio() {
    let mut r = router();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let items = [crate::dialect::MISSION_ITEM_INT_DATA {
        target_system: 1,
        target_component: 1,
        ..Default::default()
    }];
    let packed = crate::mission::pack::frames(7, 1, (1, 1), Default::default(), &items, 200);
    r.handle_gcs_bytes(ms(0), gcs.frame(&packed[0]).as_bytes());
    let out = radio_out(&mut r, ms(0));
    assert!(
        out.iter()
            .all(|m| !matches!(m, MavMessage::MAVLORA_MISSION_ITEMS(_))),
        "{out:?}"
    );
}

fn radio_out(r: &mut Router, now: Instant) -> Vec<MavMessage> {
    r.handle_timeout(now);
    std::iter::from_fn(|| r.poll_radio_transmit(now, usize::MAX))
        .map(|f| f.decode::<MavMessage>().unwrap())
        .collect()
}

fn commands(msgs: &[MavMessage]) -> usize {
    msgs.iter()
        .filter(|m| matches!(m, MavMessage::COMMAND_LONG(_)))
        .count()
}

#[test]
fn a_command_is_resent_over_the_radio_until_its_ack_returns() {
    use crate::dialect::{COMMAND_LONG_DATA, MavCmd, MavResult};
    let mut r = router();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let cmd = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        ..Default::default()
    });
    r.handle_gcs_bytes(ms(0), gcs.frame(&cmd).as_bytes());
    assert_eq!(commands(&radio_out(&mut r, ms(0))), 1);
    // the link's loss is not measured yet: redundant copies before any timeout, in other air
    // packets of the first two TDM rounds (SiK 64k: half a round and a round after the
    // first; at this 1 kB/s budget the 44-byte command takes longer than the 40 ms pair gap,
    // so no copy goes within the first round)
    for (quiet, due) in [(124, 125), (249, 250)] {
        assert_eq!(commands(&radio_out(&mut r, ms(quiet))), 0);
        assert_eq!(commands(&radio_out(&mut r, ms(due))), 1, "copy at {due} ms");
    }
    // all lost on the radio: resent the initial 1 s timeout after the last copy, not at the
    // ground's 1.5 s
    assert_eq!(commands(&radio_out(&mut r, ms(1249))), 0);
    assert_eq!(commands(&radio_out(&mut r, ms(1250))), 1);
    // the ground station's own retry (confirmation 1) is not sent again
    let MavMessage::COMMAND_LONG(mut retry) = cmd.clone() else {
        unreachable!()
    };
    retry.confirmation = 1;
    r.handle_gcs_bytes(
        ms(1500),
        gcs.frame(&MavMessage::COMMAND_LONG(retry)).as_bytes(),
    );
    assert_eq!(commands(&radio_out(&mut r, ms(1500))), 0);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        result: MavResult::MAV_RESULT_ACCEPTED,
        ..Default::default()
    });
    r.handle_radio_bytes(ms(1700), fc.frame(&ack).as_bytes());
    assert!(
        gcs_out(&mut r)
            .iter()
            .any(|f| f.message_id() == ids::COMMAND_ACK)
    );
    assert_eq!(commands(&radio_out(&mut r, ms(20_000))), 0);
    let s = r.stats().commands;
    assert_eq!(
        (
            s.commands,
            s.early_copies,
            s.retransmissions,
            s.ground_duplicates,
            s.acked
        ),
        (1, 2, 1, 1, 1)
    );
}

/// The ground's 1 Hz heartbeats go over the radio each second on a budget where 2.5 % carries
/// them (SiK: the autopilot hears of a link loss at most 3 s late), one per 5 s on LoRa SF7's
/// 251 B/s, in between on the default 683 B/s.
#[test]
fn ground_heartbeats_go_as_often_as_the_budget_allows() {
    for (rate, every) in [(4000, 1), (683, 2), (251, 5)] {
        let mut r = Router::new(
            RouterConfig::new(SchedulerConfig {
                rate_bytes_per_s: rate,
                burst_bytes: 600,
                max_queued_bytes: 8000,
            }),
            Instant::ZERO,
        )
        .unwrap();
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype: MavType::MAV_TYPE_GCS,
            ..Default::default()
        });
        let mut sent = 0;
        for k in 0..60 {
            let now = ms(1000 * k + 10);
            r.handle_gcs_bytes(now, gcs.frame(&hb).as_bytes());
            sent += radio_out(&mut r, now)
                .iter()
                .filter(
                    |m| matches!(m, MavMessage::HEARTBEAT(h) if h.mavtype == MavType::MAV_TYPE_GCS),
                )
                .count();
        }
        assert_eq!(sent, 60 / every, "{rate} B/s");
    }
}

/// 60,000 source addresses each sending one frame: every one is counted, the first 1024 are
/// reported (logged) and remembered, the rest neither (they took 9.3 MB and 7.9 MB of log).
#[test]
fn a_sweep_of_source_addresses_is_counted_without_remembering_or_logging_each() {
    let mut r = router();
    let mut spoof = Sender::new(255, 190, MavlinkVersion::V2);
    let hb = spoof.frame(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
    let mut reported = 0;
    for k in 0..60_000u32 {
        let from = std::net::SocketAddr::from((std::net::Ipv4Addr::from(0x0a00_0000 + k), 14550));
        let input = r.handle_gcs_input(ms(u64::from(k) / 100), from, hb.as_bytes());
        reported += usize::from(input.report.is_some());
    }
    assert_eq!(r.stats().ground.rejected_address, 60_000);
    assert_eq!(reported, super::engine::REPORTED_SOURCES);
}

#[test]
fn ground_frames_from_other_addresses_or_system_ids_never_reach_the_radio() {
    let mut r = router();
    let arm = crate::testutil::arm_command();
    let intruder: std::net::SocketAddr = "192.168.1.66:14550".parse().unwrap();
    let mut spoof = Sender::new(255, 190, MavlinkVersion::V2);
    let input = r.handle_gcs_input(ms(0), intruder, spoof.frame(&arm).as_bytes());
    assert!(!input.learn_peer());
    assert_eq!(input.report, Some(GroundRejection::Address));
    // the vehicle's own id from loopback: not a ground station
    let mut fake_vehicle = Sender::new(1, 1, MavlinkVersion::V2);
    let input = r.handle_gcs_bytes(ms(10), fake_vehicle.frame(&arm).as_bytes());
    assert!(!input.learn_peer());
    assert_eq!(input.report, Some(GroundRejection::SystemId(1)));
    // a corrupted frame from the allowed station teaches nothing either
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut bad = gcs.frame(&arm).as_bytes().to_vec();
    let last = bad.len() - 1;
    bad[last] ^= 0xff;
    assert!(!r.handle_gcs_bytes(ms(20), &bad).learn_peer());
    assert_eq!(commands(&radio_out(&mut r, ms(30))), 0);
    // reports are rate-limited per source and reason, counts are not
    let again = r.handle_gcs_input(ms(40), intruder, spoof.frame(&arm).as_bytes());
    assert_eq!(again.report, None);
    let s = r.stats().ground;
    assert_eq!((s.rejected_address, s.rejected_sysid, s.total()), (2, 1, 3));
    // the pilot's own command goes
    assert!(
        r.handle_gcs_bytes(ms(50), gcs.frame(&arm).as_bytes())
            .learn_peer()
    );
    assert_eq!(commands(&radio_out(&mut r, ms(50))), 1);
}

/// Issue 22 item 11: a station the router lets in by address but refuses a frame of (a
/// system id not allowed) is told why, once per report period, in a `STATUSTEXT` for it
/// alone; a stranger (an address not allowed) is told nothing.
#[test]
fn a_refused_station_is_told_why_and_a_stranger_is_not() {
    let mut r = router();
    let arm = crate::testutil::arm_command();
    let mut station = Sender::new(42, 190, MavlinkVersion::V2);
    let input = r.handle_gcs_bytes(ms(0), station.frame(&arm).as_bytes());
    assert_eq!(input.report, Some(GroundRejection::SystemId(42)));
    let reply = input.reply.expect("the refused station was not told");
    assert_eq!(
        (reply.system_id(), reply.message_id()),
        (
            RouterConfig::new(SchedulerConfig::for_radio(1000, 300)).system_id,
            crate::wire::ids::STATUSTEXT
        )
    );
    let Ok(MavMessage::STATUSTEXT(text)) = reply.decode::<MavMessage>() else {
        panic!("not a STATUSTEXT: {reply:?}");
    };
    let text = String::from_utf8_lossy(&text.text.to_vec())
        .trim_end_matches('\0')
        .to_string();
    assert_eq!(text, "MavLora router refused: system id 42 not allowed");
    assert!(
        r.handle_gcs_bytes(ms(100), station.frame(&arm).as_bytes())
            .reply
            .is_none(),
        "told again within the report period"
    );
    let stranger: std::net::SocketAddr = "192.168.1.66:14550".parse().unwrap();
    let mut spoof = Sender::new(255, 190, MavlinkVersion::V2);
    let input = r.handle_gcs_input(ms(200), stranger, spoof.frame(&arm).as_bytes());
    assert_eq!(input.report, Some(GroundRejection::Address));
    assert!(input.reply.is_none(), "a stranger was answered");
    // Nothing of the refused station's went to the radio, and its reply not to the peers.
    assert_eq!(commands(&radio_out(&mut r, ms(300))), 0);
    assert!(
        r.poll_gcs_transmit()
            .is_none_or(|f| f.message_id() != crate::wire::ids::STATUSTEXT)
    );
}

#[test]
fn one_source_cannot_fill_the_command_relay() {
    use crate::dialect::{COMMAND_LONG_DATA, MavCmd};
    let mut r = router();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    // Another application on the same host: same address, its own port.
    let other: std::net::SocketAddr = "127.0.0.1:14551".parse().unwrap();
    // distinct commands (to ten vehicles) from one source: only the budget goes out
    let budget = GroundPolicy::default().commands_in_flight;
    for k in 0..10u8 {
        let msg = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: k + 1,
            target_component: 1,
            command: MavCmd::MAV_CMD_DO_SET_SERVO,
            ..Default::default()
        });
        r.handle_gcs_bytes(ms(0), gcs.frame(&msg).as_bytes());
    }
    assert_eq!(commands(&radio_out(&mut r, ms(0))), budget);
    // another station's command still goes (the pilot's, when a script used up its own)
    let mut other_gcs = Sender::new(255, 191, MavlinkVersion::V2);
    let input = r.handle_gcs_input(
        ms(10),
        other,
        other_gcs
            .frame(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                target_system: 1,
                command: MavCmd::MAV_CMD_NAV_LAND,
                ..Default::default()
            }))
            .as_bytes(),
    );
    assert!(input.learn_peer());
    assert_eq!(commands(&radio_out(&mut r, ms(10))), 1);
    assert_eq!(r.stats().ground.rejected_budget, 10 - budget as u64);
}

/// A router whose ground stations must sign with `key`.
fn router_with_ground_key(
    key: &crate::signing::SigningKey,
    link_id: u8,
    epoch: u64,
    state: crate::signing::SigningState,
) -> Router {
    let mut config = RouterConfig::new(SchedulerConfig {
        rate_bytes_per_s: 1000,
        burst_bytes: 300,
        max_queued_bytes: 4000,
    });
    config.ground_signing = Some(crate::signing::SigningConfig {
        key: key.clone(),
        link_id,
        epoch,
        state,
    });
    Router::new(config, Instant::ZERO).unwrap()
}

#[test]
fn with_a_ground_key_only_signed_ground_frames_reach_the_radio_and_the_ground_gets_signed_ones() {
    use crate::signing::{LinkSigner, SigningKey};
    let key = SigningKey([7; 32]);
    let mut r = router_with_ground_key(&key, 2, 1_000_000, Default::default());
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut station = LinkSigner::new(key, 9, 1_000_000);
    let arm = crate::testutil::arm_command();
    // unsigned, from an allowed address and system id: not enough
    let input = r.handle_gcs_bytes(ms(0), gcs.frame(&arm).as_bytes());
    assert!(!input.learn_peer());
    assert_eq!(input.report, Some(GroundRejection::Signature));
    // signed with another key: no
    let mut stranger = LinkSigner::new(SigningKey([8; 32]), 9, 1_000_000);
    let forged = stranger.sign(&gcs.frame(&arm), ms(5)).unwrap();
    assert!(!r.handle_gcs_bytes(ms(5), forged.as_bytes()).learn_peer());
    assert_eq!(commands(&radio_out(&mut r, ms(10))), 0);
    // signed with the ground key: goes, without the ground's signature
    let signed = station.sign(&gcs.frame(&arm), ms(20)).unwrap();
    assert!(r.handle_gcs_bytes(ms(20), signed.as_bytes()).learn_peer());
    let out: Vec<OwnedFrame> = std::iter::from_fn(|| r.poll_radio_transmit(ms(20), usize::MAX))
        .filter(|f| f.message_id() == ids::COMMAND_LONG)
        .collect();
    assert_eq!(out.len(), 1);
    assert!(!out[0].is_signed());
    // ... and a replay of it does not
    assert!(!r.handle_gcs_bytes(ms(30), signed.as_bytes()).learn_peer());
    assert_eq!(r.stats().ground.rejected_signature, 3);
    // what the ground gets is signed with the ground key
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
    r.handle_radio_bytes(ms(40), fc.frame(&hb).as_bytes());
    let to_ground = gcs_out(&mut r);
    assert!(!to_ground.is_empty());
    for f in &to_ground {
        assert!(f.is_signed());
        station
            .verify(f, ms(41))
            .expect("signed with the ground key");
    }
}

/// The ground signer's state, stored and given to the next router, keeps a ground station's
/// captured ARM a replay across the restart (the binary stores it in the ground key's state
/// file); the station's next frame still goes.
#[test]
fn the_ground_signers_stored_state_refuses_after_a_restart_what_it_accepted_before() {
    use crate::signing::{LinkSigner, SigningKey, SigningState};
    let key = SigningKey([7; 32]);
    let start = |epoch: u64, state: SigningState| router_with_ground_key(&key, 3, epoch, state);
    let mut station = LinkSigner::new(key.clone(), 5, 1_000_000);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let arm = crate::testutil::arm_command();
    let captured = station.sign(&gcs.frame(&arm), ms(10)).unwrap();
    let mut before = start(1_000_000, SigningState::default());
    assert!(
        before
            .handle_gcs_bytes(ms(10), captured.as_bytes())
            .learn_peer()
    );
    assert_eq!(commands(&radio_out(&mut before, ms(10))), 1);
    let stored = before
        .ground_signing_state(ms(500))
        .expect("ground signing on");
    assert!(stored.streams.contains_key(&(5, 255, 190)), "{stored:?}");
    // restarted two seconds later: engine time from zero again, the clock moved on
    let mut after = start(1_000_000 + 200_000, stored);
    let input = after.handle_gcs_bytes(ms(0), captured.as_bytes());
    assert_eq!(input.report, Some(GroundRejection::Signature));
    assert_eq!(commands(&radio_out(&mut after, ms(0))), 0);
    assert_eq!(after.stats().ground_signing.replayed, 1);
    let next = station.sign(&gcs.frame(&arm), ms(2100)).unwrap();
    assert!(after.handle_gcs_bytes(ms(10), next.as_bytes()).learn_peer());
    assert_eq!(router().ground_signing_state(ms(0)), None);
}

#[test]
fn a_restarted_bridge_is_not_read_as_loss_even_when_its_first_frame_is_lost() {
    use crate::dialect::LINK_QUALITY_DATA;
    let report = |uptime_ms: u32| {
        MavMessage::LINK_QUALITY(LINK_QUALITY_DATA {
            time_boot_ms: uptime_ms,
            rssi: i8::MAX,
            remote_rssi: i8::MAX,
            ..Default::default()
        })
    };
    let pos = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA::default());
    let mut r = router();
    // The first bridge: 40 frames of telemetry and a report.
    let (mut fc, mut bridge) = (
        Sender::new(1, 1, MavlinkVersion::V2),
        Sender::new(1, 191, MavlinkVersion::V2),
    );
    for k in 0..40 {
        r.handle_radio_bytes(ms(100 * k), fc.frame(&pos).as_bytes());
    }
    r.handle_radio_bytes(ms(4000), bridge.frame(&report(60_000)).as_bytes());
    // Killed; a new one numbers from 0 again. Its report (sent first) arrives; its first
    // telemetry frame is lost with the old one's torn last frame: seq 1 comes first.
    let (mut fc, mut bridge) = (
        Sender::new(1, 1, MavlinkVersion::V2),
        Sender::new(1, 191, MavlinkVersion::V2),
    );
    bridge.set_next_sequence(0);
    r.handle_radio_bytes(ms(8000), bridge.frame(&report(30)).as_bytes());
    fc.set_next_sequence(1);
    for k in 0..10 {
        r.handle_radio_bytes(ms(8100 + 100 * k), fc.frame(&pos).as_bytes());
    }
    let stats = r.quality().reader_stats();
    // both streams started again: the report's at 0, the telemetry's told by the report
    assert_eq!((stats.lost, stats.restarts), (0, 2), "{stats:?}");
    r.handle_timeout(ms(9100));
    assert_ne!(
        r.monitor().health(crate::quality::Direction::Downlink),
        Some(crate::quality::Health::Degraded)
    );
}

/// Regression: the router's own LINK_QUALITY reached the ground stations as system 0 (its
/// unconfigured id), a vehicle no ground station shows. Its ground copy speaks for the
/// vehicle's radio (component 68), as the link announcements do, and none goes out before
/// the vehicle is known.
#[test]
fn link_quality_reaches_the_ground_as_the_vehicle_s_radio_never_as_system_0() {
    let link_quality_to_ground = |frames: &[OwnedFrame]| -> Vec<(u8, u8)> {
        frames
            .iter()
            .filter(|f| f.message_id() == ids::LINK_QUALITY)
            .map(|f| (f.system_id(), f.component_id()))
            .collect()
    };
    let mut r = router();
    for k in 1..=30 {
        r.handle_timeout(ms(1000 * k));
    }
    assert!(r.stats().link_quality_sent > 0, "reports went to the radio");
    assert_eq!(
        link_quality_to_ground(&gcs_out(&mut r)),
        [],
        "no vehicle yet"
    );
    let mut fc = Sender::new(7, 1, MavlinkVersion::V2);
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
    let mut ground = Vec::new();
    for k in 31..=60 {
        r.handle_radio_bytes(ms(1000 * k), fc.frame(&hb).as_bytes());
        r.handle_timeout(ms(1000 * k + 1));
        ground.extend(gcs_out(&mut r));
    }
    let seen = link_quality_to_ground(&ground);
    assert!(!seen.is_empty(), "the ground gets the router's reports");
    assert!(seen.iter().all(|&ids| ids == (7, 68)), "{seen:?}");
}

/// Packed parameter values are a new parser of radio bytes: a malformed frame (a bridge of
/// another version) gives the ground nothing and is counted; a good one gives each value as
/// the standard `PARAM_VALUE` of the component it names, numbered on in that stream with what
/// the component sends itself.
#[test]
fn packed_parameters_expand_as_the_autopilot_and_malformed_ones_are_refused() {
    use crate::dialect::{MAVLORA_PARAM_VALUES_DATA, PARAM_VALUE_DATA};
    use crate::param::{ParamValue, pack};
    use mavlink::MessageData;
    let value = |text: &[u8], index: u16| {
        let mut name = [0u8; 16];
        name[..text.len()].copy_from_slice(text);
        ParamValue {
            value: [0, 0, 0x80, 0x3F],
            count: 900,
            index,
            name,
            param_type: 9,
        }
    };
    let values = [value(b"BAT1_N_CELLS", 3), value(b"BAT1_R_INTERNAL", 4)];
    let (n, data) = pack::pack(&values, pack::MAX_DATA);
    assert_eq!(n, 2);
    let good = pack::frame(1, &values, &data);
    let mut bridge = Sender::new(1, 191, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let mut r = router();
    let mut bad_frames = Vec::new();
    for bad in [
        MAVLORA_PARAM_VALUES_DATA {
            values: 0,
            ..good.clone()
        },
        MAVLORA_PARAM_VALUES_DATA {
            values: 3,
            ..good.clone()
        },
        MAVLORA_PARAM_VALUES_DATA {
            data: [0xFF; pack::MAX_DATA],
            ..good.clone()
        },
    ] {
        bad_frames.extend_from_slice(
            bridge
                .frame(&MavMessage::MAVLORA_PARAM_VALUES(bad))
                .as_bytes(),
        );
    }
    r.handle_radio_bytes(ms(0), &bad_frames);
    assert!(
        gcs_out(&mut r)
            .iter()
            .all(|f| f.message_id() != ids::PARAM_VALUE)
    );
    assert_eq!(r.stats().param_frames_undecodable, 3);

    let mut radio = bridge
        .frame(&MavMessage::MAVLORA_PARAM_VALUES(good))
        .as_bytes()
        .to_vec();
    // the autopilot's own answer to a read, raw, after them
    fc.set_next_sequence(200);
    radio.extend_from_slice(
        fc.frame(&MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_id: (*b"BAT1_CAPACITY\0\0\0").into(),
            param_count: 900,
            param_index: 2,
            param_value: 5000.0,
            param_type: crate::dialect::MavParamType::MAV_PARAM_TYPE_REAL32,
        }))
        .as_bytes(),
    );
    r.handle_radio_bytes(ms(10), &radio);
    let out: Vec<_> = gcs_out(&mut r)
        .into_iter()
        .filter(|f| f.message_id() == ids::PARAM_VALUE)
        .collect();
    assert_eq!(out.len(), 3);
    for (f, v) in out.iter().zip(&values) {
        assert_eq!((f.system_id(), f.component_id()), (1, 1));
        assert_eq!(ParamValue::from_payload(f.payload()), Some(*v));
        assert!(f.crc_matches(PARAM_VALUE_DATA::EXTRA_CRC));
    }
    let seqs: Vec<u8> = out.iter().map(|f| f.sequence()).collect();
    assert_eq!(seqs, vec![0, 1, 2], "one stream, gap-free");
    assert!(out[2].crc_matches(PARAM_VALUE_DATA::EXTRA_CRC));
    let s = r.stats();
    assert_eq!((s.param_frames_expanded, s.param_values_expanded), (1, 2));
}

/// A ground station that reads values one by one once its list went quiet for 1 s takes a slow
/// radio's pause between two packed frames for the list's end: its reads of what the list in
/// flight brings wait at the router, a read of a value the list lost goes to the radio.
/// A ground station's read of parameter `index` of vehicle 1.
fn param_read(g: &mut Sender, index: i16) -> OwnedFrame {
    g.frame(&MavMessage::PARAM_REQUEST_READ(
        crate::dialect::PARAM_REQUEST_READ_DATA {
            target_system: 1,
            target_component: 1,
            param_index: index,
            ..Default::default()
        },
    ))
}

#[test]
fn reads_of_what_the_list_in_flight_brings_wait_and_lost_values_are_read() {
    use crate::param::{ParamValue, pack};
    let value = |index: u16| ParamValue {
        value: [0; 4],
        count: 900,
        index,
        name: *b"SOME_PARAMETER\0\0",
        param_type: 9,
    };
    let values: Vec<ParamValue> = [0, 1, 2, 5, 6].into_iter().map(value).collect();
    let (n, data) = pack::pack(&values, pack::MAX_DATA);
    assert_eq!(n, 5);
    let mut bridge = Sender::new(1, 191, MavlinkVersion::V2);
    let mut r = router();
    let f = bridge.frame(&MavMessage::MAVLORA_PARAM_VALUES(pack::frame(
        1, &values, &data,
    )));
    r.handle_radio_bytes(ms(0), f.as_bytes());
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    let read = param_read;
    for index in [3, 7, 8, 3] {
        r.handle_gcs_bytes(ms(1200), read(&mut ground, index).as_bytes());
    }
    let radio: Vec<u32> = std::iter::from_fn(|| r.poll_radio_transmit(ms(1200), usize::MAX))
        .map(|f| f.message_id())
        .collect();
    assert_eq!(
        radio
            .iter()
            .filter(|&&id| id == ids::PARAM_REQUEST_READ)
            .count(),
        1,
        "only the lost value's read, once: {radio:?}"
    );
    let s = r.stats().param_reads;
    assert_eq!((s.forwarded, s.held_ahead, s.held_repeat), (1, 2, 1));
}

/// Regression (issue 22, item 12): another allowed ground station sending 100
/// PARAM_REQUEST_READ a second made 0 of 8 pilot commands run: the reads and the commands
/// queued for the radio in one line. The pilot's commands now leave within one frame's air
/// time, and the pilot's own reads take turns with the flood.
#[test]
fn a_flooding_ground_station_delays_neither_the_pilots_commands_nor_its_reads() {
    use crate::dialect::{COMMAND_LONG_DATA, MavCmd, MavResult};
    let mut r = Router::new(
        RouterConfig::new(SchedulerConfig::for_radio(300, 300)),
        Instant::ZERO,
    )
    .unwrap();
    let read = param_read;
    let (mut pilot, mut fc) = (
        Sender::new(255, 190, MavlinkVersion::V2),
        Sender::new(1, 1, MavlinkVersion::V2),
    );
    // MAVProxy on the same machine (the same address, its own component id)
    let mut flooder = Sender::new(255, 230, MavlinkVersion::V2);
    let (mut sent_at, mut delays, mut pilot_reads) = (Vec::new(), Vec::new(), 0);
    for t in (0..8_000u64).step_by(10) {
        let now = ms(t);
        r.handle_gcs_bytes(now, read(&mut flooder, (t / 10) as i16 + 100).as_bytes());
        if t % 1_000 == 0 {
            let k = (t / 1_000) as u8;
            // distinct commands: none waits for the one before's ack to be told apart
            let command = [
                MavCmd::MAV_CMD_DO_SET_SERVO,
                MavCmd::MAV_CMD_DO_SET_RELAY,
                MavCmd::MAV_CMD_DO_REPEAT_SERVO,
                MavCmd::MAV_CMD_DO_REPEAT_RELAY,
                MavCmd::MAV_CMD_DO_CHANGE_SPEED,
                MavCmd::MAV_CMD_DO_SET_HOME,
                MavCmd::MAV_CMD_DO_DIGICAM_CONTROL,
                MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
            ][usize::from(k)];
            let cmd = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                target_system: 1,
                target_component: 1,
                command,
                param1: f32::from(k),
                ..Default::default()
            });
            r.handle_gcs_bytes(now, pilot.frame(&cmd).as_bytes());
            r.handle_gcs_bytes(now, read(&mut pilot, i16::from(k)).as_bytes());
            sent_at.push(t);
        }
        for msg in radio_out(&mut r, now) {
            match msg {
                MavMessage::COMMAND_LONG(c) => {
                    // the first copy on the air (the relay adds redundant ones)
                    let k = c.param1 as usize;
                    if delays.len() == k {
                        delays.push(t - sent_at[k]);
                    }
                    let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                        command: c.command,
                        result: MavResult::MAV_RESULT_ACCEPTED,
                        ..Default::default()
                    });
                    r.handle_radio_bytes(now, fc.frame(&ack).as_bytes());
                }
                MavMessage::PARAM_REQUEST_READ(p) if p.param_index < 100 => pilot_reads += 1,
                _ => {}
            }
        }
    }
    // a command's 45 bytes take 150 ms at 300 B/s; one frame already on the air before it
    assert_eq!(delays.len(), 8, "commands on the radio: {delays:?}");
    assert!(
        delays.iter().all(|&d| d <= 300),
        "command delays {delays:?} ms"
    );
    assert_eq!(pilot_reads, 8, "the pilot's reads");
    let s = r.stats().scheduler;
    assert!(s.dropped_protocol > 0 && s.dropped_command == 0, "{s:?}");
}
