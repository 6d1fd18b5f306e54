use super::*;
use crate::dialect::MavMissionType;
use crate::mission::pack;
use crate::mission::plan::{plan_hash, transfer_id};

const ROUTER: (u8, u8) = (255, 191);
const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

fn plan(xs: &[i32]) -> Vec<MISSION_ITEM_INT_DATA> {
    xs.iter()
        .enumerate()
        .map(|(seq, x)| MISSION_ITEM_INT_DATA {
            seq: seq as u16,
            x: *x,
            target_system: 1,
            ..Default::default()
        })
        .collect()
}

fn count_for(items: &[MISSION_ITEM_INT_DATA], generation: u8) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: items.len() as u16,
        target_system: 1,
        opaque_id: transfer_id(generation, plan_hash(MISSION, items)),
        ..Default::default()
    })
}

fn radio_out(r: &mut MissionRelay) -> Vec<MavMessage> {
    std::iter::from_fn(|| r.poll_radio()).collect()
}

fn fc_out(r: &mut MissionRelay) -> Vec<MavMessage> {
    std::iter::from_fn(|| r.poll_fc((1, 1))).collect()
}

/// The items asked for: ranges (`MISSION_REQUEST_PARTIAL_LIST`, both ends included) and
/// single requests (`MISSION_REQUEST_INT`: the "busy" answer, seq = count).
fn requested(msgs: &[MavMessage]) -> Vec<u16> {
    msgs.iter()
        .flat_map(|m| match m {
            MavMessage::MISSION_REQUEST_INT(r) => vec![r.seq],
            MavMessage::MISSION_REQUEST_PARTIAL_LIST(r) => {
                (r.start_index as u16..=r.end_index as u16).collect()
            }
            _ => vec![],
        })
        .collect()
}

fn fc_request(seq: u16) -> MavMessage {
    MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq,
        target_system: 1,
        target_component: 191,
        ..Default::default()
    })
}

fn fc_ack(result: MavMissionResult) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: 1,
        target_component: 191,
        mavtype: result,
        ..Default::default()
    })
}

/// Runs the wire leg to the end as an autopilot that takes every item.
fn wire_upload(r: &mut MissionRelay, n: u16, now: Instant) -> Vec<MISSION_ITEM_INT_DATA> {
    let mut got = Vec::new();
    assert!(matches!(&fc_out(r)[..], [MavMessage::MISSION_COUNT(c)] if c.count == n));
    for seq in 0..n {
        r.handle_fc(now, &fc_request(seq));
        for m in fc_out(r) {
            if let MavMessage::MISSION_ITEM_INT(i) = m {
                got.push(i);
            }
        }
    }
    r.handle_fc(now, &fc_ack(MavMissionResult::MAV_MISSION_ACCEPTED));
    got
}

#[test]
fn lost_items_are_requested_selectively_and_a_lost_tail_after_one_timeout() {
    let items = plan(&[10, 11, 12, 13, 14]);
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&items, 1));
    assert!(
        radio_out(&mut r).is_empty(),
        "a loss-free stream costs no request"
    );
    r.handle_radio(
        ms(100),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[0].clone()),
    );
    // item 1 and 2 lost: item 3 shows the gap
    r.handle_radio(
        ms(200),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[3].clone()),
    );
    assert_eq!(requested(&radio_out(&mut r)), vec![1, 2]);
    // item 4 (the tail) lost too; the repairs arrive
    r.handle_radio(
        ms(500),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[1].clone()),
    );
    r.handle_radio(
        ms(510),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[2].clone()),
    );
    assert!(radio_out(&mut r).is_empty());
    let due = r.poll_timeout().unwrap();
    r.handle_timeout(due);
    assert_eq!(
        requested(&radio_out(&mut r)),
        vec![4],
        "only what is missing"
    );
    r.handle_radio(
        due + Duration::from_millis(300),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[4].clone()),
    );
    let got = wire_upload(&mut r, 5, ms(3000));
    assert!(super::super::plan::same_plan(&got, &items));
    let out = radio_out(&mut r);
    assert!(matches!(&out[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED && a.opaque_id == transfer_id(1, plan_hash(MISSION, &items))));
    assert_eq!(r.stats().radio_requests, 3);
}

