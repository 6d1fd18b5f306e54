use mavlink::MavlinkVersion;

use super::*;
use crate::command::ack_tag::untag_command;
use crate::command::split_confirmation;
use crate::dialect::{COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd};
use crate::wire::Sender;

const MS: fn(u64) -> Duration = Duration::from_millis;
const GCS: SocketAddr = SocketAddr::new(std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST), 14550);

fn command_with(s: &mut Sender, cmd: MavCmd, param1: f32, conf: u8) -> (OwnedFrame, MavMessage) {
    let msg = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: cmd,
        param1,
        confirmation: conf,
        ..Default::default()
    });
    (s.frame(&msg), msg)
}

fn command(s: &mut Sender, cmd: MavCmd) -> (OwnedFrame, MavMessage) {
    command_with(s, cmd, 0.0, 0)
}

fn ack(cmd: MavCmd) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: cmd,
        result: MavResult::MAV_RESULT_ACCEPTED,
        ..Default::default()
    })
}

/// (param1, generation, attempt) of a radio copy, from its tag.
fn sent(f: &OwnedFrame) -> (f32, u8, u8) {
    let msg = f.decode::<MavMessage>().unwrap();
    let param1 = match &msg {
        MavMessage::COMMAND_LONG(c) => c.param1,
        MavMessage::COMMAND_INT(c) => c.param1,
        other => panic!("not a command: {other:?}"),
    };
    let tag = untag_command(f, &msg).expect("tagged");
    let (g, a) = split_confirmation(tag.confirmation);
    (param1, g, a)
}

fn command_int(s: &mut Sender, cmd: MavCmd, param1: f32) -> (OwnedFrame, MavMessage) {
    let msg = MavMessage::COMMAND_INT(crate::dialect::COMMAND_INT_DATA {
        target_system: 1,
        target_component: 1,
        command: cmd,
        param1,
        ..Default::default()
    });
    (s.frame(&msg), msg)
}

/// A tag naming `generation` and no copy.
fn tag(generation: u8) -> Option<AckTag> {
    Some(AckTag::new(0, generation, None))
}

fn forwarded(a: Admission) -> OwnedFrame {
    match a {
        Admission::Forward(f) => f,
        other => panic!("{other:?}"),
    }
}

/// The frame due at `now`, if any: the timer, then the queue.
fn resend(r: &mut CommandRetransmitter, now: Instant) -> Option<OwnedFrame> {
    r.handle_timeout(now);
    r.poll_retransmit()
}

fn retransmitter() -> CommandRetransmitter {
    CommandRetransmitter::new(MS(1000), MS(200), MS(1500), 4)
}

#[test]
fn resends_until_acked_then_stops() {
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let (frame, msg) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
    let t0 = Instant::from_millis(0);
    assert_eq!(
        sent(&forwarded(r.from_ground(t0, GCS, &frame, &msg))),
        (0.0, 0, 0)
    );
    assert_eq!(r.poll_timeout(), Some(t0 + MS(1000)));
    assert!(resend(&mut r, t0 + MS(999)).is_none());
    let again = resend(&mut r, t0 + MS(1000)).expect("due");
    assert_eq!(sent(&again), (0.0, 0, 1), "a retransmission says so");
    // the ground station's own retry while we are at it goes nowhere
    let (retry, retry_msg) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 0.0, 1);
    assert_eq!(
        r.from_ground(t0 + MS(1500), GCS, &retry, &retry_msg),
        Admission::Retry
    );
    assert!(r.from_radio(t0 + MS(1600), 1, 1, &ack(MavCmd::MAV_CMD_DO_SET_MODE)));
    // a second copy's ack, replayed by the bridge, is not the next command's
    assert!(!r.from_radio(t0 + MS(1700), 1, 1, &ack(MavCmd::MAV_CMD_DO_SET_MODE)));
    assert!(resend(&mut r, t0 + MS(10_000)).is_none());
    let s = r.stats();
    assert_eq!(
        (
            s.commands,
            s.retransmissions,
            s.ground_duplicates,
            s.acked,
            s.late_acks
        ),
        (1, 1, 1, 1, 1)
    );
    // the retransmitted command's round trip is ambiguous: no sample (Karn)
    assert_eq!(r.rtt().samples(), 0);
}

