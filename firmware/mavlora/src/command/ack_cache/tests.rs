use crate::command::ack_tag::Epoch;
use mavlink::MavlinkVersion;

use super::*;
use crate::command::ack_tag::{CommandTag, tag_command};
use crate::command::{ACK_HOLD, Redundancy, radio_confirmation};
use crate::dialect::{COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd};
use crate::wire::{Sender, encode};

const MS: fn(u64) -> Duration = Duration::from_millis;

/// The router run of most tests.
const EPOCH: Epoch = 0x5eed;

/// A copy of a command from the radio, tagged by the router run `epoch`.
fn tagged(
    s: &mut Sender,
    msg: MavMessage,
    epoch: Epoch,
    confirmation: u8,
) -> (OwnedFrame, MavMessage) {
    let tag = CommandTag {
        epoch,
        confirmation,
        age: Duration::ZERO,
    };
    (tag_command(&s.frame(&msg), &msg, tag), msg)
}

fn set_mode(confirmation: u8, param1: f32) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        confirmation,
        param1,
        ..Default::default()
    })
}

/// A `COMMAND_LONG` copy from the radio with its radio `confirmation`, of run [`EPOCH`].
fn command(s: &mut Sender, confirmation: u8, param1: f32) -> (OwnedFrame, MavMessage) {
    tagged(s, set_mode(confirmation, param1), EPOCH, confirmation)
}

fn ack(fc: &mut Sender) -> (OwnedFrame, MavMessage) {
    let msg = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        result: MavResult::MAV_RESULT_ACCEPTED,
        ..Default::default()
    });
    (fc.frame(&msg), msg)
}

/// The tag of an ack on the radio and the ack as the autopilot sent it.
fn untagged(f: &OwnedFrame) -> (AckTag, Vec<u8>) {
    let Ok(MavMessage::COMMAND_ACK(a)) = f.decode::<MavMessage>() else {
        panic!("not an ack");
    };
    let (tag, plain, _) = crate::command::ack_tag::untag_ack(f, &a).expect("tagged");
    (tag, plain.as_bytes().to_vec())
}

fn forwarded_confirmation(v: CacheVerdict) -> u8 {
    match v {
        CacheVerdict::Forward(f) => match f.decode::<MavMessage>() {
            Ok(MavMessage::COMMAND_LONG(c)) => c.confirmation,
            other => panic!("{other:?}"),
        },
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_copy_is_dropped_in_flight_and_answered_after_the_ack() {
    let mut c = AckCache::new(ACK_HOLD, Instant::ZERO);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let t0 = Instant::from_millis(60_000);
    let (f, m) = command(&mut gcs, 0, 4.0);
    assert_eq!(forwarded_confirmation(c.command(&f, &m, t0)), 0);
    // a retry (confirmation + 1) while the FC executes it
    let (f2, m2) = command(&mut gcs, 1, 4.0);
    assert_eq!(c.command(&f2, &m2, t0 + MS(300)), CacheVerdict::Drop);
    let (af, am) = ack(&mut fc);
    let radio = c
        .ack(t0, 1, 1, &af, &am)
        .expect("answers a command from the radio");
    // the ack was lost on the radio: the next copy gets it again, not a second execution
    match c.command(&f2, &m2, t0 + MS(1200)) {
        CacheVerdict::Replay(a) => {
            // the autopilot's ack again, naming the copy it answers
            assert_eq!(untagged(&a).1, untagged(&radio).1);
            assert_eq!(untagged(&radio).0, AckTag::new(EPOCH, 0, Some(0)));
            assert_eq!(untagged(&a).0, AckTag::new(EPOCH, 0, Some(1)));
        }
        other => panic!("{other:?}"),
    }
    // a different command with the same id is new
    let (f3, m3) = command(&mut gcs, 0, 5.0);
    assert_eq!(
        forwarded_confirmation(c.command(&f3, &m3, t0 + MS(1300))),
        0
    );
    assert_eq!(
        c.stats(),
        AckCacheStats {
            forwarded: 2,
            replayed: 1,
            dropped: 1,
            ..Default::default()
        }
    );
}

/// Regression: a broadcast command (target system 0) never matched the autopilot's ack, so
/// each copy the router resent went to the autopilot and ran again.
#[test]
fn a_broadcast_command_s_copy_is_answered_from_the_cache_not_run_again() {
    let mut c = AckCache::new(ACK_HOLD, Instant::ZERO);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let broadcast = |confirmation: u8, gcs: &mut Sender| {
        let msg = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 0,
            target_component: 0,
            command: MavCmd::MAV_CMD_DO_SET_MODE,
            confirmation,
            param1: 4.0,
            ..Default::default()
        });
        tagged(gcs, msg, EPOCH, confirmation)
    };
    let t0 = Instant::from_millis(60_000);
    let (f, m) = broadcast(0, &mut gcs);
    assert_eq!(forwarded_confirmation(c.command(&f, &m, t0)), 0);
    let (af, am) = ack(&mut fc);
    c.ack(t0 + MS(100), 1, 1, &af, &am)
        .expect("the autopilot's ack answers the broadcast");
    // The router's copy after its ack was lost: answered again, not run a second time.
    let (f2, m2) = broadcast(1, &mut gcs);
    assert!(
        matches!(c.command(&f2, &m2, t0 + MS(1200)), CacheVerdict::Replay(_)),
        "a copy of an acked broadcast is answered from the cache"
    );
}

