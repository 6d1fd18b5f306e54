//! The command relay end to end on a virtual clock: a ground station that follows the MAVLink
//! command protocol (confirmation 0 first, +1 on each retry every 1.5 s, 5 tries), the router
//! and bridge engines joined by a lossy radio with ack-loss bursts, and an autopilot that
//! records every command it executes and acknowledges each with a result that tells which
//! execution it answers (its n-th execution of a command id answers with result n mod 5).
//!
//! Properties: each command the ground sends reaches the autopilot exactly once, in order,
//! even when it repeats an earlier one with identical parameters; every ack the ground
//! sees answers the command it is waiting on. Both hold with the redundant copies of a
//! lossy link (the router's extra copies of each command, the bridge's repeat of each ack)
//! off, as configured by default, or forced on with gaps drawn against the link's latency,
//! so that copies, repeats and the next command cross on the way.

use mavlora::Duration;
use std::collections::{HashMap, VecDeque};

use mavlink::MavlinkVersion;
use proptest::prelude::*;

use mavlora::Instant;
use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::command::Redundancy;
use mavlora::dialect::{
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, HEARTBEAT_DATA, MavCmd, MavMessage, MavResult,
};
use mavlora::filter::Profile;
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::SchedulerConfig;
use mavlora::wire::{FrameReader, OwnedFrame, Sender};

/// What the autopilot answers, by execution of a command id: its n-th execution answers
/// `RESULTS[n]` (plans hold at most 10 commands), so the ground can tell which execution an
/// ack comes from.
const RESULTS: [MavResult; 10] = [
    MavResult::MAV_RESULT_ACCEPTED,
    MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
    MavResult::MAV_RESULT_DENIED,
    MavResult::MAV_RESULT_UNSUPPORTED,
    MavResult::MAV_RESULT_FAILED,
    MavResult::MAV_RESULT_CANCELLED,
    MavResult::MAV_RESULT_COMMAND_LONG_ONLY,
    MavResult::MAV_RESULT_COMMAND_INT_ONLY,
    MavResult::MAV_RESULT_COMMAND_UNSUPPORTED_MAV_FRAME,
    MavResult::MAV_RESULT_NOT_IN_CONTROL,
];
const IDS: [MavCmd; 2] = [
    MavCmd::MAV_CMD_DO_SET_MODE,
    MavCmd::MAV_CMD_DO_DIGICAM_CONTROL,
];

/// The `result_param2` of the autopilot's n-th execution of a command id (negative and
/// positive: the relay's tag must give back both).
fn result_param2(n: usize) -> i32 {
    if n.is_multiple_of(2) {
        n as i32 * 1000
    } else {
        -(n as i32)
    }
}

/// One command the ground sends: which id, which parameter, when (ms after the previous one
/// of the same id was answered or given up; `eager`: ms after the previous one was sent,
/// without waiting for its ack, as DO_SET_MODE 4 then 5 200 ms later).
#[derive(Debug, Clone, Copy)]
struct Planned {
    id: usize,
    param: u8,
    gap_ms: u64,
    eager: bool,
}

fn budget() -> SchedulerConfig {
    SchedulerConfig {
        rate_bytes_per_s: 2000,
        burst_bytes: 600,
        max_queued_bytes: 8000,
    }
}

/// A tiny deterministic generator for the link's loss.
struct Rng(u64);

impl Rng {
    fn chance(&mut self, p: f64) -> bool {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 / ((1u64 << 53) as f64)) < p
    }
}

struct Outstanding {
    rank: usize,
    msg: COMMAND_LONG_DATA,
    tries: u8,
    next_try: Instant,
}

#[derive(Debug, Default)]
struct Outcome {
    /// Per command id: the parameters the autopilot executed, in order.
    executed: HashMap<u16, Vec<u8>>,
    /// Per command id: the parameters the ground sent (each a distinct command), in order.
    sent: HashMap<u16, Vec<u8>>,
    /// Acks the ground took for a command they do not answer.
    misattributed: Vec<String>,
    acked: usize,
    /// Acks that came when the ground waited for nothing with that id.
    stray_acks: usize,
    /// Per command id: commands the ground gave up on (no ack after 5 tries).
    gave_up: HashMap<u16, usize>,
}