#[test]
fn timeout_follows_the_measured_round_trip() {
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut now = Instant::from_millis(0);
    for k in 0..20 {
        let (frame, msg) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, k as f32, 0);
        forwarded(r.from_ground(now, GCS, &frame, &msg));
        now += MS(150);
        r.from_radio(now, 1, 1, &ack(MavCmd::MAV_CMD_DO_SET_MODE));
        now += MS(1000);
    }
    assert!(r.rtt().rto() <= MS(300), "{:?}", r.rtt().rto());
}

#[test]
fn an_ack_from_another_vehicle_component_or_command_does_not_count() {
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let (frame, msg) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
    let t0 = Instant::from_millis(0);
    r.from_ground(t0, GCS, &frame, &msg);
    r.from_radio(t0 + MS(100), 2, 1, &ack(MavCmd::MAV_CMD_DO_SET_MODE));
    r.from_radio(t0 + MS(100), 1, 100, &ack(MavCmd::MAV_CMD_DO_SET_MODE));
    r.from_radio(t0 + MS(100), 1, 1, &ack(MavCmd::MAV_CMD_NAV_LAND));
    assert!(resend(&mut r, t0 + MS(1000)).is_some());
}

/// Regression: a command to system 0 (a broadcast) never matched its ack, which comes from
/// the vehicle's own system id: the router resent it on every timeout and the vehicle ran
/// ARM five times.
#[test]
fn a_broadcast_command_is_answered_by_the_vehicle_s_ack() {
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let msg = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 0,
        target_component: 0,
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        ..Default::default()
    });
    let frame = gcs.frame(&msg);
    let t0 = Instant::from_millis(0);
    forwarded(r.from_ground(t0, GCS, &frame, &msg));
    assert!(r.from_radio(
        t0 + MS(150),
        1,
        1,
        &ack(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM)
    ));
    assert!(
        resend(&mut r, t0 + MS(10_000)).is_none(),
        "acked: nothing goes again"
    );
    assert_eq!((r.stats().acked, r.stats().retransmissions), (1, 0));
}

#[test]
fn gives_up_after_the_last_attempt() {
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let (frame, msg) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
    r.from_ground(Instant::from_millis(0), GCS, &frame, &msg);
    let mut resent = 0;
    let mut now = Instant::from_millis(0);
    while let Some(t) = r.poll_timeout() {
        now = now.max(t);
        if resend(&mut r, now).is_some() {
            resent += 1;
        }
    }
    assert_eq!(resent, 3, "4 attempts in all");
    assert_eq!(r.stats().given_up, 1);
    // a later retry by the ground station within the window is that command again
    let (retry, retry_msg) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 0.0, 2);
    let f = forwarded(r.from_ground(now + MS(1600), GCS, &retry, &retry_msg));
    assert_eq!(sent(&f), (0.0, 0, 4));
}

#[test]
fn a_second_command_with_the_same_id_waits_for_the_first() {
    // DO_SET_MODE mode 4, then mode 5 200 ms later: both go, in order, one at a time
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let t0 = Instant::from_millis(0);
    let (f4, m4) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 4.0, 0);
    let (f5, m5) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 5.0, 0);
    assert_eq!(
        sent(&forwarded(r.from_ground(t0, GCS, &f4, &m4))),
        (4.0, 0, 0)
    );
    assert_eq!(r.from_ground(t0 + MS(200), GCS, &f5, &m5), Admission::Hold);
    // mode 4's copies continue alone
    assert_eq!(sent(&resend(&mut r, t0 + MS(1000)).unwrap()), (4.0, 0, 1));
    assert!(r.from_radio(t0 + MS(1300), 1, 1, &ack(MavCmd::MAV_CMD_DO_SET_MODE)));
    // mode 4 went twice: mode 5 waits until the second copy's ack can no longer come
    assert!(resend(&mut r, t0 + MS(1300)).is_none());
    assert!(!r.from_radio(t0 + MS(1400), 1, 1, &ack(MavCmd::MAV_CMD_DO_SET_MODE)));
    let due = r.poll_timeout().unwrap();
    assert_eq!(due, t0 + MS(2500));
    assert_eq!(sent(&resend(&mut r, due).unwrap()), (5.0, 1, 0));
    assert!(r.from_radio(due + MS(300), 1, 1, &ack(MavCmd::MAV_CMD_DO_SET_MODE)));
    assert_eq!(r.stats().acked, 2);
}