#[test]
fn a_late_copy_within_the_router_window_is_not_run_again() {
    // the camera trigger ran, its acks were lost for 7 s: a copy at 7.1 s is answered
    let mut c = AckCache::new(ACK_HOLD, Instant::ZERO);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let t0 = Instant::from_millis(60_000);
    let (f, m) = command(&mut gcs, radio_confirmation(0, 0), 1.0);
    c.command(&f, &m, t0);
    let (af, am) = ack(&mut fc);
    c.ack(t0, 1, 1, &af, &am);
    let (late, late_m) = command(&mut gcs, radio_confirmation(0, 7), 1.0);
    assert!(matches!(
        c.command(&late, &late_m, t0 + MS(7100)),
        CacheVerdict::Replay(_)
    ));
    assert!(matches!(
        c.command(&late, &late_m, t0 + ACK_HOLD - MS(1)),
        CacheVerdict::Replay(_)
    ));
}

#[test]
fn a_deliberate_repeat_runs_again_even_if_its_first_copy_was_lost() {
    let mut c = AckCache::new(ACK_HOLD, Instant::ZERO);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let t0 = Instant::from_millis(60_000);
    let (f, m) = command(&mut gcs, radio_confirmation(0, 0), 1.0);
    c.command(&f, &m, t0);
    let (af, am) = ack(&mut fc);
    c.ack(t0, 1, 1, &af, &am);
    // the second trigger, 2.5 s later: its first copy arrives
    let (f2, m2) = command(&mut gcs, radio_confirmation(1, 0), 1.0);
    assert_eq!(
        forwarded_confirmation(c.command(&f2, &m2, t0 + MS(2500))),
        0
    );
    c.ack(t0, 1, 1, &af, &am);
    // a third: only its second copy arrives; still a new command here
    let (f3, m3) = command(&mut gcs, radio_confirmation(2, 1), 1.0);
    assert_eq!(
        forwarded_confirmation(c.command(&f3, &m3, t0 + MS(5000))),
        0
    );
    assert_eq!(c.stats().forwarded, 3);
}

#[test]
fn cached_acks_expire_after_the_hold() {
    let mut c = AckCache::new(MS(5000), Instant::ZERO);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let t0 = Instant::from_millis(60_000);
    let (f, m) = command(&mut gcs, 0, 4.0);
    c.command(&f, &m, t0);
    let (af, am) = ack(&mut fc);
    c.ack(t0, 1, 1, &af, &am);
    let (f2, m2) = command(&mut gcs, 1, 4.0);
    // after the hold a copy is unknown: forwarded (the router never sends one that late)
    assert_eq!(
        forwarded_confirmation(c.command(&f2, &m2, t0 + MS(6000))),
        0
    );
    // and never again while the FC has it
    assert_eq!(c.command(&f2, &m2, t0 + MS(7100)), CacheVerdict::Drop);
}

#[test]
fn acks_on_the_radio_name_the_generation_they_answer() {
    use crate::command::ack_tag::untag_ack;
    let mut c = AckCache::new(ACK_HOLD, Instant::ZERO);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let t0 = Instant::from_millis(60_000);
    let (af, am) = ack(&mut fc);
    // an ack that answers nothing from the radio goes as the autopilot sent it
    assert!(c.ack(t0, 1, 1, &af, &am).is_none());
    for (k, generation) in [0u8, 1, 31].into_iter().enumerate() {
        let (f, m) = command(&mut gcs, radio_confirmation(generation, 0), 1.0);
        c.command(&f, &m, t0 + MS(3000 * k as u64));
        let radio = c.ack(t0, 1, 1, &af, &am).expect("tagged");
        let MavMessage::COMMAND_ACK(a) = radio.decode::<MavMessage>().unwrap() else {
            panic!()
        };
        let (tag, plain, _) = untag_ack(&radio, &a).expect("tag");
        assert_eq!(tag, AckTag::new(EPOCH, generation, Some(0)));
        assert_eq!(plain.as_bytes(), af.as_bytes());
    }
}