/// On the radio leg too: items of an older plan must never be mixed in.
#[test]
fn items_of_another_plan_are_refused_and_all_asked_again() {
    let old = plan(&[1, 2]);
    let new = plan(&[3, 4]);
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&new, 2));
    // the old plan's items (a COUNT lost, a late copy) arrive under the new transfer
    r.handle_radio(
        ms(10),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(old[0].clone()),
    );
    r.handle_radio(
        ms(20),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(new[1].clone()),
    );
    assert!(fc_out(&mut r).is_empty(), "nothing reaches the autopilot");
    assert_eq!(requested(&radio_out(&mut r)), vec![0, 1]);
    assert_eq!(r.stats().plan_mismatches, 1);
    r.handle_radio(
        ms(30),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(new[0].clone()),
    );
    r.handle_radio(
        ms(40),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(new[1].clone()),
    );
    let got = wire_upload(&mut r, 2, ms(50));
    assert!(super::super::plan::same_plan(&got, &new));
}

/// Regression: an autopilot reboot mid-upload ended in an error instead of a restart.
#[test]
fn autopilot_reboot_mid_upload_restarts_the_wire_leg() {
    let items = plan(&[1, 2, 3]);
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&items, 1));
    for i in &items {
        r.handle_radio(ms(10), ROUTER, &MavMessage::MISSION_ITEM_INT(i.clone()));
    }
    fc_out(&mut r);
    r.handle_fc(ms(20), &fc_request(0));
    fc_out(&mut r);
    r.fc_rebooted(ms(4000));
    let got = wire_upload(&mut r, 3, ms(4100));
    assert!(super::super::plan::same_plan(&got, &items));
    assert!(
        matches!(&radio_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED)
    );
    assert_eq!(r.stats().wire_restarts, 1);
}

#[test]
fn router_cancel_stops_the_wire_leg_and_tells_the_autopilot() {
    let items = plan(&[1, 2]);
    let id = transfer_id(1, plan_hash(MISSION, &items));
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&items, 1));
    for i in &items {
        r.handle_radio(ms(10), ROUTER, &MavMessage::MISSION_ITEM_INT(i.clone()));
    }
    fc_out(&mut r);
    let cancel = ack(
        (1, 1),
        MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
        MISSION,
        id,
    );
    assert!(r.handle_radio(ms(20), ROUTER, &cancel));
    assert!(matches!(&fc_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_OPERATION_CANCELLED));
    // the autopilot's further requests are no longer answered, nor passed on: they were
    // addressed to us
    assert!(r.handle_fc(ms(30), &fc_request(1)));
    assert!(fc_out(&mut r).is_empty() && radio_out(&mut r).is_empty());
    assert_eq!(r.stats().wire_stray, 1);
    assert_eq!(r.poll_timeout(), None);
    // an ack without a transfer id (a ground's download ACK) is for the autopilot
    assert!(!r.handle_radio(
        ms(40),
        ROUTER,
        &ack((1, 1), MavMissionResult::MAV_MISSION_ACCEPTED, MISSION, 0)
    ));
}

#[test]
fn poll_is_answered_by_state_missing_busy_or_the_same_ack() {
    let items = plan(&[1, 2]);
    let count = packed_poll(&items, 1);
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&items, 1));
    r.handle_radio(
        ms(10),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[0].clone()),
    );
    r.handle_radio(ms(20), ROUTER, &count);
    assert_eq!(requested(&radio_out(&mut r)), vec![1]);
    r.handle_radio(
        ms(30),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[1].clone()),
    );
    r.handle_radio(ms(40), ROUTER, &count);
    assert_eq!(requested(&radio_out(&mut r)), vec![2], "busy: seq = count");
    wire_upload(&mut r, 2, ms(50));
    radio_out(&mut r);
    r.handle_radio(ms(60), ROUTER, &count);
    assert!(
        matches!(&radio_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED)
    );
    assert_eq!(r.stats().completed, 1, "the poll did not upload again");
}

#[test]
fn silent_autopilot_and_silent_router_end_in_an_error_ack() {
    let items = plan(&[]);
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&items, 1));
    let mut now = ms(0);
    while let Some(t) = r.poll_timeout() {
        now = t;
        r.handle_timeout(now);
    }
    assert_eq!(fc_out(&mut r).len(), 6, "COUNT sent wire_attempts times");
    assert!(
        matches!(&radio_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_ERROR)
    );
    assert_eq!(now, ms(6 * 1500));

    let items = plan(&[1, 2, 3]);
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&items, 1));
    while let Some(t) = r.poll_timeout() {
        r.handle_timeout(t);
    }
    let out = radio_out(&mut r);
    assert_eq!(requested(&out).len(), 30, "10 rounds of 3 requests");
    assert!(matches!(out.last(), Some(MavMessage::MISSION_ACK(a))
        if a.mavtype == MavMissionResult::MAV_MISSION_OPERATION_CANCELLED));
    assert_eq!(r.stats().failed, 1);
}