#[test]
fn an_identical_new_command_is_a_new_generation() {
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let t0 = Instant::from_millis(0);
    let (f, m) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_DIGICAM_CONTROL, 1.0, 0);
    assert_eq!(
        sent(&forwarded(r.from_ground(t0, GCS, &f, &m))),
        (1.0, 0, 0)
    );
    r.from_radio(t0 + MS(300), 1, 1, &ack(MavCmd::MAV_CMD_DO_DIGICAM_CONTROL));
    // the same trigger again, confirmation 0: a new command the bridge must run again
    let (f2, m2) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_DIGICAM_CONTROL, 1.0, 0);
    assert_eq!(
        sent(&forwarded(r.from_ground(t0 + MS(2500), GCS, &f2, &m2))),
        (1.0, 1, 0)
    );
}

#[test]
fn a_tagged_ack_lets_the_next_command_go_at_once_and_a_late_one_is_swallowed() {
    // as mode 4 then 5 above, but the bridge names the generation in its acks: mode 5
    // need not wait for mode 4's late copies' acks, and those never answer mode 5
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let t0 = Instant::from_millis(0);
    let set_mode = MavCmd::MAV_CMD_DO_SET_MODE;
    let (f4, m4) = command_with(&mut gcs, set_mode, 4.0, 0);
    let (f5, m5) = command_with(&mut gcs, set_mode, 5.0, 0);
    forwarded(r.from_ground(t0, GCS, &f4, &m4));
    assert_eq!(r.from_ground(t0 + MS(200), GCS, &f5, &m5), Admission::Hold);
    assert_eq!(sent(&resend(&mut r, t0 + MS(1000)).unwrap()), (4.0, 0, 1));
    assert!(r.from_radio_tagged(t0 + MS(1300), 1, 1, &ack(set_mode), tag(0)));
    // mode 5, another generation of the same slot, goes at once
    assert_eq!(sent(&resend(&mut r, t0 + MS(1300)).unwrap()), (5.0, 1, 0));
    // the ack of mode 4's second copy comes now: it names mode 4, not mode 5
    assert!(!r.from_radio_tagged(t0 + MS(1400), 1, 1, &ack(set_mode), tag(0)));
    assert_eq!((r.stats().acked, r.stats().late_acks), (1, 1));
    // mode 5 is resent until its own ack comes
    assert_eq!(sent(&resend(&mut r, t0 + MS(2300)).unwrap()), (5.0, 1, 1));
    assert!(r.from_radio_tagged(t0 + MS(2400), 1, 1, &ack(set_mode), tag(1)));
    assert_eq!(r.stats().acked, 2);
}

#[test]
fn a_late_ack_of_an_older_generation_is_not_the_newer_ones() {
    // the same trigger twice: the second is a new generation; the first's late ack
    // (tagged 0) arriving while the second (1) is on the radio is swallowed
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let t0 = Instant::from_millis(0);
    let cam = MavCmd::MAV_CMD_DO_DIGICAM_CONTROL;
    let (f, m) = command_with(&mut gcs, cam, 1.0, 0);
    forwarded(r.from_ground(t0, GCS, &f, &m));
    assert_eq!(sent(&resend(&mut r, t0 + MS(1000)).unwrap()), (1.0, 0, 1));
    assert!(r.from_radio_tagged(t0 + MS(1100), 1, 1, &ack(cam), tag(0)));
    let (f2, m2) = command_with(&mut gcs, cam, 1.0, 0);
    assert_eq!(
        sent(&forwarded(r.from_ground(t0 + MS(1200), GCS, &f2, &m2))),
        (1.0, 1, 0),
        "no wait for the first's late acks"
    );
    assert!(!r.from_radio_tagged(t0 + MS(1300), 1, 1, &ack(cam), tag(0)));
    assert_eq!(r.stats().late_acks, 1);
    // the second's copy keeps going until its own ack
    assert!(resend(&mut r, t0 + MS(2200)).is_some());
    assert!(r.from_radio_tagged(t0 + MS(2300), 1, 1, &ack(cam), tag(1)));
    assert_eq!(r.stats().acked, 2);
}