/// A cache with SiK 64k's redundancy, its link at `loss` since `now`.
fn redundant(now: Instant, loss: Option<f64>) -> AckCache {
    let mut c = AckCache::new(ACK_HOLD, Instant::ZERO).with_redundancy(Redundancy::SIK_64K);
    c.set_link_loss(now, loss);
    c
}

fn repeats(c: &mut AckCache, now: Instant) -> Vec<OwnedFrame> {
    std::iter::from_fn(|| c.poll_repeat(now)).collect()
}

#[test]
fn on_a_lossy_link_an_ack_goes_again_half_a_round_later_naming_no_copy() {
    let t0 = Instant::from_millis(60_000);
    let mut c = redundant(t0, Some(0.1));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let (f, m) = command(&mut gcs, radio_confirmation(4, 0), 1.0);
    c.command(&f, &m, t0);
    let (af, am) = ack(&mut fc);
    let first = c.ack(t0 + MS(10), 1, 1, &af, &am).expect("tagged");
    assert_eq!(untagged(&first).0, AckTag::new(EPOCH, 4, Some(0)));
    assert_eq!(c.poll_timeout(), Some(t0 + MS(135)));
    assert!(repeats(&mut c, t0 + MS(134)).is_empty());
    let again = repeats(&mut c, t0 + MS(135));
    assert_eq!(again.len(), 1, "once");
    assert_eq!(
        untagged(&again[0]),
        (AckTag::new(EPOCH, 4, None), untagged(&first).1)
    );
    assert!(repeats(&mut c, t0 + MS(5000)).is_empty());
    assert_eq!(c.poll_timeout(), None);
    assert_eq!(c.stats().repeated, 1);
}

#[test]
fn a_copy_before_the_repeat_is_answered_by_it_and_one_after_gets_its_own_answer() {
    let t0 = Instant::from_millis(60_000);
    let mut c = redundant(t0, Some(0.1));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let (f, m) = command(&mut gcs, radio_confirmation(0, 0), 1.0);
    c.command(&f, &m, t0);
    let (af, am) = ack(&mut fc);
    c.ack(t0, 1, 1, &af, &am);
    // the router's second copy, 40 ms on: the ack would share the first's air packet
    let (f1, m1) = command(&mut gcs, radio_confirmation(0, 1), 1.0);
    assert_eq!(c.command(&f1, &m1, t0 + MS(40)), CacheVerdict::Drop);
    assert_eq!(repeats(&mut c, t0 + MS(125)).len(), 1);
    // its third copy, a round on: answered, naming that copy, and repeated in turn
    let (f2, m2) = command(&mut gcs, radio_confirmation(0, 2), 1.0);
    match c.command(&f2, &m2, t0 + MS(250)) {
        CacheVerdict::Replay(a) => assert_eq!(untagged(&a).0, AckTag::new(EPOCH, 0, Some(2))),
        other => panic!("{other:?}"),
    }
    assert_eq!(c.poll_timeout(), Some(t0 + MS(375)));
    assert_eq!(
        untagged(&repeats(&mut c, t0 + MS(375))[0]).0,
        AckTag::new(EPOCH, 0, None)
    );
    let s = c.stats();
    assert_eq!(
        (s.forwarded, s.replayed, s.covered, s.repeated),
        (1, 1, 1, 2)
    );
}

#[test]
fn a_copy_after_an_overdue_repeat_is_answered_in_its_place() {
    let t0 = Instant::from_millis(60_000);
    let mut c = redundant(t0, None);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let (f, m) = command(&mut gcs, radio_confirmation(0, 0), 1.0);
    c.command(&f, &m, t0);
    let (af, am) = ack(&mut fc);
    c.ack(t0, 1, 1, &af, &am);
    let (f1, m1) = command(&mut gcs, radio_confirmation(0, 1), 1.0);
    assert!(matches!(
        c.command(&f1, &m1, t0 + MS(200)),
        CacheVerdict::Replay(_)
    ));
    assert!(
        repeats(&mut c, t0 + MS(200)).is_empty(),
        "the answer took its place"
    );
    assert_eq!(repeats(&mut c, t0 + MS(325)).len(), 1, "the answer's own");
}