#[test]
fn items_whose_count_was_lost_are_kept_for_it_and_not_sent_again() {
    let items = plan(&[5, 6, 7]);
    let mut r = MissionRelay::new(MissionConfig::default());
    // the COUNT is lost; items 0 and 2 arrive (1 lost too)
    r.handle_radio(
        ms(10),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[0].clone()),
    );
    r.handle_radio(
        ms(20),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[2].clone()),
    );
    // the router's poll repeats the count: only item 1 is asked for
    r.handle_radio(ms(2000), ROUTER, &count_for(&items, 1));
    assert_eq!(requested(&radio_out(&mut r)), vec![1]);
    r.handle_radio(
        ms(2500),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[1].clone()),
    );
    let got = wire_upload(&mut r, 3, ms(2600));
    assert!(super::super::plan::same_plan(&got, &items));
}

/// The count got through but every item of the stream was lost (a fade): the router's poll
/// says the stream has left, and every missing item is asked for at once, one request per
/// run, not a batch of 8 per round trip (100 items would take 13 rounds).
#[test]
fn after_a_poll_every_missing_item_is_asked_for_at_once_one_request_per_run() {
    let items = plan(&(0..100).collect::<Vec<_>>());
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&items, 1));
    for i in (0..10).chain(50..60) {
        r.handle_radio(
            ms(10),
            ROUTER,
            &MavMessage::MISSION_ITEM_INT(items[i].clone()),
        );
    }
    // items 10..49 show as a gap when 50 arrives
    let gap = radio_out(&mut r);
    assert_eq!(gap.len(), 1, "one request for one run");
    assert_eq!(requested(&gap), (10..50).collect::<Vec<u16>>());
    // 2 s later, nothing else arrived; the router polls: the tail too, and the first run
    // again (its request or its answer was lost: the poll came after both would have)
    r.handle_radio(ms(2000), ROUTER, &packed_poll(&items, 1));
    let asked = radio_out(&mut r);
    assert_eq!(asked.len(), 2, "{asked:?}");
    assert_eq!(
        requested(&asked),
        (10..50).chain(60..100).collect::<Vec<u16>>()
    );
    assert_eq!(r.stats().radio_request_frames, 3);
    assert_eq!(r.stats().radio_requests, 40 + 80);
    for i in (10..50).chain(60..100) {
        r.handle_radio(
            ms(2300),
            ROUTER,
            &MavMessage::MISSION_ITEM_INT(items[i].clone()),
        );
    }
    assert!(radio_out(&mut r).is_empty(), "nothing more to ask");
    assert!(matches!(&fc_out(&mut r)[..], [MavMessage::MISSION_COUNT(c)] if c.count == 100));
}

fn packed(items: &[MISSION_ITEM_INT_DATA], generation: u8) -> Vec<MavMessage> {
    let id = transfer_id(generation, plan_hash(MISSION, items));
    pack::frames(id, items.len() as u16, (1, 1), MISSION, items, 60)
}

fn packed_poll(items: &[MISSION_ITEM_INT_DATA], generation: u8) -> MavMessage {
    let id = transfer_id(generation, plan_hash(MISSION, items));
    pack::poll(id, items.len() as u16, (1, 1), MISSION, None)
}

/// Packed frames name their transfer and the plan's size: a bridge that lost the count
/// opens the transfer from the first frame it gets, repairs a lost frame by range, and
/// uploads exactly the plan.
#[test]
fn packed_items_open_their_transfer_and_a_lost_frame_is_asked_for_by_range() {
    let items = plan(&(0..30).map(|x| 1000 + 70_000 * x).collect::<Vec<_>>());
    let frames = packed(&items, 1);
    assert!(frames.len() >= 3, "{}", frames.len());
    let mut r = MissionRelay::new(MissionConfig::default());
    // the count and the first frame are lost
    for f in &frames[1..] {
        r.handle_radio(ms(10), ROUTER, f);
    }
    let MavMessage::MAVLORA_MISSION_ITEMS(first) = &frames[0] else {
        unreachable!()
    };
    let lost: Vec<u16> = pack::span(first).map(|s| s as u16).collect();
    assert_eq!(requested(&radio_out(&mut r)), lost);
    assert_eq!(r.stats().radio_request_frames, 1);
    assert!(
        fc_out(&mut r).is_empty(),
        "incomplete: nothing for the autopilot"
    );
    // the repair arrives (the router re-packs the range)
    r.handle_radio(ms(300), ROUTER, &frames[0]);
    let got = wire_upload(&mut r, 30, ms(400));
    assert!(super::super::plan::same_plan(&got, &items));
    assert!(
        matches!(&radio_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED
            && a.opaque_id == transfer_id(1, plan_hash(MISSION, &items)))
    );
    assert_eq!(r.stats().radio_packed_frames, frames.len() as u64);
    assert!(
        r.rtt().samples() > 0,
        "the repair's round trip was measured"
    );
}