#[test]
fn an_ack_flood_of_other_generations_never_completes_a_command() {
    // hostile or broken radio peer: 1000 acks naming every other generation, and
    // untagged ones for other vehicles, while generation 0 is on the radio
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let t0 = Instant::from_millis(0);
    let set_mode = MavCmd::MAV_CMD_DO_SET_MODE;
    let (f, m) = command_with(&mut gcs, set_mode, 4.0, 0);
    forwarded(r.from_ground(t0, GCS, &f, &m));
    for k in 0..1000u32 {
        let g = 1 + (k % 31) as u8;
        r.from_radio_tagged(t0 + MS(1), 1, 1, &ack(set_mode), tag(g));
        r.from_radio_tagged(t0 + MS(1), 2 + (k % 200) as u8, 1, &ack(set_mode), None);
    }
    assert_eq!(r.stats().acked, 0);
    // still resent on its timeout, and its own ack completes it
    assert_eq!(sent(&resend(&mut r, t0 + MS(1000)).unwrap()), (4.0, 0, 1));
    assert!(r.from_radio_tagged(t0 + MS(1100), 1, 1, &ack(set_mode), tag(0)));
    assert_eq!(r.stats().acked, 1);
    assert!(resend(&mut r, t0 + MS(5000)).is_none());
}

#[test]
fn a_late_replay_of_an_acked_command_goes_as_that_command() {
    // the ground's copy (confirmation 3) of a command acked 5 s ago arrives: it goes on
    // the radio as the same generation with attempt > 0, so the bridge answers it from
    // its cache instead of running it again
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let t0 = Instant::from_millis(0);
    let cam = MavCmd::MAV_CMD_DO_DIGICAM_CONTROL;
    let (f, m) = command_with(&mut gcs, cam, 1.0, 0);
    forwarded(r.from_ground(t0, GCS, &f, &m));
    assert!(r.from_radio_tagged(t0 + MS(150), 1, 1, &ack(cam), tag(0)));
    let (late, late_m) = command_with(&mut gcs, cam, 1.0, 3);
    let (_, generation, attempt) = sent(&forwarded(r.from_ground(
        t0 + MS(5000),
        GCS,
        &late,
        &late_m,
    )));
    assert_eq!(generation, 0);
    assert!(attempt > 0, "a copy, not a new command");
    // its (replayed) ack is the ground's, once; a second replay's ack is swallowed
    assert!(r.from_radio_tagged(t0 + MS(5150), 1, 1, &ack(cam), tag(0)));
    assert!(!r.from_radio_tagged(t0 + MS(5200), 1, 1, &ack(cam), tag(0)));
}

/// DO_SET_MODE 4 from the ground at 0 and copied by the router at 1.45 s (its timeout, no
/// redundant copies), no ack yet; the ground retries mode 4 at 1.5 s and sends mode 5 then,
/// before mode 4 is answered: mode 5 waits. (The retransmitter, the ground's sender.)
fn mode_4_retried_at_1_5_s_and_mode_5_waiting(t0: Instant) -> (CommandRetransmitter, Sender) {
    let mut r = CommandRetransmitter::new(MS(1450), MS(200), MS(1500), MAX_ATTEMPTS);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let set_mode = MavCmd::MAV_CMD_DO_SET_MODE;
    let (f4, m4) = command_with(&mut gcs, set_mode, 4.0, 0);
    forwarded(r.from_ground(t0, GCS, &f4, &m4));
    assert_eq!(sent(&resend(&mut r, t0 + MS(1450)).unwrap()), (4.0, 0, 1));
    let (retry, retry_m) = command_with(&mut gcs, set_mode, 4.0, 1);
    assert_eq!(
        r.from_ground(t0 + MS(1500), GCS, &retry, &retry_m),
        Admission::Retry
    );
    let (f5, m5) = command_with(&mut gcs, set_mode, 5.0, 0);
    assert_eq!(r.from_ground(t0 + MS(1500), GCS, &f5, &m5), Admission::Hold);
    (r, gcs)
}