/// How the relay's redundant copies are set up for a run.
#[derive(Debug, Clone, Copy)]
enum Copies {
    /// The defaults (on until the link is measured clean).
    Default,
    /// None: only timeouts and the ground's retries resend.
    Off,
    /// Always on (no loss is low enough), with these gaps.
    Forced(Redundancy),
}

fn run(plan: &[Planned], loss: f64, burst_at_ms: u64, burst_ms: u64, seed: u64) -> Outcome {
    run_with(plan, loss, burst_at_ms, burst_ms, seed, Copies::Default)
}

/// Where the burst of [`run_with`] loses frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Burst {
    /// Acks only (the downlink).
    Downlink,
    /// Everything: a radio silence.
    BothWays,
}

fn run_with(
    plan: &[Planned],
    loss: f64,
    burst_at_ms: u64,
    burst_ms: u64,
    seed: u64,
    copies: Copies,
) -> Outcome {
    run_burst(
        plan,
        0,
        loss,
        (burst_at_ms, burst_ms, Burst::Downlink),
        seed,
        copies,
    )
}

/// As [`run_with`], the ground's first command `start_ms` in (the link up before it), the
/// burst where it says.
fn run_burst(
    plan: &[Planned],
    start_ms: u64,
    loss: f64,
    (burst_at_ms, burst_ms, burst_where): (u64, u64, Burst),
    seed: u64,
    copies: Copies,
) -> Outcome {
    let t0 = Instant::ZERO;
    let mut router_config = RouterConfig::new(budget());
    let profile = Profile::parse("", "test").unwrap();
    let mut bridge_config = BridgeConfig::new(profile, budget());
    match copies {
        Copies::Default => {}
        Copies::Off => {
            router_config.command_redundancy = None;
            bridge_config.command_redundancy = None;
        }
        Copies::Forced(r) => {
            router_config.command_redundancy = Some(r);
            bridge_config.command_redundancy = Some(r);
        }
    }
    let mut router = Router::new(router_config, t0).unwrap();
    let mut bridge = Bridge::new(bridge_config, t0).unwrap();
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let mut rng = Rng(seed | 1);
    let latency = Duration::from_millis(120);
    let mut up: VecDeque<(Instant, OwnedFrame)> = VecDeque::new();
    let mut down: VecDeque<(Instant, OwnedFrame)> = VecDeque::new();
    let burst = (
        t0 + Duration::from_millis(burst_at_ms),
        t0 + Duration::from_millis(burst_at_ms + burst_ms),
    );

    // the ground station: per id, its plan and the one command it waits on
    let mut queues: Vec<VecDeque<Planned>> = vec![VecDeque::new(); IDS.len()];
    for p in plan {
        let mut p = *p;
        // Two identical commands outstanding at once cannot be told apart by anyone (their
        // retries are the same bytes, their acks too): a ground station waits for the first
        // (here: sends a command early only if none of that id had those parameters).
        if queues[p.id].iter().any(|q| q.param == p.param) {
            p.eager = false;
        }
        queues[p.id].push_back(p);
    }
    let mut waiting: Vec<VecDeque<Outstanding>> = (0..IDS.len()).map(|_| VecDeque::new()).collect();
    let mut next_new: Vec<Instant> = vec![t0 + Duration::from_millis(start_ms); IDS.len()];
    let mut ranks = vec![0usize; IDS.len()];
    let mut last_answer: Vec<Option<usize>> = vec![None; IDS.len()];
    let mut executions: HashMap<u16, usize> = HashMap::new();
    let mut out = Outcome::default();
    let mut reader = FrameReader::new();

    let step = Duration::from_millis(10);
    let mut now = t0;
    let end = t0 + Duration::from_secs(240);
    while now < end {
        // ground station: new commands, retries
        for k in 0..IDS.len() {
            let may_send = queues[k]
                .front()
                .is_some_and(|p| (p.eager || waiting[k].is_empty()) && now >= next_new[k]);
            if may_send {
                let p = queues[k].pop_front().unwrap();
                let msg = COMMAND_LONG_DATA {
                    target_system: 1,
                    target_component: 1,
                    command: IDS[k],
                    param1: 1.0,
                    param2: f32::from(p.param),
                    ..Default::default()
                };
                out.sent.entry(IDS[k] as u16).or_default().push(p.param);
                waiting[k].push_back(Outstanding {
                    rank: ranks[k],
                    msg,
                    tries: 0,
                    next_try: now,
                });
                ranks[k] += 1;
                if let Some(next) = queues[k].front().filter(|n| n.eager) {
                    next_new[k] = now + Duration::from_millis(next.gap_ms);
                }
            }
            for w in waiting[k]
                .iter_mut()
                .filter(|w| now >= w.next_try && w.tries < 5)
            {
                w.msg.confirmation = w.tries;
                let f = gcs.frame(&MavMessage::COMMAND_LONG(w.msg.clone()));
                router.handle_gcs_bytes(now, f.as_bytes());
                w.tries += 1;
                w.next_try = now + Duration::from_millis(1500);
            }
            let before = waiting[k].len();
            waiting[k].retain(|w| w.tries < 5 || now < w.next_try);
            if waiting[k].len() < before {
                *out.gave_up.entry(IDS[k] as u16).or_default() += before - waiting[k].len();
            }
            if waiting[k].len() < before && waiting[k].is_empty() {
                next_new[k] =
                    now + Duration::from_millis(queues[k].front().map_or(0, |p| p.gap_ms));
            }
        }
        // engines
        router.handle_timeout(now);
        bridge.handle_timeout(now);
        let in_burst = now >= burst.0 && now < burst.1;
        let uplink_silent = in_burst && burst_where == Burst::BothWays;
        while let Some(f) = router.poll_radio_transmit(now, usize::MAX) {
            if !uplink_silent && !rng.chance(loss) {
                up.push_back((now + latency, f));
            }
        }
        while let Some(f) = bridge.poll_radio_transmit(now, usize::MAX) {
            if !in_burst && !rng.chance(loss) {
                down.push_back((now + latency, f));
            }
        }
        while up.front().is_some_and(|(at, _)| *at <= now) {
            let (_, f) = up.pop_front().unwrap();
            bridge.handle_radio_bytes(now, f.as_bytes());
        }
        while down.front().is_some_and(|(at, _)| *at <= now) {
            let (_, f) = down.pop_front().unwrap();
            router.handle_radio_bytes(now, f.as_bytes());
        }
        // the autopilot: a heartbeat every second, as any does (the link carries
        // something besides acks)
        if now.since_epoch().as_millis().is_multiple_of(1000) {
            let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
            bridge.handle_fc_bytes(now, fc.frame(&hb).as_bytes());
        }
        // the autopilot executes and answers at once
        while let Some(f) = bridge.poll_fc_transmit(now) {
            if let Ok(MavMessage::COMMAND_LONG(c)) = f.decode::<MavMessage>() {
                let n = executions.entry(c.command as u16).or_default();
                out.executed
                    .entry(c.command as u16)
                    .or_default()
                    .push(c.param2 as u8);
                let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                    command: c.command,
                    result: RESULTS[*n % RESULTS.len()],
                    // the autopilot's own extension values, which the ground must get as sent
                    result_param2: result_param2(*n),
                    target_system: 255,
                    target_component: 190,
                    ..Default::default()
                });
                *n += 1;
                bridge.handle_fc_bytes(now, fc.frame(&ack).as_bytes());
            }
        }
        // the ground station reads its acks
        while let Some(f) = router.poll_gcs_transmit() {
            reader.push(f.as_bytes());
        }
        while let Some(rx) = reader.next_frame() {
            let Ok(MavMessage::COMMAND_ACK(ack)) = rx.frame.decode::<MavMessage>() else {
                continue;
            };
            let Some(k) = IDS.iter().position(|&c| c == ack.command) else {
                continue;
            };
            // The ack answers the ground's oldest command of that id, rank r, if it comes
            // from a later execution than the previous ack's, and the executions missing
            // before it are of commands the ground gave up on (lost on the way up).
            let e = RESULTS.iter().position(|&r| r == ack.result);
            if e.is_none_or(|e| ack.result_param2 != result_param2(e))
                || (ack.target_system, ack.target_component) != (255, 190)
            {
                out.misattributed
                    .push(format!("ack not as the autopilot sent it: {ack:?}"));
            }
            let gave_up = out.gave_up.get(&(IDS[k] as u16)).copied().unwrap_or(0);
            let ran = executions.get(&(IDS[k] as u16)).copied().unwrap_or(0);
            match waiting[k].pop_front() {
                Some(w)
                    if e.is_some_and(|e| {
                        e <= w.rank
                            && w.rank - e <= gave_up
                            && e < ran
                            && last_answer[k].is_none_or(|l| e > l)
                    }) =>
                {
                    out.acked += 1;
                    last_answer[k] = e;
                    if waiting[k].is_empty() {
                        next_new[k] =
                            now + Duration::from_millis(queues[k].front().map_or(0, |p| p.gap_ms));
                    }
                }
                Some(w) => {
                    out.misattributed.push(format!(
                        "{:?} #{} got {:?} at {now}",
                        ack.command, w.rank, ack.result
                    ));
                    waiting[k].push_front(w);
                }
                // nothing outstanding (the ground gave up): an ack a ground station ignores
                None => out.stray_acks += 1,
            }
        }
        if queues.iter().all(VecDeque::is_empty) && waiting.iter().all(VecDeque::is_empty) {
            // let the last copies drain, then stop
            if up.is_empty() && down.is_empty() && now > end - Duration::from_secs(200) {
                break;
            }
        }
        now += step;
    }
    out
}