#[test]
fn untagged_and_in_progress_acks_are_not_repeated() {
    let t0 = Instant::from_millis(60_000);
    let mut c = redundant(t0, Some(0.3));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    // a command without the router's tag (an older router): forwarded uncached, its ack
    // goes as the autopilot sent it (a repeat could answer the next one)
    let int = MavMessage::COMMAND_INT(crate::dialect::COMMAND_INT_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        ..Default::default()
    });
    let f = gcs.frame(&int);
    assert_eq!(c.command(&f, &int, t0), CacheVerdict::Forward(f));
    let (af, am) = ack(&mut fc);
    assert!(c.ack(t0, 1, 1, &af, &am).is_none(), "untagged");
    assert_eq!(c.poll_timeout(), None);
    // IN_PROGRESS: only the final ack is repeated
    let (f, m) = command(&mut gcs, radio_confirmation(0, 0), 2.0);
    c.command(&f, &m, t0 + MS(10));
    let busy = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        result: MavResult::MAV_RESULT_IN_PROGRESS,
        ..Default::default()
    });
    c.ack(t0 + MS(20), 1, 1, &fc.frame(&busy), &busy)
        .expect("tagged");
    assert_eq!(c.poll_timeout(), None);
    c.ack(t0 + MS(900), 1, 1, &af, &am).expect("tagged");
    assert_eq!(c.poll_timeout(), Some(t0 + MS(1025)));
}

#[test]
fn on_a_link_measured_clean_for_30_s_an_ack_goes_once() {
    let mut c = redundant(Instant::ZERO, Some(0.0));
    let t0 = Instant::from_millis(30_000);
    c.set_link_loss(t0, Some(0.01));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let (f, m) = command(&mut gcs, radio_confirmation(0, 0), 1.0);
    c.command(&f, &m, t0);
    let (af, am) = ack(&mut fc);
    c.ack(t0, 1, 1, &af, &am).expect("tagged");
    assert_eq!(c.poll_timeout(), None);
    // a copy is answered at once, still once
    let (f1, m1) = command(&mut gcs, radio_confirmation(0, 1), 1.0);
    assert!(matches!(
        c.command(&f1, &m1, t0 + MS(40)),
        CacheVerdict::Replay(_)
    ));
    assert_eq!(c.poll_timeout(), None);
}

#[test]
fn a_copy_is_never_forwarded_again_while_the_autopilot_takes_2_5_s_to_ack() {
    // a camera that acks after 2.5 s: every copy meanwhile is dropped, not run again
    let mut c = AckCache::new(ACK_HOLD, Instant::ZERO);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let t0 = Instant::from_millis(60_000);
    let (f, m) = command(&mut gcs, radio_confirmation(0, 0), 1.0);
    assert_eq!(forwarded_confirmation(c.command(&f, &m, t0)), 0);
    for (k, at) in [300u64, 1200, 1500, 2400].into_iter().enumerate() {
        let (fk, mk) = command(&mut gcs, radio_confirmation(0, k as u32 + 1), 1.0);
        assert_eq!(
            c.command(&fk, &mk, t0 + MS(at)),
            CacheVerdict::Drop,
            "{at} ms"
        );
    }
    let (af, am) = ack(&mut fc);
    c.ack(t0 + MS(2500), 1, 1, &af, &am).expect("tagged");
    let (f5, m5) = command(&mut gcs, radio_confirmation(0, 5), 1.0);
    assert!(matches!(
        c.command(&f5, &m5, t0 + MS(2700)),
        CacheVerdict::Replay(_)
    ));
    assert_eq!(c.stats().forwarded, 1);
}