#[test]
fn an_older_command_keeps_its_slot_while_the_ground_may_still_retry_it() {
    // The ground's next retry of mode 4 is due at 3 s, and until it is overdue the ground
    // still waits for mode 4's ack: mode 5 must not go before (1.4 s after the ground's
    // last send, when the router's last copy is older than it), or the ground takes mode
    // 5's ack for mode 4's.
    let t0 = Instant::from_millis(0);
    let (mut r, mut gcs) = mode_4_retried_at_1_5_s_and_mode_5_waiting(t0);
    let set_mode = MavCmd::MAV_CMD_DO_SET_MODE;
    for ms in (1510..3000).step_by(10) {
        if let Some(f) = resend(&mut r, t0 + MS(ms)) {
            assert_eq!(sent(&f).0, 4.0, "at {ms} ms");
        }
    }
    let (retry, retry_m) = command_with(&mut gcs, set_mode, 4.0, 2);
    assert_eq!(
        r.from_ground(t0 + MS(3000), GCS, &retry, &retry_m),
        Admission::Retry,
        "mode 4 is still on the radio"
    );
    assert!(r.from_radio_tagged(t0 + MS(3100), 1, 1, &ack(set_mode), tag(0)));
    assert_eq!(sent(&resend(&mut r, t0 + MS(3100)).unwrap()), (5.0, 1, 0));
    assert_eq!((r.stats().acked, r.stats().abandoned), (1, 0));
}

#[test]
fn an_ack_the_ground_may_have_given_up_on_is_swallowed_but_its_retry_is_answered() {
    // Mode 4's ack comes 1.4 s after the ground's retry: a station giving up on mode 4
    // would take it for mode 5's, so it is swallowed. But the ground may retry mode 4
    // instead (due at 3 s): mode 5 waits, and the retry goes as mode 4 again (the bridge
    // answers it from its cache) and gets mode 4's ack.
    let t0 = Instant::from_millis(0);
    let (mut r, mut gcs) = mode_4_retried_at_1_5_s_and_mode_5_waiting(t0);
    let set_mode = MavCmd::MAV_CMD_DO_SET_MODE;
    assert!(!r.from_radio_tagged(t0 + MS(2900), 1, 1, &ack(set_mode), tag(0)));
    for ms in (2900..3000).step_by(10) {
        assert!(resend(&mut r, t0 + MS(ms)).is_none(), "at {ms} ms");
    }
    let (retry, retry_m) = command_with(&mut gcs, set_mode, 4.0, 2);
    let (param1, generation, attempt) = sent(&forwarded(r.from_ground(
        t0 + MS(3000),
        GCS,
        &retry,
        &retry_m,
    )));
    assert_eq!((param1, generation), (4.0, 0));
    assert!(attempt > 0, "a copy, not a new command");
    assert!(r.from_radio_tagged(t0 + MS(3100), 1, 1, &ack(set_mode), tag(0)));
    assert_eq!(sent(&resend(&mut r, t0 + MS(3100)).unwrap()), (5.0, 1, 0));
}

/// A retransmitter with SiK 64k's redundant copies, its link at `loss` from `now`.
fn redundant(now: Instant, loss: Option<f64>) -> CommandRetransmitter {
    let mut r = CommandRetransmitter::new(MS(1000), MS(200), MS(1500), MAX_ATTEMPTS)
        .with_redundancy(Redundancy::SIK_64K);
    r.set_link_loss(now, loss);
    r
}

/// (ms, attempt) of every command sent from `from` to `until` ms, polling every ms.
fn sends(r: &mut CommandRetransmitter, from: u64, until: u64) -> Vec<(u64, u8)> {
    (from..=until)
        .filter_map(|t| resend(r, Instant::from_millis(t)).map(|f| (t, sent(&f).2)))
        .collect()
}

#[test]
fn on_a_lossy_link_a_command_goes_in_separate_packets_of_the_first_two_rounds() {
    // SiK 64k at 10 % loss: a second copy past one air packet (40 ms), a third half a
    // round on (125 ms), a fourth a round on (250 ms); then the timeout from the last
    let t0 = Instant::from_millis(0);
    let mut r = redundant(t0, Some(0.1));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let (f, m) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
    assert_eq!(sent(&forwarded(r.from_ground(t0, GCS, &f, &m))).2, 0);
    assert_eq!(sends(&mut r, 0, 1249), vec![(40, 1), (125, 2), (250, 3)]);
    assert_eq!(
        r.poll_timeout(),
        Some(t0 + MS(1250)),
        "initial 1 s after the last"
    );
    assert_eq!(sends(&mut r, 1250, 1250), vec![(1250, 4)]);
    let s = r.stats();
    assert_eq!((s.redundant, s.early_copies, s.retransmissions), (1, 3, 1));
}