fn check(out: &Outcome) -> Result<(), String> {
    if !out.misattributed.is_empty() {
        return Err(format!("acks misattributed: {:?}", out.misattributed));
    }
    // Each command ran once, in order; only one the ground gave up on may be missing.
    for (id, sent) in &out.sent {
        let executed = out.executed.get(id).cloned().unwrap_or_default();
        let mut rest = executed.iter().peekable();
        for s in sent {
            if rest.peek() == Some(&s) {
                rest.next();
            }
        }
        let missing = sent.len().saturating_sub(executed.len());
        let gave_up = out.gave_up.get(id).copied().unwrap_or(0);
        if rest.peek().is_some() || missing > gave_up {
            return Err(format!(
                "id {id}: executed {executed:?}, sent {sent:?}, ground gave up {gave_up}"
            ));
        }
    }
    if out.executed.keys().any(|id| !out.sent.contains_key(id)) {
        return Err(format!("executed unsent commands: {:?}", out.executed));
    }
    Ok(())
}

#[test]
fn a_repeated_trigger_runs_again_and_a_late_copy_does_not() {
    // the camera trigger twice with identical parameters 2.5 s apart, then an ack-loss burst
    // of 8 s over the third: each runs exactly once
    let trigger = |gap_ms| Planned {
        id: 1,
        param: 1,
        gap_ms,
        eager: false,
    };
    let plan = [trigger(0), trigger(2500), trigger(2500)];
    let out = run(&plan, 0.0, 6000, 8000, 7);
    check(&out).unwrap();
    assert_eq!(
        out.executed[&(MavCmd::MAV_CMD_DO_DIGICAM_CONTROL as u16)].len(),
        3
    );
}

