#![allow(clippy::needless_update)] // full literals keep `..Default::default()`: the dialect may grow
use super::*;
use crate::dialect::{MISSION_ACK_DATA, MavMissionResult, MavMissionType};
use crate::mission::MARGIN;

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
            MavMessage::MISSION_COUNT(_)
                | MavMessage::MISSION_ITEM_INT(_)
                | MavMessage::MAVLORA_MISSION_ITEMS(_)
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

/// The items a stream carries, one per `MISSION_ITEM_INT` or packed.
fn items_of(msgs: &[MavMessage]) -> Vec<(u16, i32)> {
    msgs.iter()
        .flat_map(|m| match m {
            MavMessage::MISSION_ITEM_INT(i) => vec![(i.seq, i.x)],
            MavMessage::MAVLORA_MISSION_ITEMS(p) if p.items > 0 => pack::unpack(p)
                .unwrap()
                .iter()
                .map(|i| (i.seq, i.x))
                .collect(),
            _ => vec![],
        })
        .collect()
}

/// Polls in a stream: packed frames without items.
fn polls_of(msgs: &[MavMessage]) -> usize {
    msgs.iter()
        .filter(|m| matches!(m, MavMessage::MAVLORA_MISSION_ITEMS(p) if p.items == 0))
        .count()
}

/// The terminator with one `MISSION_ITEM_INT` per item (no packing).
fn unpacked() -> TerminatorConfig {
    TerminatorConfig {
        pack_bytes: None,
        ..TerminatorConfig::default()
    }
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

/// Regression: a second MISSION_COUNT with the same count kept item 0 of the old plan.
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

/// Regression (MAVSDK uploads failed): with the plan in, the router re-requested the last
/// item every 250 ms while the vehicle side worked, and MAVSDK counts each repeated request
/// against its retries (5) and resends nothing while it waits, so it gave up after about a
/// second, without a cancel, while the vehicle went on to take the plan. A ground that never
/// resends is never asked twice; it is never told ACCEPTED before the vehicle said so.
#[test]
fn a_ground_that_waits_silently_is_never_asked_for_an_item_twice() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    upload(&mut m, 0, &[1, 2, 3], MISSION);
    ground_out(&mut m);
    let mut t = 0;
    while t < 20_000 {
        t = m.poll_timeout().unwrap().as_millis();
        m.handle_timeout(ms(t));
        radio_out(&mut m, ms(t));
        let out = ground_out(&mut m);
        assert!(out.is_empty(), "the ground got {out:?} at {t} ms");
    }
    assert!(m.stats().polls > 0, "the bridge is polled");
    assert_eq!(m.stats().keepalives, 0);
}

/// A ground that resends its last item when its timer fires (0.5 s here, 3 retries: many
/// SDKs) shows its period with its first retry; from then on it is asked for that item at
/// 4/5 of it, so its timer never fires again while the radio leg works.
#[test]
fn a_ground_that_resends_on_its_timeout_is_kept_waiting_after_its_first_retry() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    upload(&mut m, 0, &[1, 2, 3], MISSION);
    ground_out(&mut m);
    // the ground: resends item 2 when 500 ms pass without a request for it
    let mut ground_at = 0;
    let mut own_retries = 0;
    let mut t = 0;
    while t < 20_000 {
        let next = m.poll_timeout().unwrap().as_millis().min(ground_at + 500);
        t = next;
        m.handle_timeout(ms(t));
        radio_out(&mut m, ms(t));
        let asked = ground_out(&mut m)
            .iter()
            .any(|msg| matches!(msg, MavMessage::MISSION_REQUEST_INT(r) if r.seq == 2));
        if asked || t >= ground_at + 500 {
            own_retries += u32::from(!asked);
            ground_at = t;
            m.from_ground(ms(t), GROUND, 1, &item(2, 3, MISSION));
        }
        assert!(acks(&ground_out(&mut m)).is_empty(), "no made-up answer");
    }
    assert_eq!(own_retries, 1, "one retry of its own, then kept waiting");
    assert!(m.stats().keepalives >= 45, "{}", m.stats().keepalives);
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

/// Regression: the relay kept going after the ground cancelled.
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
    let mut m = MissionTerminator::new(unpacked());
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