#[test]
fn on_a_slow_radio_the_copies_wait_half_a_round() {
    // 250 B/s (LoRa SF7's budget) carries the 45-byte command in 180 ms, more than the
    // 40 ms pair gap: no second copy in the first round
    let t0 = Instant::from_millis(0);
    let mut r = redundant(t0, Some(0.1)).with_budget(250);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let (f, m) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
    forwarded(r.from_ground(t0, GCS, &f, &m));
    assert_eq!(sends(&mut r, 0, 1000), vec![(125, 1), (250, 2)]);
    // SiK 64k's ~3 kB/s carries it in 15 ms: the pair goes
    let mut r = redundant(t0, Some(0.1)).with_budget(3000);
    forwarded(r.from_ground(t0, GCS, &f, &m));
    assert_eq!(sends(&mut r, 0, 1000), vec![(40, 1), (125, 2), (250, 3)]);
}

#[test]
fn the_ack_ends_the_copies_still_planned() {
    let t0 = Instant::from_millis(0);
    let mut r = redundant(t0, Some(0.1));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let (f, m) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
    forwarded(r.from_ground(t0, GCS, &f, &m));
    assert_eq!(sends(&mut r, 0, 100), vec![(40, 1)]);
    let ack = ack(MavCmd::MAV_CMD_DO_SET_MODE);
    assert!(r.from_radio_tagged(t0 + MS(101), 1, 1, &ack, Some(AckTag::new(0, 0, Some(0)))));
    assert!(sends(&mut r, 101, 5000).is_empty());
    assert_eq!(r.poll_timeout(), None);
}

#[test]
fn in_progress_ends_the_copies_still_planned() {
    let t0 = Instant::from_millis(0);
    let mut r = redundant(t0, Some(0.1));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let (f, m) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
    forwarded(r.from_ground(t0, GCS, &f, &m));
    let busy = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        result: MavResult::MAV_RESULT_IN_PROGRESS,
        ..Default::default()
    });
    assert!(r.from_radio_tagged(t0 + MS(20), 1, 1, &busy, tag(0)));
    assert!(sends(&mut r, 20, 5000).is_empty(), "the vehicle has it");
}

#[test]
fn a_link_measured_clean_for_30_s_gets_one_copy_and_a_lossy_reading_starts_over() {
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut r = redundant(Instant::from_millis(0), Some(0.0));
    // clean for 29.9 s only: still redundant
    let t1 = Instant::from_millis(29_900);
    r.set_link_loss(t1, Some(0.01));
    let set_mode = ack(MavCmd::MAV_CMD_DO_SET_MODE);
    let (f, m) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 1.0, 0);
    let g = sent(&forwarded(r.from_ground(t1, GCS, &f, &m))).1;
    assert_eq!(sends(&mut r, 29_900, 29_950).len(), 1, "its second copy");
    assert!(r.from_radio_tagged(t1 + MS(60), 1, 1, &set_mode, tag(g)));
    // clean for 30 s: one copy, then the timeout
    let t2 = Instant::from_millis(30_000);
    r.set_link_loss(t2, Some(0.0));
    let (f, m) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 2.0, 0);
    let g = sent(&forwarded(r.from_ground(t2, GCS, &f, &m))).1;
    assert_eq!(r.poll_timeout(), Some(t2 + r.rtt().rto()));
    assert!(sends(&mut r, 30_000, 30_000 + 900).is_empty());
    assert!(r.from_radio_tagged(t2 + MS(901), 1, 1, &set_mode, tag(g)));
    // one reading at 2 %, or none, and it starts over
    for (k, reading) in [Some(0.02), None].into_iter().enumerate() {
        let t3 = 70_000 + 40_000 * k as u64;
        r.set_link_loss(Instant::from_millis(t3 - 40_000), Some(0.0));
        r.set_link_loss(Instant::from_millis(t3), reading);
        let (f, m) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 3.0 + k as f32, 0);
        let g = sent(&forwarded(r.from_ground(
            Instant::from_millis(t3),
            GCS,
            &f,
            &m,
        )))
        .1;
        assert_eq!(
            sends(&mut r, t3, t3 + 40),
            vec![(t3 + 40, 1)],
            "{reading:?}"
        );
        let done = Instant::from_millis(t3 + 41);
        assert!(r.from_radio_tagged(done, 1, 1, &set_mode, tag(g)));
    }
    assert_eq!(r.stats().redundant, 3);
}