#[test]
fn a_new_router_run_s_copy_is_not_answered_with_the_previous_run_s_ack() {
    // ARM ran for one router run (generation 0); the router restarted, and its new run's
    // ARM, again generation 0, arrives as a second copy (the first was lost)
    let mut c = AckCache::new(ACK_HOLD, Instant::ZERO);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let t0 = Instant::from_millis(60_000);
    let (f, m) = tagged(&mut gcs, set_mode(0, 1.0), 1, radio_confirmation(0, 0));
    assert_eq!(forwarded_confirmation(c.command(&f, &m, t0)), 0);
    let (af, am) = ack(&mut fc);
    c.ack(t0 + MS(10), 1, 1, &af, &am).expect("tagged");
    let (f2, m2) = tagged(&mut gcs, set_mode(1, 1.0), 2, radio_confirmation(0, 1));
    assert_eq!(
        forwarded_confirmation(c.command(&f2, &m2, t0 + MS(3000))),
        0
    );
    // its ack names the new run
    let radio = c.ack(t0 + MS(3010), 1, 1, &af, &am).expect("tagged");
    assert_eq!(untagged(&radio).0, AckTag::new(2, 0, Some(1)));
    // a late copy of the previous run's is still answered from the cache, as that run's
    let (f3, m3) = tagged(&mut gcs, set_mode(2, 1.0), 1, radio_confirmation(0, 2));
    match c.command(&f3, &m3, t0 + MS(3100)) {
        CacheVerdict::Replay(a) => assert_eq!(untagged(&a).0, AckTag::new(1, 0, Some(2))),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_copy_of_a_command_that_may_have_come_before_the_bridge_started_is_not_forwarded() {
    // the bridge restarted at 60 s; the router's copies tell how long after their
    // command's first copy they went
    let started = Instant::from_millis(60_000);
    let mut c = AckCache::new(ACK_HOLD, started);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let copy = |gcs: &mut Sender, generation, attempt, age| {
        let msg = set_mode(radio_confirmation(generation, attempt), 1.0);
        let tag = CommandTag {
            epoch: EPOCH,
            confirmation: radio_confirmation(generation, attempt),
            age: MS(age),
        };
        (tag_command(&gcs.frame(&msg), &msg, tag), msg)
    };
    // its first copy went 1 s before this one, 0.9 s before the bridge started: it may
    // have run, its ack lost; neither this copy nor a later one goes
    let (f, m) = copy(&mut gcs, 3, 2, 1000);
    assert_eq!(c.command(&f, &m, started + MS(100)), CacheVerdict::Drop);
    let (f2, m2) = copy(&mut gcs, 3, 3, 2500);
    assert_eq!(c.command(&f2, &m2, started + MS(1600)), CacheVerdict::Drop);
    assert_eq!(c.stats().refused_after_restart, 1);
    assert_eq!(c.stats().forwarded, 0);
    // the autopilot's ack for that id (of its earlier run) is not taken for it
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let (af, am) = ack(&mut fc);
    assert!(c.ack(started + MS(1700), 1, 1, &af, &am).is_none());
    // a first copy is new, whenever it comes
    let (f3, m3) = copy(&mut gcs, 4, 0, 0);
    assert_eq!(
        forwarded_confirmation(c.command(&f3, &m3, started + MS(200))),
        0
    );
    // a copy whose first went 1.7 s after the start (past the margin for queueing): that
    // first copy was lost, and this one goes
    let (f4, m4) = copy(&mut gcs, 5, 1, 300);
    assert_eq!(
        forwarded_confirmation(c.command(&f4, &m4, started + MS(2000))),
        0
    );
}

#[test]
fn a_command_int_of_a_new_generation_runs_and_its_ack_is_tagged() {
    let mut c = AckCache::new(ACK_HOLD, Instant::ZERO);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let t0 = Instant::from_millis(60_000);
    let int = MavMessage::COMMAND_INT(crate::dialect::COMMAND_INT_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        param1: 1.0,
        ..Default::default()
    });
    let (af, am) = ack(&mut fc);
    for (k, generation) in [0u8, 1].into_iter().enumerate() {
        let at = t0 + MS(1000 * k as u64);
        let (f, m) = tagged(
            &mut gcs,
            int.clone(),
            EPOCH,
            radio_confirmation(generation, 0),
        );
        match c.command(&f, &m, at) {
            // the autopilot gets it as the ground sent it, without the tag
            CacheVerdict::Forward(out) => {
                assert_eq!(
                    out.as_bytes(),
                    encode(f.version(), f.header(), &int).as_bytes()
                )
            }
            other => panic!("{other:?}"),
        }
        let radio = c.ack(at + MS(10), 1, 1, &af, &am).expect("tagged");
        assert_eq!(untagged(&radio).0, AckTag::new(EPOCH, generation, Some(0)));
        let (f1, m1) = tagged(
            &mut gcs,
            int.clone(),
            EPOCH,
            radio_confirmation(generation, 1),
        );
        assert!(matches!(
            c.command(&f1, &m1, at + MS(500)),
            CacheVerdict::Replay(_)
        ));
    }
    assert_eq!(c.stats().forwarded, 2);
}