#[test]
fn a_command_sent_into_a_5_s_silence_runs_once_when_it_ends_and_is_acked() {
    // The link runs 2 s (the router hears the autopilot and times two commands' round
    // trips), then falls silent both ways for 5 s at 3.5 s, with 10 % loss besides; the
    // third command goes somewhere before or in the silence, and the ground retries it
    // every 1.5 s, 5 sends (the soak's silences). The relay has to get it through and its
    // ack back before the ground gives up, 7.5 s after its first send. Its own resends
    // must not use up their eight attempts in the silence: a relay that gave the command
    // up would send the ground's last retry nowhere.
    let mut failed = Vec::new();
    for gap_ms in (0..=2400).step_by(200) {
        for seed in 1..=5 {
            let command = |param, gap_ms| Planned {
                id: 0,
                param,
                gap_ms,
                eager: false,
            };
            let plan = [command(1, 0), command(2, 300), command(3, gap_ms)];
            let silence = (3500, 5000, Burst::BothWays);
            let out = run_burst(&plan, 2000, 0.1, silence, seed, Copies::Default);
            let executed = out
                .executed
                .get(&(IDS[0] as u16))
                .cloned()
                .unwrap_or_default();
            if out.acked != 3 || executed != [1, 2, 3] {
                failed.push(format!(
                    "third {gap_ms} ms after the second, seed {seed}: {out:?}"
                ));
            }
        }
    }
    assert!(
        failed.is_empty(),
        "{} failed:\n{}",
        failed.len(),
        failed.join("\n")
    );
}

