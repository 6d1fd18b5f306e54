use super::*;
use crate::dialect::MavMissionType;
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

fn requested(msgs: &[MavMessage]) -> Vec<u16> {
    msgs.iter()
        .filter_map(|m| match m {
            MavMessage::MISSION_REQUEST_INT(r) => Some(r.seq),
            _ => None,
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

/// Issue 9, 3.1, on the radio leg: items of an older plan must never be mixed in.
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

/// Issue 9, 3.4: an autopilot reboot mid-upload ended in an error instead of a restart.
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
    // the autopilot's further requests are no longer answered
    assert!(!r.handle_fc(ms(30), &fc_request(1)));
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
    let count = count_for(&items, 1);
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count);
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
/// says the stream has left, and from then on each answered request fetches the next, at
/// the round trip, with no timeout between batches.
#[test]
fn after_a_poll_repairs_flow_at_the_round_trip_not_a_batch_per_timeout() {
    let items = plan(&(0..100).collect::<Vec<_>>());
    let mut r = MissionRelay::new(MissionConfig::default());
    r.handle_radio(ms(0), ROUTER, &count_for(&items, 1));
    radio_out(&mut r);
    // 2 s later, nothing else arrived; the router polls.
    r.handle_radio(ms(2000), ROUTER, &count_for(&items, 1));
    let mut asked = requested(&radio_out(&mut r));
    assert!(!asked.is_empty() && asked.len() <= 8, "{asked:?}");
    // A router that answers each request 100 ms later, and never a timeout in between.
    let mut now = 2000;
    let mut rounds = 0;
    while let Some(&seq) = asked.first() {
        asked.remove(0);
        now += 10;
        r.handle_radio(
            ms(now),
            ROUTER,
            &MavMessage::MISSION_ITEM_INT(items[usize::from(seq)].clone()),
        );
        asked.extend(requested(&radio_out(&mut r)));
        rounds += 1;
        assert!(rounds <= 100, "asked again: {asked:?}");
    }
    assert_eq!(rounds, 100, "each item once");
    // Every item in, well within one retransmission timeout of the poll.
    assert!(now - 2000 <= 1000, "{now}");
    assert!(matches!(&fc_out(&mut r)[..], [MavMessage::MISSION_COUNT(c)] if c.count == 100));
}