/// The router's poll when packing is a frame without items: the bridge knows it for a poll
/// even when it never saw the transfer (count and every frame lost) and asks for all of it;
/// later polls get "busy" while the autopilot takes the items, then the same ack.
#[test]
fn packed_poll_asks_for_everything_missing_then_busy_then_the_same_ack() {
    let items = plan(&[5, 6, 7, 8]);
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &packed_poll(&items, 1));
    assert_eq!(requested(&radio_out(&mut r)), vec![0, 1, 2, 3]);
    for f in packed(&items, 1) {
        r.handle_radio(ms(100), ROUTER, &f);
    }
    assert!(matches!(&fc_out(&mut r)[..], [MavMessage::MISSION_COUNT(c)] if c.count == 4));
    r.handle_radio(ms(200), ROUTER, &packed_poll(&items, 1));
    assert_eq!(requested(&radio_out(&mut r)), vec![4], "busy: seq = count");
    for seq in 0..4 {
        r.handle_fc(ms(300), &fc_request(seq));
    }
    r.handle_fc(ms(300), &fc_ack(MavMissionResult::MAV_MISSION_ACCEPTED));
    radio_out(&mut r);
    r.handle_radio(ms(400), ROUTER, &packed_poll(&items, 1));
    assert!(
        matches!(&radio_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED)
    );
    assert_eq!(r.stats().completed, 1);
}

/// A late frame of a transfer that is over (a repair that crossed a new upload's count, or
/// a duplicate) never reopens it: the new upload goes on. Its count does reopen it: a
/// restarted router numbers transfers from the start again.
#[test]
fn a_late_packed_frame_never_reopens_a_finished_transfer_but_its_count_does() {
    let old = plan(&[1, 2, 3]);
    let new = plan(&[4, 5, 6]);
    let mut r = MissionRelay::new(MissionConfig::default());
    for f in packed(&old, 1) {
        r.handle_radio(ms(0), ROUTER, &f);
    }
    wire_upload(&mut r, 3, ms(10));
    radio_out(&mut r);
    r.handle_radio(ms(20), ROUTER, &count_for(&new, 2));
    for f in packed(&old, 1) {
        r.handle_radio(ms(30), ROUTER, &f);
    }
    assert_eq!(r.stats().radio_stale_frames, 1);
    assert!(
        fc_out(&mut r).is_empty(),
        "the old plan does not go to the autopilot again"
    );
    for f in packed(&new, 2) {
        r.handle_radio(ms(40), ROUTER, &f);
    }
    let got = wire_upload(&mut r, 3, ms(50));
    assert!(super::super::plan::same_plan(&got, &new));
    radio_out(&mut r);
    // the old transfer's count again (a restarted router): a new transfer of it
    r.handle_radio(ms(60), ROUTER, &count_for(&old, 1));
    for f in packed(&old, 1) {
        r.handle_radio(ms(70), ROUTER, &f);
    }
    let got = wire_upload(&mut r, 3, ms(80));
    assert!(super::super::plan::same_plan(&got, &old));
}

#[test]
fn an_unreadable_packed_frame_is_counted_and_changes_nothing() {
    let items = plan(&[1, 2, 3]);
    let mut frames = packed(&items, 1);
    let MavMessage::MAVLORA_MISSION_ITEMS(p) = &mut frames[0] else {
        unreachable!()
    };
    p.data = [0xFF; pack::MAX_DATA];
    let mut r = MissionRelay::new(MissionConfig::default());
    assert!(r.handle_radio(ms(0), ROUTER, &frames[0]));
    assert_eq!(r.stats().radio_bad_frames, 1);
    assert_eq!(r.stats().transfers, 0);
    assert_eq!(r.poll_timeout(), None);
}

