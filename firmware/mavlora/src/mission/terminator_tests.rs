#![allow(clippy::needless_update)] // full literals keep `..Default::default()`: the dialect may grow
use super::*;
use crate::dialect::{MISSION_ACK_DATA, MavMissionResult, MavMissionType};

const GROUND: (u8, u8) = (255, 190);
const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;
const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

fn count(n: u16, t: MavMissionType) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: n,
        target_system: 1,
        target_component: 1,
        mission_type: t,
        ..Default::default()
    })
}

fn item(seq: u16, x: i32, t: MavMissionType) -> MavMessage {
    MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
        seq,
        x,
        target_system: 1,
        target_component: 1,
        mission_type: t,
        ..Default::default()
    })
}

fn ground_out(m: &mut MissionTerminator) -> Vec<MavMessage> {
    std::iter::from_fn(|| m.poll_ground())
        .map(|(from, msg)| {
            assert_eq!(
                from,
                (1, 1),
                "answers come from the vehicle the ground addressed"
            );
            msg
        })
        .collect()
}

fn radio_out(m: &mut MissionTerminator, now: Instant) -> Vec<MavMessage> {
    // Each frame leaves the radio queue as soon as it is handed over.
    let mut out = Vec::new();
    while let Some(msg) = m.poll_radio(now) {
        if matches!(
            msg,
            MavMessage::MISSION_COUNT(_) | MavMessage::MISSION_ITEM_INT(_)
        ) {
            m.radio_frame_left(now);
        }
        out.push(msg);
    }
    out
}

/// Uploads `xs` (item i has x = xs[i]) from the ground at `t`; returns the radio stream.
fn upload(m: &mut MissionTerminator, t: u64, xs: &[i32], ty: MavMissionType) -> Vec<MavMessage> {
    m.from_ground(ms(t), GROUND, 1, &count(xs.len() as u16, ty));
    for (seq, x) in xs.iter().enumerate() {
        m.from_ground(ms(t), GROUND, 1, &item(seq as u16, *x, ty));
    }
    radio_out(m, ms(t))
}

fn items_of(msgs: &[MavMessage]) -> Vec<(u16, i32)> {
    msgs.iter()
        .filter_map(|m| match m {
            MavMessage::MISSION_ITEM_INT(i) => Some((i.seq, i.x)),
            _ => None,
        })
        .collect()
}

fn id_of(msgs: &[MavMessage]) -> u32 {
    msgs.iter()
        .find_map(|m| match m {
            MavMessage::MISSION_COUNT(c) => Some(c.opaque_id),
            _ => None,
        })
        .expect("a MISSION_COUNT")
}

fn bridge_ack(id: u32, result: MavMissionResult, t: MavMissionType) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: 255,
        target_component: 191,
        mavtype: result,
        mission_type: t,
        opaque_id: id,
        ..Default::default()
    })
}

fn acks(msgs: &[MavMessage]) -> Vec<MavMissionResult> {
    msgs.iter()
        .filter_map(|m| match m {
            MavMessage::MISSION_ACK(a) => Some(a.mavtype),
            _ => None,
        })
        .collect()
}

/// Issue 9, 3.1: a second MISSION_COUNT with the same count kept item 0 of the old plan.
#[test]
fn same_count_again_mid_upload_restarts_from_item_zero() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    m.from_ground(ms(0), GROUND, 1, &count(2, MISSION));
    m.from_ground(ms(1), GROUND, 1, &item(0, 100, MISSION));
    // the ground starts over with another plan of the same length
    m.from_ground(ms(2), GROUND, 1, &count(2, MISSION));
    m.from_ground(ms(3), GROUND, 1, &item(0, 200, MISSION));
    m.from_ground(ms(4), GROUND, 1, &item(1, 201, MISSION));
    let radio = radio_out(&mut m, ms(4));
    assert_eq!(items_of(&radio), vec![(0, 200), (1, 201)]);
    assert_eq!(m.stats().restarts, 1);
}