/// Each frame is paced at its own length on the radio (signed: 13 bytes more), not at the
/// longest a frame could be: a 21-byte count held the stream as long as a signed item.
#[test]
fn stream_is_paced_at_the_radio_budget_frame_by_frame() {
    let config = TerminatorConfig {
        pace_bytes_per_s: Some(1000),
        ..unpacked()
    };
    let mut m = MissionTerminator::new(config);
    m.from_ground(ms(0), GROUND, 1, &count(3, MISSION));
    for seq in 0..3 {
        m.from_ground(
            ms(0),
            GROUND,
            1,
            &item(seq, 100_000 + i32::from(seq), MISSION),
        );
    }
    let count = m.poll_radio(ms(0)).unwrap();
    assert!(matches!(count, MavMessage::MISSION_COUNT(_)));
    assert!(m.poll_radio(ms(0)).is_none(), "paced");
    let at = |msg: &MavMessage| Duration::from_millis(radio_len(msg) + 13);
    // at 1000 B/s a byte takes 1 ms
    let due = Instant::ZERO + at(&count);
    assert_eq!(m.poll_timeout(), Some(due));
    let first = m.poll_radio(due).unwrap();
    assert!(matches!(first, MavMessage::MISSION_ITEM_INT(_)));
    assert!(radio_len(&first) > radio_len(&count));
    assert_eq!(m.poll_timeout(), Some(due + at(&first)));
    // unsigned: only the frame
    let mut m = MissionTerminator::new(TerminatorConfig {
        frame_extra_bytes: 0,
        ..config
    });
    m.from_ground(ms(0), GROUND, 1, &count_msg(1));
    m.from_ground(ms(0), GROUND, 1, &item(0, 1, MISSION));
    let count = m.poll_radio(ms(0)).unwrap();
    assert_eq!(
        m.poll_timeout(),
        Some(Instant::ZERO + Duration::from_millis(radio_len(&count)))
    );
}

fn count_msg(n: u16) -> MavMessage {
    count(n, MISSION)
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
            MavMessage::MAVLORA_MISSION_ITEMS(p) => {
                assert_eq!(p.mission_type, FENCE);
                if p.items > 0 {
                    assert!(
                        pack::unpack(p)
                            .unwrap()
                            .iter()
                            .all(|i| i.mission_type == FENCE)
                    );
                }
            }
            other => panic!("{other:?}"),
        }
    }
    // the bridge's repair request is answered with the fence item
    m.from_radio(ms(3), &super::request((255, 191), 1, FENCE));
    assert_eq!(items_of(&radio_out(&mut m, ms(3))), vec![(1, 2)]);
    // a request of another type is not for this upload
    m.from_radio(ms(4), &super::request((255, 191), 1, MISSION));
    assert!(items_of(&radio_out(&mut m, ms(4))).is_empty());
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

/// The simulated ground station's survey: a waypoint every 100 m, climbing 1 m each.
fn survey(n: u16) -> Vec<i32> {
    (0..n).map(|i| 553_700_000 + i32::from(i) * 1000).collect()
}

/// Runs the terminator's timers from `t` until its first poll has gone to the radio; the
/// radio stream and the time of that poll.
fn until_poll(m: &mut MissionTerminator, from: Instant) -> (Vec<MavMessage>, Instant) {
    let mut t = from;
    let mut out = radio_out(m, t);
    for _ in 0..10_000 {
        if polls_of(&out) > 0 {
            return (out, t);
        }
        t = m.poll_timeout().unwrap();
        m.handle_timeout(t);
        out.extend(radio_out(m, t));
        ground_out(m);
    }
    panic!("no poll by {t}")
}

fn range(start: u16, end: u16) -> MavMessage {
    super::super::relay::request_range((255, 191), start, end, MISSION)
}

#[test]
fn a_plan_streams_packed_in_a_fifth_of_the_bytes_with_a_poll_behind() {
    let xs = survey(100);
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    let radio = upload(&mut m, 0, &xs, MISSION);
    assert!(matches!(radio.first(), Some(MavMessage::MISSION_COUNT(c)) if c.count == 100));
    let want: Vec<(u16, i32)> = xs.iter().enumerate().map(|(s, x)| (s as u16, *x)).collect();
    assert_eq!(items_of(&radio), want);
    assert!(
        matches!(radio.last(), Some(MavMessage::MAVLORA_MISSION_ITEMS(p)) if p.items == 0),
        "a poll right behind the stream"
    );
    let bytes: u64 = radio.iter().map(radio_len).sum();
    assert!(
        bytes * 5 < 100 * 49,
        "{bytes} bytes in {} frames",
        radio.len()
    );
    assert_eq!(m.stats().polls, 1);
}