#[test]
fn the_first_timeout_follows_the_radios_budget() {
    // Two 280-byte frames at the rate plus the 100 ms margin, within 300 ms and 1.5 s.
    let ms = |c: MissionConfig| c.initial_rtt.as_micros() / 1000;
    assert_eq!(ms(MissionConfig::for_rate(6_400)), 300); // SiK 64k at 80 %: 187 ms
    assert_eq!(ms(MissionConfig::for_rate(546)), 1_125); // LoRa SF7 at 80 %
    assert_eq!(ms(MissionConfig::for_rate(100)), 1_500); // slower: the default
    assert_eq!(MissionConfig::for_rate(0), MissionConfig::default());
}

/// Regression: a count whose transfer id matched the finished transfer was answered from
/// memory (the same ACCEPTED again) and never reached the autopilot. A restarted router
/// numbers the same plan the same way, and the autopilot may have cleared it since: a count
/// is always a new upload.
#[test]
fn a_count_for_a_finished_transfer_is_uploaded_again_never_answered_from_memory() {
    let items = plan(&[1, 2, 3]);
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&items, 1));
    for f in packed(&items, 1) {
        r.handle_radio(ms(10), ROUTER, &f);
    }
    wire_upload(&mut r, 3, ms(20));
    radio_out(&mut r);
    // the same count again
    r.handle_radio(ms(5000), ROUTER, &count_for(&items, 1));
    assert!(
        radio_out(&mut r).is_empty(),
        "no ack from memory: {:?}",
        r.stats()
    );
    for f in packed(&items, 1) {
        r.handle_radio(ms(5010), ROUTER, &f);
    }
    let got = wire_upload(&mut r, 3, ms(5020));
    assert!(super::super::plan::same_plan(&got, &items));
    assert_eq!(r.stats().completed, 2);
}

/// A restarted router numbers its transfers from its seed again and knows none of ours: a
/// finished transfer is forgotten, so a poll or frames of the same id (their count lost)
/// open a new upload instead of repeating the old ack.
#[test]
fn after_a_router_restart_the_finished_transfer_is_forgotten() {
    let items = plan(&[4, 5]);
    let mut r = MissionRelay::new(MissionConfig::default());
    for f in packed(&items, 1) {
        r.handle_radio(ms(0), ROUTER, &f);
    }
    wire_upload(&mut r, 2, ms(10));
    radio_out(&mut r);
    r.router_restarted();
    // the count is lost; the stream's frames and its poll arrive
    for f in packed(&items, 1) {
        r.handle_radio(ms(3000), ROUTER, &f);
    }
    r.handle_radio(ms(3000), ROUTER, &packed_poll(&items, 1));
    assert!(
        !radio_out(&mut r)
            .iter()
            .any(|m| matches!(m, MavMessage::MISSION_ACK(_))),
        "no ack from memory"
    );
    let got = wire_upload(&mut r, 2, ms(3100));
    assert!(super::super::plan::same_plan(&got, &items));
}

/// Regression: the wire leg ended on any MISSION_ACK of its type, even before the autopilot
/// asked for the last item. An ACCEPTED before then answers an earlier upload; an error
/// ends this one.
#[test]
fn only_an_accepted_after_every_item_answers_the_upload() {
    let items = plan(&[7, 8, 9]);
    let id = transfer_id(1, plan_hash(MISSION, &items));
    let mut r = MissionRelay::new(MissionConfig::default());
    for f in packed(&items, 1) {
        r.handle_radio(ms(0), ROUTER, &f);
    }
    assert!(matches!(
        &fc_out(&mut r)[..],
        [MavMessage::MISSION_COUNT(_)]
    ));
    // the previous plan's late ACCEPTED (PX4 names it), and ArduPilot's (no id)
    for opaque_id in [0xABCD, 0] {
        let late = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: 1,
            target_component: 191,
            mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
            opaque_id,
            ..Default::default()
        });
        assert!(r.handle_fc(ms(10), &late));
    }
    assert!(radio_out(&mut r).is_empty(), "not this upload's answer");
    assert_eq!(r.stats().wire_early_acks, 2);
    for seq in 0..2 {
        r.handle_fc(ms(20), &fc_request(seq));
    }
    r.handle_fc(ms(30), &fc_ack(MavMissionResult::MAV_MISSION_ACCEPTED));
    assert!(radio_out(&mut r).is_empty(), "item 2 was never asked for");
    r.handle_fc(ms(40), &fc_request(2));
    r.handle_fc(ms(50), &fc_ack(MavMissionResult::MAV_MISSION_ACCEPTED));
    assert!(
        matches!(&radio_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED && a.opaque_id == id)
    );
    // an error ends an upload at any point
    let other = plan(&[1, 2]);
    for f in packed(&other, 2) {
        r.handle_radio(ms(100), ROUTER, &f);
    }
    fc_out(&mut r);
    r.handle_fc(ms(110), &fc_ack(MavMissionResult::MAV_MISSION_NO_SPACE));
    assert!(
        matches!(&radio_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_NO_SPACE)
    );
}