/// Issue 9, 3.3: the ground's 0.5 s timeouts must never meet the radio, and it must never be
/// told ACCEPTED before the vehicle said so.
#[test]
fn ground_is_kept_waiting_with_requests_for_its_last_item_never_a_made_up_accept() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    upload(&mut m, 0, &[1, 2, 3], MISSION);
    ground_out(&mut m);
    let mut t = 0;
    let mut keepalives = 0;
    while t < 20_000 {
        t = m.poll_timeout().unwrap().as_millis();
        m.handle_timeout(ms(t));
        radio_out(&mut m, ms(t));
        for msg in ground_out(&mut m) {
            match msg {
                MavMessage::MISSION_REQUEST_INT(r) => {
                    assert_eq!(r.seq, 2);
                    keepalives += 1;
                }
                other => panic!("the ground got {other:?} while the vehicle is silent"),
            }
        }
    }
    // at least one request per 0.5 s (a 0.5 s ground station's timer never fires)
    assert!(keepalives >= 40, "{keepalives}");
    assert!(m.stats().polls > 0, "the bridge is polled");
}

#[test]
fn accepted_only_for_the_ack_naming_the_current_plan() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    let first = id_of(&upload(&mut m, 0, &[1, 2], MISSION));
    let second = id_of(&upload(&mut m, 10, &[3, 4], MISSION));
    assert_ne!(first, second);
    ground_out(&mut m);
    // the vehicle's ack for the first plan arrives late: not the ground's answer
    assert!(m.from_radio(
        ms(20),
        &bridge_ack(first, MavMissionResult::MAV_MISSION_ACCEPTED, MISSION)
    ));
    assert!(acks(&ground_out(&mut m)).is_empty());
    assert_eq!(m.stats().stale_acks, 1);
    assert!(m.from_radio(
        ms(30),
        &bridge_ack(second, MavMissionResult::MAV_MISSION_ACCEPTED, MISSION)
    ));
    assert_eq!(
        acks(&ground_out(&mut m)),
        vec![MavMissionResult::MAV_MISSION_ACCEPTED]
    );
    // a lost ack: the ground repeats its last item and hears it again
    m.from_ground(ms(40), GROUND, 1, &item(1, 4, MISSION));
    assert_eq!(
        acks(&ground_out(&mut m)),
        vec![MavMissionResult::MAV_MISSION_ACCEPTED]
    );
}

#[test]
fn vehicle_error_reaches_the_ground_as_an_error() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    let id = id_of(&upload(&mut m, 0, &[1], MISSION));
    m.from_radio(
        ms(5),
        &bridge_ack(id, MavMissionResult::MAV_MISSION_NO_SPACE, MISSION),
    );
    assert_eq!(
        acks(&ground_out(&mut m)),
        vec![MavMissionResult::MAV_MISSION_NO_SPACE]
    );
}

/// Issue 9, 3.4: the relay kept going after the ground cancelled.
#[test]
fn ground_cancel_stops_the_transfer_and_tells_the_bridge() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    let id = id_of(&upload(&mut m, 0, &[1, 2], MISSION));
    let cancel = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: 1,
        target_component: 1,
        mavtype: MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
        ..Default::default()
    });
    assert!(m.from_ground(ms(5), GROUND, 1, &cancel));
    let radio = radio_out(&mut m, ms(5));
    assert!(matches!(&radio[..], [MavMessage::MISSION_ACK(a)]
        if a.opaque_id == id && a.mavtype == MavMissionResult::MAV_MISSION_OPERATION_CANCELLED));
    assert_eq!(
        m.poll_timeout(),
        None,
        "no keep-alive, no poll after a cancel"
    );
    // a late ACCEPTED for it is not passed on
    m.from_radio(
        ms(9),
        &bridge_ack(id, MavMissionResult::MAV_MISSION_ACCEPTED, MISSION),
    );
    assert!(
        ground_out(&mut m)
            .iter()
            .all(|msg| !matches!(msg, MavMessage::MISSION_ACK(_)))
    );
    // a download's final ACCEPTED from the ground is not a cancel: it passes through
    let done = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: 1,
        mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
        ..Default::default()
    });
    assert!(!m.from_ground(ms(10), GROUND, 1, &done));
}