/// A range request is answered packed, ahead of what has not left yet, without what still
/// waits to leave (it goes anyway) and without what left less than the shortest measured
/// round trip ago (the request crossed it: answering would send it twice).
#[test]
fn a_range_request_is_answered_ahead_of_the_stream_without_what_waits_or_crossed_it() {
    let config = TerminatorConfig {
        pace_bytes_per_s: Some(1000),
        pack_bytes: Some(60),
        ..TerminatorConfig::default()
    };
    let mut m = MissionTerminator::new(config);
    let xs: Vec<i32> = (0..40).map(|i| i * 70_000).collect();
    m.from_ground(ms(0), GROUND, 1, &count(40, MISSION));
    for (seq, x) in xs.iter().enumerate() {
        m.from_ground(ms(0), GROUND, 1, &item(seq as u16, *x, MISSION));
    }
    // the count and the first item frame leave; the rest wait for the pace
    let mut out = radio_out(&mut m, ms(0));
    let t = m.poll_timeout().unwrap();
    out.extend(radio_out(&mut m, t));
    let sent = items_of(&out);
    assert!(!sent.is_empty() && sent.len() < 40, "{}", sent.len());
    let last_sent = sent.last().unwrap().0;
    // the bridge asks for everything, a round trip later (a request sooner would have
    // crossed those frames): only what already left comes again, first
    m.from_radio(t + Duration::from_millis(600), &range(0, 39));
    let later = t + Duration::from_millis(2000);
    let next = radio_out(&mut m, later);
    let again: Vec<u16> = items_of(&next[..1]).iter().map(|(s, _)| *s).collect();
    assert_eq!(again, (0..=last_sent).collect::<Vec<_>>());
    assert_eq!(m.stats().items_repaired, u64::from(last_sent) + 1);
    // The trailing poll answered 300 ms after it left: the shortest round trip is 300 ms.
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    upload(&mut m, 0, &[1, 2, 3], MISSION);
    m.from_radio(ms(300), &range(3, 3)); // the answer to the trailing poll: "busy"
    assert_eq!(m.rtt().samples(), 1);
    m.from_radio(ms(400), &range(1, 1));
    assert_eq!(items_of(&radio_out(&mut m, ms(400))), vec![(1, 2)]);
    // a request for item 1 that left the bridge before the repair arrived
    m.from_radio(ms(500), &range(1, 1));
    assert!(items_of(&radio_out(&mut m, ms(500))).is_empty(), "crossed");
    // one sent after it: the repair was lost
    m.from_radio(ms(800), &range(1, 1));
    assert_eq!(items_of(&radio_out(&mut m, ms(800))), vec![(1, 2)]);
}

/// On SiK a fixed 2 s wait for the first poll would be most of a 100-item upload. The poll
/// timeout is two stream frames at the paced rate plus the margin until a round trip is
/// measured, then the measured RTO; a poll lost in a fade is followed by the next one a
/// timeout later, several times, before the timeout doubles up to `poll_max`.
#[test]
fn poll_timeout_follows_the_round_trip_and_polls_keep_coming_through_a_fade() {
    let uploaded = || {
        let mut m = MissionTerminator::new(TerminatorConfig {
            pace_bytes_per_s: Some(3000),
            ..TerminatorConfig::default()
        });
        m.from_ground(ms(0), GROUND, 1, &count(100, MISSION));
        for (seq, x) in survey(100).iter().enumerate() {
            m.from_ground(ms(0), GROUND, 1, &item(seq as u16, *x, MISSION));
        }
        let (out, t0) = until_poll(&mut m, ms(0));
        (m, out, t0)
    };
    let (mut m, out, t0) = uploaded();
    let largest = out.iter().map(|f| radio_len(f) + 13).max().unwrap();
    let unmeasured = Duration::from_micros(2 * largest * 1_000_000 / 3000) + MARGIN;
    assert!(unmeasured < Duration::from_millis(300), "{unmeasured:?}");
    // the poll behind the stream is lost: the next goes one unmeasured timeout after it
    let (_, t1) = until_poll(&mut m, t0);
    assert_eq!(t1, t0 + unmeasured);
    // answered 200 ms after it left: the RTO follows (RFC 6298 first sample: 200 + 4 x 100)
    let (mut m, _, t0) = uploaded();
    let answer = t0 + Duration::from_millis(200);
    m.from_radio(answer, &range(100, 100)); // "busy"
    assert_eq!(m.rtt().rto(), Duration::from_millis(600));
    let (_, t2) = until_poll(&mut m, answer);
    assert_eq!(t2, answer + Duration::from_millis(600));
    // a fade: polls unanswered; after POLLS_BEFORE_BACKOFF of them the timeout doubles
    let mut gaps = Vec::new();
    let mut t = t2;
    for _ in 0..8 {
        let (_, next) = until_poll(&mut m, t);
        gaps.push((next - t).as_millis());
        t = next;
    }
    let mut want = vec![600; POLLS_BEFORE_BACKOFF as usize];
    want.extend([1200, 2000, 2000, 2000]);
    want.truncate(8);
    assert_eq!(gaps, want);
}