#[test]
fn the_round_trip_is_measured_from_the_copy_the_ack_names() {
    // copies at 0, 40 and 125 ms; the vehicle got the third and its ack comes 131 ms
    // after it: a sample of 131 ms, not 256 ms from the first copy
    let t0 = Instant::from_millis(0);
    let mut r = redundant(t0, Some(0.1));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let (f, m) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 1.0, 0);
    forwarded(r.from_ground(t0, GCS, &f, &m));
    sends(&mut r, 0, 200);
    let set_mode = ack(MavCmd::MAV_CMD_DO_SET_MODE);
    assert!(r.from_radio_tagged(
        t0 + MS(256),
        1,
        1,
        &set_mode,
        Some(AckTag::new(0, 0, Some(2)))
    ));
    assert_eq!(r.rtt().srtt(), Some(MS(131)));
    // the bridge's repeat names no copy, an untagged ack after several copies is
    // ambiguous (Karn): neither is a sample
    for (k, t) in [tag(1), None].into_iter().enumerate() {
        let (f, m) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 2.0 + k as f32, 0);
        let start = t0 + MS(10_000 * (k as u64 + 1));
        forwarded(r.from_ground(start, GCS, &f, &m));
        sends(&mut r, start.as_millis(), start.as_millis() + 200);
        assert!(r.from_radio_tagged(start + MS(400), 1, 1, &set_mode, t));
    }
    assert_eq!(r.rtt().samples(), 1);
    assert_eq!(r.stats().rtt_samples, 1);
}

#[test]
fn no_resend_comes_sooner_than_the_spacing_after_the_last_copy() {
    // a round trip measured at 20 ms (a timeout floor of 10 ms): a resend sooner than
    // half a TDM round after the last copy would share its air packet
    let mut r = CommandRetransmitter::new(MS(1000), MS(10), MS(1500), 8)
        .with_redundancy(Redundancy::SIK_64K);
    r.set_link_loss(Instant::ZERO, Some(0.0));
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let set_mode = ack(MavCmd::MAV_CMD_DO_SET_MODE);
    let mut now = Instant::from_millis(40_000);
    r.set_link_loss(now, Some(0.0));
    for k in 0..20 {
        let (f, m) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, k as f32, 0);
        forwarded(r.from_ground(now, GCS, &f, &m));
        now += MS(20);
        assert!(r.from_radio(now, 1, 1, &set_mode));
        now += MS(1000);
    }
    assert!(r.rtt().rto() < MS(125), "{:?}", r.rtt().rto());
    let (f, m) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 99.0, 0);
    forwarded(r.from_ground(now, GCS, &f, &m));
    assert_eq!(r.poll_timeout(), Some(now + MS(125)));
}

#[test]
fn each_copy_carries_the_run_s_epoch_and_a_command_long_its_radio_confirmation() {
    let t0 = Instant::from_millis(0);
    let mut r = retransmitter().with_epoch(0xabcd, t0);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let (f, m) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 4.0, 0);
    let first = forwarded(r.from_ground(t0, GCS, &f, &m));
    let again = resend(&mut r, t0 + MS(1000)).expect("due");
    for (copy, attempt) in [(first, 0), (again, 1)] {
        let msg = copy.decode::<MavMessage>().unwrap();
        let tag = untag_command(&copy, &msg).expect("tagged");
        assert_eq!(tag.epoch, 0xabcd);
        assert_eq!(split_confirmation(tag.confirmation), (0, attempt));
        let MavMessage::COMMAND_LONG(c) = msg else {
            panic!()
        };
        assert_eq!(c.confirmation, tag.confirmation);
    }
}