#[test]
fn stream_goes_out_through_a_window_and_a_restart_drops_what_never_left() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    m.from_ground(ms(0), GROUND, 1, &count(10, MISSION));
    for seq in 0..10 {
        m.from_ground(ms(0), GROUND, 1, &item(seq, 1, MISSION));
    }
    let first: Vec<_> = std::iter::from_fn(|| m.poll_radio(ms(0))).collect();
    assert_eq!(first.len(), 4, "count + 3 items, then the window is full");
    m.radio_frame_left(ms(1));
    assert!(m.poll_radio(ms(1)).is_some(), "one left, one more goes");
    // a new plan: the old one's items still waiting never reach the radio
    m.from_ground(ms(2), GROUND, 1, &count(1, MISSION));
    m.from_ground(ms(2), GROUND, 1, &item(0, 77, MISSION));
    (0..4).for_each(|_| m.radio_frame_left(ms(3)));
    let rest = radio_out(&mut m, ms(3));
    assert!(
        matches!(&rest[0], MavMessage::MISSION_ACK(_)),
        "the bridge hears the cancel first"
    );
    assert_eq!(items_of(&rest), vec![(0, 77)]);
}

#[test]
fn stream_is_paced_at_the_radio_budget() {
    let config = TerminatorConfig {
        pace_bytes_per_s: Some(620),
        ..TerminatorConfig::default()
    };
    let mut m = MissionTerminator::new(config);
    m.from_ground(ms(0), GROUND, 1, &count(3, MISSION));
    for seq in 0..3 {
        m.from_ground(ms(0), GROUND, 1, &item(seq, 1, MISSION));
    }
    assert!(m.poll_radio(ms(0)).is_some());
    assert!(
        m.poll_radio(ms(0)).is_none(),
        "62 bytes at 620 B/s: 100 ms apart"
    );
    assert_eq!(m.poll_timeout(), Some(ms(100)));
    assert!(m.poll_radio(ms(100)).is_some());
}

#[test]
fn fence_upload_carries_its_type_on_every_message() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    m.from_ground(ms(0), GROUND, 1, &count(2, FENCE));
    for msg in ground_out(&mut m) {
        assert!(matches!(msg, MavMessage::MISSION_REQUEST_INT(r) if r.mission_type == FENCE));
    }
    // an item of another type is not part of this upload
    m.from_ground(ms(1), GROUND, 1, &item(0, 9, MISSION));
    m.from_ground(ms(1), GROUND, 1, &item(0, 1, FENCE));
    m.from_ground(ms(2), GROUND, 1, &item(1, 2, FENCE));
    let radio = radio_out(&mut m, ms(2));
    assert_eq!(items_of(&radio), vec![(0, 1), (1, 2)]);
    for msg in &radio {
        match msg {
            MavMessage::MISSION_COUNT(c) => assert_eq!(c.mission_type, FENCE),
            MavMessage::MISSION_ITEM_INT(i) => assert_eq!(i.mission_type, FENCE),
            other => panic!("{other:?}"),
        }
    }
    // the bridge's repair request is answered with the fence item
    m.from_radio(ms(3), &super::request((255, 191), 1, FENCE));
    assert_eq!(items_of(&radio_out(&mut m, ms(3))), vec![(1, 2)]);
}

#[test]
fn silent_vehicle_side_ends_in_an_error_for_the_ground() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    upload(&mut m, 0, &[1], MISSION);
    let mut t = 0;
    let mut result = None;
    while result.is_none() && t < 120_000 {
        t = m.poll_timeout().unwrap().as_millis();
        m.handle_timeout(ms(t));
        radio_out(&mut m, ms(t));
        result = acks(&ground_out(&mut m)).first().copied();
    }
    assert_eq!(result, Some(MavMissionResult::MAV_MISSION_ERROR));
    assert!((60_000..70_000).contains(&t), "{t}");
}