fn vehicle_ack(result: MavMissionResult, t: MavMissionType, opaque_id: u32) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: GROUND.0,
        target_component: GROUND.1,
        mavtype: result,
        mission_type: t,
        opaque_id,
        ..Default::default()
    })
}

/// Regression: while the router took a ground upload, the autopilot's own MISSION_ACKs
/// with `opaque_id` 0 (ArduPilot's always are) went to the ground, which took the first for
/// its upload's answer. The autopilot's acks reach a ground only as the answer to an
/// operation it passed through, never while it uploads that type.
#[test]
fn the_autopilots_acks_answer_only_what_the_ground_passed_through() {
    let accepted = MavMissionResult::MAV_MISSION_ACCEPTED;
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    // answering nothing
    assert!(!m.from_vehicle(ms(0), &vehicle_ack(accepted, MISSION, 0)));
    // mid-upload, with or without an id
    m.from_ground(ms(0), GROUND, 1, &count(2, MISSION));
    assert!(!m.from_vehicle(ms(1), &vehicle_ack(accepted, MISSION, 0)));
    upload(&mut m, 2, &[1, 2], MISSION);
    assert!(!m.from_vehicle(ms(3), &vehicle_ack(accepted, MISSION, 0)));
    assert!(!m.from_vehicle(ms(3), &vehicle_ack(accepted, MISSION, 77)));
    assert_eq!(m.stats().vehicle_acks_held, 4);
    // the answer to a clear-all (PX4 names the cleared plan), once
    let clear = MavMessage::MISSION_CLEAR_ALL(crate::dialect::MISSION_CLEAR_ALL_DATA {
        target_system: 1,
        target_component: 1,
        mission_type: FENCE,
        ..Default::default()
    });
    assert!(!m.from_ground(ms(4), GROUND, 1, &clear), "passes through");
    assert!(m.from_vehicle(ms(5), &vehicle_ack(accepted, FENCE, 0xC1EA)));
    assert!(!m.from_vehicle(ms(6), &vehicle_ack(accepted, FENCE, 0xC1EA)));
    // requests always pass (a partial write's)
    assert!(m.from_vehicle(ms(7), &super::request(GROUND, 1, FENCE)));
}

/// Regression: `seq + 1` overflowed on an item numbered 65535 (a debug build panicked).
#[test]
fn an_item_numbered_65535_neither_panics_nor_counts() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    m.from_ground(ms(0), GROUND, 1, &count(1, MISSION));
    assert!(m.from_ground(ms(1), GROUND, 1, &item(u16::MAX, 0, MISSION)));
    // after the vehicle answered an empty plan (count 0)
    let id = id_of(&upload(&mut m, 2, &[], MISSION));
    m.from_radio(
        ms(3),
        &bridge_ack(id, MavMissionResult::MAV_MISSION_ACCEPTED, MISSION),
    );
    assert!(m.from_ground(ms(4), GROUND, 1, &item(u16::MAX, 0, MISSION)));
}

/// The ground's items requested so far (from what the terminator sent it).
fn requests_in(msgs: &[MavMessage]) -> Vec<u16> {
    msgs.iter()
        .filter_map(|m| match m {
            MavMessage::MISSION_REQUEST_INT(r) => Some(r.seq),
            _ => None,
        })
        .collect()
}