#[test]
fn set_mode_4_then_5_200_ms_later_both_run_in_order_each_acked_as_itself() {
    let mode = |param, gap_ms, eager| Planned {
        id: 0,
        param,
        gap_ms,
        eager,
    };
    // mode 4's acks are lost for 2 s: the router resends it, mode 5 waits its turn
    let out = run(&[mode(4, 0, false), mode(5, 200, true)], 0.0, 100, 2000, 3);
    check(&out).unwrap();
    assert_eq!(
        out.executed[&(MavCmd::MAV_CMD_DO_SET_MODE as u16)],
        vec![4, 5]
    );
    assert_eq!(out.acked, 2);
}

/// Redundant copies off, default, or forced on with a pair gap and a spacing from 1 ms to
/// beyond the link's 240 ms round trip.
fn copies() -> impl Strategy<Value = Copies> {
    prop_oneof![
        Just(Copies::Off),
        Just(Copies::Default),
        (1u64..200, 1u64..400).prop_map(|(gap, spacing)| Copies::Forced(Redundancy {
            min_loss: 0.0,
            pair_gap: Duration::from_millis(gap),
            spacing: Duration::from_millis(spacing),
            ..Redundancy::SIK_64K
        })),
    ]
}

#[test]
fn forced_copies_and_ack_repeats_under_ack_loss_run_each_command_once() {
    // every command three times more and every ack twice, the acks lost for 8 s over the
    // second trigger: the copies are answered from the cache, the repeats never answer the
    // next command
    let trigger = |gap_ms| Planned {
        id: 1,
        param: 1,
        gap_ms,
        eager: false,
    };
    let forced = Copies::Forced(Redundancy {
        min_loss: 0.0,
        ..Redundancy::SIK_64K
    });
    let plan = [trigger(0), trigger(2500), trigger(2500), trigger(0)];
    // the link up 2 s before the first: a copy of a command that may have come before the
    // bridge started is not run (here the first's first copy is lost)
    let out = run_burst(&plan, 2000, 0.1, (5000, 8000, Burst::Downlink), 11, forced);
    check(&out).unwrap();
    assert_eq!(
        out.executed[&(MavCmd::MAV_CMD_DO_DIGICAM_CONTROL as u16)].len(),
        4
    );
}

fn plans(eager: bool) -> impl Strategy<Value = Vec<Planned>> {
    prop::collection::vec(
        (0..IDS.len(), 0u8..2, 0u64..4000, any::<bool>()).prop_map(
            move |(id, param, gap_ms, e)| Planned {
                id,
                param,
                gap_ms,
                eager: eager && e,
            },
        ),
        1..=RESULTS.len(),
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// A ground station that waits for a command's ack (or gives up) before it sends the
    /// next with the same id (QGroundControl and MAVSDK queue their commands so), under loss
    /// and ack-loss bursts up to 12 s.
    #[test]
    fn each_command_runs_once_and_each_ack_answers_its_own(
        plan in plans(false),
        loss in 0.0f64..0.3,
        burst_at_ms in 0u64..20_000,
        burst_ms in 0u64..12_000,
        seed in any::<u64>(),
        copies in copies(),
    ) {
        let out = run_with(&plan, loss, burst_at_ms, burst_ms, seed, copies);
        prop_assert!(check(&out).is_ok(), "{}", check(&out).unwrap_err());
    }

    /// A ground station that sends a second command with the same id before the first is
    /// answered (DO_SET_MODE 4, then 5), under loss. (With ack-loss bursts longer than its
    /// patience such a station gives up on the waiting command and then takes its ack for
    /// the next one: nothing on the router's side can tell.)
    #[test]
    fn eager_ground_commands_run_once_in_order_each_acked_as_itself(
        plan in plans(true),
        loss in 0.0f64..0.3,
        seed in any::<u64>(),
        copies in copies(),
    ) {
        let out = run_with(&plan, loss, 0, 0, seed, copies);
        prop_assert!(check(&out).is_ok(), "{}", check(&out).unwrap_err());
    }
}