#[test]
fn an_identical_command_int_after_its_ack_is_a_new_command_and_before_it_a_retry() {
    // ARM, DISARM, ARM as COMMAND_INT: no confirmation says which is a retry; a ground
    // station retries only while it has no ack
    let mut r = retransmitter();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let arm = MavCmd::MAV_CMD_COMPONENT_ARM_DISARM;
    let t0 = Instant::from_millis(0);
    let (f, m) = command_int(&mut gcs, arm, 1.0);
    assert_eq!(
        sent(&forwarded(r.from_ground(t0, GCS, &f, &m))),
        (1.0, 0, 0)
    );
    // the ground's retry before the ack: the relay is at it already
    assert_eq!(r.from_ground(t0 + MS(500), GCS, &f, &m), Admission::Retry);
    assert!(r.from_radio_tagged(t0 + MS(600), 1, 1, &ack(arm), tag(0)));
    let (f2, m2) = command_int(&mut gcs, arm, 0.0);
    assert_eq!(
        sent(&forwarded(r.from_ground(t0 + MS(1000), GCS, &f2, &m2))),
        (0.0, 1, 0)
    );
    assert!(r.from_radio_tagged(t0 + MS(1300), 1, 1, &ack(arm), tag(1)));
    // ARM again: answered, so a new command, with a generation of its own
    assert_eq!(
        sent(&forwarded(r.from_ground(t0 + MS(2000), GCS, &f, &m))),
        (1.0, 2, 0)
    );
    // and its ack, tagged, answers it (not the first ARM's)
    assert!(r.from_radio_tagged(t0 + MS(2300), 1, 1, &ack(arm), tag(2)));
    assert_eq!(r.stats().commands, 3);
    assert_eq!(r.stats().acked, 3);
}

#[test]
fn a_command_int_given_up_without_an_ack_is_sent_again_as_itself() {
    // the ground never got an ack: an identical COMMAND_INT is its retry
    let mut r = CommandRetransmitter::new(MS(1000), MS(200), MS(1500), 1);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let trigger = MavCmd::MAV_CMD_DO_DIGICAM_CONTROL;
    let t0 = Instant::from_millis(0);
    let (f, m) = command_int(&mut gcs, trigger, 1.0);
    assert_eq!(
        sent(&forwarded(r.from_ground(t0, GCS, &f, &m))),
        (1.0, 0, 0)
    );
    assert!(resend(&mut r, t0 + MS(1500)).is_none(), "given up");
    assert_eq!(
        sent(&forwarded(r.from_ground(t0 + MS(1500), GCS, &f, &m))),
        (1.0, 0, 1)
    );
}

#[test]
fn soon_after_a_restart_a_ground_retry_of_a_command_this_run_never_saw_is_not_sent() {
    let started = Instant::from_millis(100_000);
    let mut r = retransmitter().with_epoch(2, started);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let trigger = MavCmd::MAV_CMD_DO_DIGICAM_CONTROL;
    // the previous run may have had it run: not sent as a new command
    let (f, m) = command_with(&mut gcs, trigger, 1.0, 2);
    assert_eq!(
        r.from_ground(started + MS(500), GCS, &f, &m),
        Admission::Retry
    );
    assert_eq!(r.stats().refused_after_restart, 1);
    assert_eq!(r.stats().commands, 0);
    // a new one (confirmation 0) goes, and its own retries are its copies
    let (f0, m0) = command_with(&mut gcs, trigger, 1.0, 0);
    assert_eq!(
        sent(&forwarded(r.from_ground(started + MS(600), GCS, &f0, &m0))),
        (1.0, 0, 0)
    );
    // after the window a retry of an unknown command is one whose first send was lost
    let (f3, m3) = command_with(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE, 4.0, 1);
    assert!(matches!(
        r.from_ground(started + RETRANSMIT_WINDOW, GCS, &f3, &m3),
        Admission::Forward(_)
    ));
}

#[test]
fn an_ack_tagged_by_another_run_answers_nothing() {
    // the bridge repeats an ack of the previous run's generation 0 after a restart: this
    // run's generation 0 is another command
    let t0 = Instant::from_millis(0);
    let mut r = retransmitter().with_epoch(2, t0);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let arm = MavCmd::MAV_CMD_COMPONENT_ARM_DISARM;
    let (f, m) = command_with(&mut gcs, arm, 1.0, 0);
    forwarded(r.from_ground(t0, GCS, &f, &m));
    let old = Some(AckTag::new(1, 0, None));
    assert!(!r.from_radio_tagged(t0 + MS(100), 1, 1, &ack(arm), old));
    assert_eq!(r.stats().foreign_acks, 1);
    assert_eq!(r.stats().acked, 0);
    assert!(r.from_radio_tagged(t0 + MS(300), 1, 1, &ack(arm), Some(AckTag::new(2, 0, None))));
    assert_eq!(r.stats().acked, 1);
}