/// A ground that answers each request at once and never resends (MAVSDK, which counts every
/// repeated request against its 5 tries and gives up 2.5 s after its last send, without a
/// word) uploads a 100-item survey over a LoRa-paced radio leg whose bridge never answers:
/// it is asked for the next item as the radio takes the plan, never left waiting longer
/// than [`HOLD_MAX`], and not asked for its last items before the stream is nearly out.
#[test]
fn a_silent_ground_is_asked_for_its_items_as_the_radio_takes_them() {
    let config = TerminatorConfig {
        pace_bytes_per_s: Some(683),
        ..TerminatorConfig::default()
    };
    let mut m = MissionTerminator::new(config);
    let xs = survey(100);
    m.from_ground(ms(0), GROUND, 1, &count(100, MISSION));
    let (mut asked_at, mut longest, mut last_frame_left) = (0u64, 0u64, 0u64);
    let mut t = 0;
    let mut asked_last_at = None;
    while t < 60_000 && asked_last_at.is_none() {
        m.handle_timeout(ms(t));
        let out = radio_out(&mut m, ms(t));
        if !items_of(&out).is_empty() {
            last_frame_left = t;
        }
        // The ground answers at once, and may be asked again at once.
        while let seqs = requests_in(&ground_out(&mut m))
            && !seqs.is_empty()
        {
            for seq in seqs {
                longest = longest.max(t - asked_at);
                asked_at = t;
                if seq == 99 {
                    asked_last_at = Some(t);
                }
                m.from_ground(ms(t), GROUND, 1, &item(seq, xs[usize::from(seq)], MISSION));
            }
        }
        t = m
            .poll_timeout()
            .map_or(t + 10, |d| d.as_millis().max(t + 1));
    }
    assert!(
        longest <= HOLD_MAX.as_millis(),
        "the ground waited {longest} ms"
    );
    let asked_last_at = asked_last_at.expect("the last item is asked for");
    // A 100-item survey is ~5 LoRa frames of ~0.9 s each at this pace: the last item is not
    // asked for before the first four have left.
    let frames_left = 4 * 224 * 1000 / 683;
    assert!(
        asked_last_at >= frames_left,
        "last item asked for at {asked_last_at} ms, stream out at {last_frame_left} ms"
    );
}

/// The bridge's answer to a poll lists the missing runs lowest first, one request each: a run
/// above what was sent (the tail held back) releases the tail only when nothing lower was
/// asked for since the poll left. Regression: a repair and the tail in one answer released
/// the tail at once, and it queued behind seconds of repairs while the ground's timer ran.
#[test]
fn the_tail_is_asked_for_once_the_bridge_misses_nothing_sent() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    let xs: Vec<i32> = (0..10).collect();
    m.from_ground(ms(0), GROUND, 1, &count(10, MISSION));
    let mut asked = Vec::new();
    for _ in 0..10 {
        let seqs = requests_in(&ground_out(&mut m));
        if seqs.is_empty() {
            break;
        }
        for seq in seqs {
            asked.push(seq);
            m.from_ground(ms(0), GROUND, 1, &item(seq, xs[usize::from(seq)], MISSION));
        }
        radio_out(&mut m, ms(0));
    }
    assert_eq!(asked, (0..5).collect::<Vec<u16>>(), "items 5..=9 held back");
    let out = radio_out(&mut m, ms(0));
    assert!(polls_of(&out) <= 1);
    // the poll's answer: items 2..=3 lost, and the tail it never got
    m.from_radio(ms(100), &range(2, 3));
    m.from_radio(ms(100), &range(5, 9));
    assert!(requests_in(&ground_out(&mut m)).is_empty(), "repairs first");
    let out = radio_out(&mut m, ms(100));
    assert_eq!(
        items_of(&out).iter().map(|i| i.0).collect::<Vec<_>>(),
        vec![2, 3]
    );
    assert_eq!(polls_of(&out), 1, "a poll behind the repairs");
    // the next poll's answer: only the tail
    m.from_radio(ms(200), &range(5, 9));
    assert_eq!(requests_in(&ground_out(&mut m)), vec![5]);
}

/// A held tail with no word from the bridge: each time the ground has waited [`HOLD_MAX`]
/// it is asked for one more item, so a ground that waits silently never times out.
#[test]
fn a_held_tail_is_asked_for_item_by_item_while_the_bridge_is_silent() {
    let mut m = MissionTerminator::new(TerminatorConfig::default());
    m.from_ground(ms(0), GROUND, 1, &count(8, MISSION));
    let mut asked = Vec::new();
    let mut t = 0;
    while t < 30_000 && asked.len() < 8 {
        m.handle_timeout(ms(t));
        radio_out(&mut m, ms(t));
        while let seqs = requests_in(&ground_out(&mut m))
            && !seqs.is_empty()
        {
            for seq in seqs {
                asked.push((seq, t));
                m.from_ground(ms(t), GROUND, 1, &item(seq, i32::from(seq), MISSION));
            }
        }
        t = m
            .poll_timeout()
            .map_or(t + 10, |d| d.as_millis().max(t + 1));
    }
    let tail: Vec<_> = asked[3..].iter().map(|(_, at)| *at).collect();
    assert_eq!(asked.len(), 8, "{asked:?}");
    assert_eq!(asked[2].1, 0, "the head at once: {asked:?}");
    for pair in tail.windows(2) {
        assert_eq!(pair[1] - pair[0], HOLD_MAX.as_millis(), "{asked:?}");
    }
}