/// Regression: a MAVLink 1 autopilot got a fence upload as a mission (MAVLink 1 has no
/// `mission_type`) and replaced its flight plan with it. Refused, nothing sent to it.
#[test]
fn a_mavlink1_autopilot_gets_missions_only() {
    let fence = MavMissionType::MAV_MISSION_TYPE_FENCE;
    let mut r = MissionRelay::new(MissionConfig::default());
    r.set_fc_mavlink1(true);
    let id = transfer_id(1, plan_hash(fence, &[]));
    let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: 0,
        target_system: 1,
        mission_type: fence,
        opaque_id: id,
        ..Default::default()
    });
    r.handle_radio(ms(0), ROUTER, &count);
    assert!(fc_out(&mut r).is_empty());
    assert!(
        matches!(&radio_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
        if a.mavtype == MavMissionResult::MAV_MISSION_UNSUPPORTED && a.opaque_id == id
            && a.mission_type == fence)
    );
    // a mission goes
    let items = plan(&[1]);
    r.handle_radio(ms(10), ROUTER, &count_for(&items, 2));
    r.handle_radio(
        ms(10),
        ROUTER,
        &MavMessage::MISSION_ITEM_INT(items[0].clone()),
    );
    wire_upload(&mut r, 1, ms(20));
    assert_eq!(r.stats().unsupported, 1);
}

/// The router starts streaming before the ground has sent the whole plan: the count's id
/// then has plan part 0 and the poll behind the last item names the plan. With every item in,
/// the bridge waits for that name and checks the assembled plan against it: an item of
/// another plan mixed in has every item asked for again; the right plan goes to the
/// autopilot and the router hears "busy" at once.
#[test]
fn a_plan_named_by_the_poll_is_uploaded_only_once_the_poll_matches_it() {
    let items = plan(&(0..12).map(|x| 500 + 9_000 * x).collect::<Vec<_>>());
    let id = transfer_id(4, 0);
    let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: items.len() as u16,
        target_system: 1,
        opaque_id: id,
        ..Default::default()
    });
    let frames = |xs: &[MISSION_ITEM_INT_DATA]| {
        pack::frames(id, items.len() as u16, (1, 1), MISSION, xs, 60)
    };
    let mut other = items.clone();
    other[3].x += 1;
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count);
    for f in frames(&other) {
        r.handle_radio(ms(10), ROUTER, &f);
    }
    assert!(
        fc_out(&mut r).is_empty(),
        "every item here, the plan not named yet"
    );
    // its timer finds nothing lost and never gives the transfer up while it waits
    for t in (500..30_000).step_by(500) {
        r.handle_timeout(ms(t));
    }
    assert!(requested(&radio_out(&mut r)).is_empty());
    let named = pack::poll(
        id,
        items.len() as u16,
        (1, 1),
        MISSION,
        Some(plan_hash(MISSION, &items) & 0x00FF_FFFF),
    );
    r.handle_radio(ms(30_000), ROUTER, &named);
    assert_eq!(r.stats().plan_mismatches, 1);
    assert_eq!(requested(&radio_out(&mut r)), (0..12).collect::<Vec<u16>>());
    assert!(fc_out(&mut r).is_empty());
    for f in frames(&items) {
        r.handle_radio(ms(30_100), ROUTER, &f);
    }
    let got = wire_upload(&mut r, 12, ms(30_300));
    assert!(super::super::plan::same_plan(&got, &items));
    // the autopilot's ACCEPTED, and the same again for the router's next poll
    r.handle_radio(ms(30_400), ROUTER, &named);
    let out = radio_out(&mut r);
    assert!(
        out.len() == 2
            && out.iter().all(|m| matches!(m, MavMessage::MISSION_ACK(a)
                if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED && a.opaque_id == id)),
        "{out:?}"
    );
}
