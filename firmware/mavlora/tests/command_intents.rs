//! One ground intent, one execution: the command relay's invariant across restarts, slow
//! autopilots and commands repeated with identical parameters, on a virtual clock.
//!
//! The invariant: each command a ground station sends (one intent: its first send and its
//! own retries, however many copies the router puts on the radio) is executed by the flight
//! controller at most once, and every distinct intent is executed (when the link carries
//! it), even one identical to an earlier one, even after the router or the bridge restarted.
//! The one exception is a copy the bridge cannot place after its own restart: it may have
//! run already, so it is not run, and the ground gets no ack (its timeout says "unknown").
//!
//! The world: a scripted ground station (the command protocol: one command at a time, a
//! retry after its timeout, `COMMAND_LONG` with `confirmation` + 1, `COMMAND_INT` as it
//! was), the router and bridge engines joined by a radio with 120 ms latency that drops the
//! frames a test names, and an autopilot that records each command it executes and acks it
//! after a delay (its `result_param2`: the command's `param1`).

use std::collections::VecDeque;

use mavlink::MavlinkVersion;

use mavlora::Duration;
use mavlora::Instant;
use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::dialect::{
    COMMAND_ACK_DATA, COMMAND_INT_DATA, COMMAND_LONG_DATA, HEARTBEAT_DATA, MavCmd, MavMessage,
    MavResult,
};
use mavlora::filter::Profile;
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::SchedulerConfig;
use mavlora::wire::{FrameReader, OwnedFrame, Sender};

const MS: fn(u64) -> Duration = Duration::from_millis;

fn budget() -> SchedulerConfig {
    SchedulerConfig {
        rate_bytes_per_s: 2000,
        burst_bytes: 600,
        max_queued_bytes: 8000,
    }
}

fn new_router(now: Instant, tune: fn(&mut RouterConfig)) -> Router {
    let mut config = RouterConfig::new(budget());
    tune(&mut config);
    Router::new(config, now).unwrap()
}

fn new_bridge(now: Instant) -> Bridge {
    let profile = Profile::parse("", "test").unwrap();
    Bridge::new(BridgeConfig::new(profile, budget()), now).unwrap()
}

/// What a ground station sends: a command as `COMMAND_LONG` or `COMMAND_INT`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Long,
    Int,
}

/// A command (id, param1, param2) as the ground sends it, with `confirmation` for a
/// `COMMAND_LONG`.
fn command(kind: Kind, cmd: MavCmd, param1: f32, param2: f32, confirmation: u8) -> MavMessage {
    match kind {
        Kind::Long => MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 1,
            target_component: 1,
            command: cmd,
            confirmation,
            param1,
            param2,
            ..Default::default()
        }),
        Kind::Int => MavMessage::COMMAND_INT(COMMAND_INT_DATA {
            target_system: 1,
            target_component: 1,
            command: cmd,
            param1,
            param2,
            ..Default::default()
        }),
    }
}

fn is_command(f: &OwnedFrame) -> bool {
    matches!(
        f.decode::<MavMessage>(),
        Ok(MavMessage::COMMAND_LONG(_) | MavMessage::COMMAND_INT(_))
    )
}

fn is_ack(f: &OwnedFrame) -> bool {
    matches!(f.decode::<MavMessage>(), Ok(MavMessage::COMMAND_ACK(_)))
}

struct World {
    now: Instant,
    router: Router,
    /// What the router's configuration differs in from the defaults.
    tune_router: fn(&mut RouterConfig),
    bridge: Bridge,
    gcs: Sender,
    fc: Sender,
    up: VecDeque<(Instant, OwnedFrame)>,
    down: VecDeque<(Instant, OwnedFrame)>,
    /// Command frames still to drop on the way up.
    drop_commands_up: usize,
    /// Drop every ack on the way down.
    acks_down_lost: bool,
    /// How long the autopilot takes to ack a command.
    fc_delay: Duration,
    fc_acks: VecDeque<(Instant, OwnedFrame)>,
    /// (command, param1) of each execution, in order.
    executed: Vec<(MavCmd, f32)>,
    ground_reader: FrameReader,
    /// Ground frames the router rejected (its command budget).
    rejected: usize,
}

impl World {
    fn new() -> Self {
        Self::with_router(|_| {})
    }

    /// A world whose router's configuration `tune` changes.
    fn with_router(tune_router: fn(&mut RouterConfig)) -> Self {
        let now = Instant::ZERO;
        let mut w = Self {
            now,
            router: new_router(now, tune_router),
            tune_router,
            bridge: new_bridge(now),
            gcs: Sender::new(255, 190, MavlinkVersion::V2),
            fc: Sender::new(1, 1, MavlinkVersion::V2),
            up: VecDeque::new(),
            down: VecDeque::new(),
            drop_commands_up: 0,
            acks_down_lost: false,
            fc_delay: Duration::ZERO,
            fc_acks: VecDeque::new(),
            executed: Vec::new(),
            ground_reader: FrameReader::new(),
            rejected: 0,
        };
        // the link runs a while before the first command (a restarted bridge's cache is
        // cold for its first seconds; this one has been up)
        w.run(Duration::from_secs(20));
        w
    }

    /// 10 ms of the world; the acks the ground station read.
    fn step(&mut self) -> Vec<COMMAND_ACK_DATA> {
        let now = self.now;
        let latency = MS(120);
        self.router.handle_timeout(now);
        self.bridge.handle_timeout(now);
        while let Some(f) = self.router.poll_radio_transmit(now, usize::MAX) {
            if is_command(&f) && self.drop_commands_up > 0 {
                self.drop_commands_up -= 1;
                continue;
            }
            self.up.push_back((now + latency, f));
        }
        while let Some(f) = self.bridge.poll_radio_transmit(now, usize::MAX) {
            if !(self.acks_down_lost && is_ack(&f)) {
                self.down.push_back((now + latency, f));
            }
        }
        while self.up.front().is_some_and(|(at, _)| *at <= now) {
            let (_, f) = self.up.pop_front().unwrap();
            self.bridge.handle_radio_bytes(now, f.as_bytes());
        }
        while self.down.front().is_some_and(|(at, _)| *at <= now) {
            let (_, f) = self.down.pop_front().unwrap();
            self.router.handle_radio_bytes(now, f.as_bytes());
        }
        if now.since_epoch().as_millis().is_multiple_of(1000) {
            let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
            self.bridge
                .handle_fc_bytes(now, self.fc.frame(&hb).as_bytes());
        }
        while let Some(f) = self.bridge.poll_fc_transmit(now) {
            let (cmd, param1) = match f.decode::<MavMessage>() {
                Ok(MavMessage::COMMAND_LONG(c)) => (c.command, c.param1),
                Ok(MavMessage::COMMAND_INT(c)) => (c.command, c.param1),
                _ => continue,
            };
            self.executed.push((cmd, param1));
            let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                command: cmd,
                result: MavResult::MAV_RESULT_ACCEPTED,
                // which command it answers, for the ground to check
                result_param2: param1 as i32,
                target_system: 255,
                target_component: 190,
                ..Default::default()
            });
            self.fc_acks
                .push_back((now + self.fc_delay, self.fc.frame(&ack)));
        }
        while self.fc_acks.front().is_some_and(|(at, _)| *at <= now) {
            let (_, f) = self.fc_acks.pop_front().unwrap();
            self.bridge.handle_fc_bytes(now, f.as_bytes());
        }
        while let Some(f) = self.router.poll_gcs_transmit() {
            self.ground_reader.push(f.as_bytes());
        }
        let mut acks = Vec::new();
        while let Some(rx) = self.ground_reader.next_frame() {
            if let Ok(MavMessage::COMMAND_ACK(a)) = rx.frame.decode::<MavMessage>() {
                acks.push(a);
            }
        }
        self.now += MS(10);
        acks
    }

    fn run(&mut self, d: Duration) {
        let end = self.now + d;
        while self.now < end {
            self.step();
        }
    }

    fn send(&mut self, msg: &MavMessage) {
        let f = self.gcs.frame(msg);
        self.rejected += self
            .router
            .handle_gcs_bytes(self.now, f.as_bytes())
            .rejected;
    }

    /// The ground station sends one command and waits for its ack, retrying every
    /// `timeout` up to `tries` sends (the command protocol); the ack's result, `None` if it
    /// gave up.
    fn ground_command(
        &mut self,
        kind: Kind,
        cmd: MavCmd,
        param1: f32,
        timeout: Duration,
        tries: u8,
    ) -> Option<MavResult> {
        for confirmation in 0..tries {
            self.send(&command(kind, cmd, param1, 0.0, confirmation));
            let until = self.now + timeout;
            while self.now < until {
                if let Some(a) = self.step().into_iter().find(|a| a.command == cmd) {
                    return Some(a.result);
                }
            }
        }
        None
    }

    /// As a QGroundControl-like station: 1.5 s timeout, 5 tries.
    fn qgc(&mut self, kind: Kind, cmd: MavCmd, param1: f32) -> Option<MavResult> {
        self.ground_command(kind, cmd, param1, MS(1500), 5)
    }

    fn restart_router(&mut self) {
        self.router = new_router(self.now, self.tune_router);
        // what the previous run had queued dies with it
        self.down.clear();
        // the radio carries something before the next command (heartbeats, reports)
        self.run(Duration::from_secs(2));
    }

    fn restart_bridge(&mut self) {
        self.bridge = new_bridge(self.now);
        self.up.clear();
    }

    fn executions(&self, cmd: MavCmd) -> Vec<f32> {
        self.executed
            .iter()
            .filter(|(c, _)| *c == cmd)
            .map(|(_, p)| *p)
            .collect()
    }
}

const ARM: MavCmd = MavCmd::MAV_CMD_COMPONENT_ARM_DISARM;
const TRIGGER: MavCmd = MavCmd::MAV_CMD_DO_DIGICAM_CONTROL;
const SET_MODE: MavCmd = MavCmd::MAV_CMD_DO_SET_MODE;
const ACCEPTED: Option<MavResult> = Some(MavResult::MAV_RESULT_ACCEPTED);

#[test]
fn after_a_router_restart_arm_runs_although_the_bridge_holds_the_previous_runs_arm() {
    for kind in [Kind::Long, Kind::Int] {
        let mut w = World::new();
        assert_eq!(w.qgc(kind, ARM, 1.0), ACCEPTED);
        assert_eq!(w.qgc(kind, ARM, 0.0), ACCEPTED);
        w.restart_router();
        // the new run's first copy of ARM is lost: its next copy reaches the bridge first,
        // with the generation the previous run's ARM had
        w.drop_commands_up = 1;
        assert_eq!(w.qgc(kind, ARM, 1.0), ACCEPTED, "{kind:?}");
        assert_eq!(w.executions(ARM), [1.0, 0.0, 1.0], "{kind:?}");
    }
}

#[test]
fn after_a_router_restart_a_ground_retry_of_a_command_the_previous_run_sent_does_not_run_again() {
    let mut w = World::new();
    // the trigger runs, its acks are lost, the router restarts meanwhile
    w.acks_down_lost = true;
    w.send(&command(Kind::Long, TRIGGER, 1.0, 0.0, 0));
    w.run(MS(1000));
    assert_eq!(w.executions(TRIGGER).len(), 1);
    w.acks_down_lost = false;
    w.restart_router();
    // the ground retries it: the new run cannot know it ran
    for confirmation in 1..5 {
        w.send(&command(Kind::Long, TRIGGER, 1.0, 0.0, confirmation));
        w.run(MS(1500));
    }
    assert_eq!(w.executions(TRIGGER).len(), 1);
    // a new trigger (confirmation 0) runs
    assert_eq!(w.qgc(Kind::Long, TRIGGER, 1.0), ACCEPTED);
    assert_eq!(w.executions(TRIGGER).len(), 2);
}

#[test]
fn a_restarted_bridge_does_not_run_again_a_command_whose_ack_it_lost() {
    for kind in [Kind::Long, Kind::Int] {
        let mut w = World::new();
        w.acks_down_lost = true;
        w.send(&command(kind, TRIGGER, 1.0, 0.0, 0));
        // the first copy reaches the bridge at 120 ms and runs; its ack is lost
        w.run(MS(300));
        assert_eq!(w.executions(TRIGGER).len(), 1);
        w.restart_bridge();
        w.acks_down_lost = false;
        // the router's further copies (and the ground's retries) reach the new bridge
        let mut result = None;
        for _ in 0..1000 {
            if let Some(a) = w.step().into_iter().find(|a| a.command == TRIGGER) {
                result = Some(a.result);
            }
        }
        assert_eq!(w.executions(TRIGGER).len(), 1, "{kind:?}");
        // no ack: the outcome is unknown to the relay, and the ground times out
        assert_eq!(result, None, "{kind:?}");
        // a new command runs
        assert_eq!(w.qgc(kind, ARM, 1.0), ACCEPTED, "{kind:?}");
        assert_eq!(w.executions(ARM), [1.0], "{kind:?}");
    }
}

#[test]
fn a_trigger_the_autopilot_acks_after_2_5_s_runs_once_and_is_acked() {
    for kind in [Kind::Long, Kind::Int] {
        let mut w = World::new();
        w.fc_delay = MS(2500);
        assert_eq!(w.qgc(kind, TRIGGER, 1.0), ACCEPTED, "{kind:?}");
        w.run(Duration::from_secs(15));
        assert_eq!(w.executions(TRIGGER).len(), 1, "{kind:?}");
    }
}

#[test]
fn arm_disarm_arm_within_12_s_runs_all_three() {
    for kind in [Kind::Int, Kind::Long] {
        let mut w = World::new();
        for arm in [1.0, 0.0, 1.0] {
            assert_eq!(w.qgc(kind, ARM, arm), ACCEPTED, "{kind:?}");
        }
        assert_eq!(w.executions(ARM), [1.0, 0.0, 1.0], "{kind:?}");
    }
}

#[test]
fn twenty_holds_in_a_row_all_run_and_are_accepted() {
    // MAVSDK's hold(): DO_SET_MODE with the same parameters each time, the next as soon as
    // the last is answered; its command timeout is 0.5 s, 3 retries
    for kind in [Kind::Long, Kind::Int] {
        let mut w = World::new();
        let mut results = Vec::new();
        for _ in 0..20 {
            results.push(w.ground_command(kind, SET_MODE, 4.0, MS(500), 4));
        }
        assert_eq!(results, vec![ACCEPTED; 20], "{kind:?}");
        assert_eq!(w.executions(SET_MODE).len(), 20, "{kind:?}");
        assert_eq!(w.rejected, 0, "{kind:?}");
    }
}

/// An eager ground station (DO_SET_MODE 4, then 5 before 4 is answered): each command
/// `(param1, first send)` is retried every 1.5 s up to 5 sends, and an ack answers the
/// oldest one still waiting (`COMMAND_ACK` names only the command id). Steps the world until
/// every command is answered or given up; (param1 of the command the ground took the ack
/// for, the ack's `result_param2`: the param1 of the command the autopilot ran).
fn eager_ground(
    w: &mut World,
    cmd: MavCmd,
    plan: &[(f32, Instant)],
    mut each_step: impl FnMut(&mut World),
) -> Vec<(f32, i32)> {
    // (param1, sends so far, next send)
    let mut waiting: VecDeque<(f32, u8, Instant)> = plan.iter().map(|&(p, t)| (p, 0, t)).collect();
    let mut answers = Vec::new();
    let end = w.now + Duration::from_secs(30);
    while w.now < end && !waiting.is_empty() {
        each_step(w);
        let now = w.now;
        for o in waiting.iter_mut().filter(|o| now >= o.2 && o.1 < 5) {
            w.send(&command(Kind::Long, cmd, o.0, 0.0, o.1));
            o.1 += 1;
            o.2 = now + MS(1500);
        }
        // given up after the fifth send's timeout
        waiting.retain(|o| o.1 < 5 || now < o.2);
        for a in w.step().into_iter().filter(|a| a.command == cmd) {
            if let Some(o) = waiting.pop_front() {
                answers.push((o.0, a.result_param2));
            }
        }
    }
    answers
}

#[test]
fn a_newer_command_waits_while_the_ground_still_retries_the_older_one() {
    // DO_SET_MODE 4 runs at once, but its acks are lost for 3.05 s. The ground retries it
    // at 1.5 s and sends mode 5 then, before 4 is answered. The router copies mode 4 every
    // 1.45 s (its timeout on a slow link, no redundant copies): at 1.45 s, just before the
    // ground's retry, and next at 2.9 s. The ground's next retry is due at 3 s, and until
    // then it waits for mode 4's ack: the router must not give mode 4 up and put mode 5 on
    // the radio before (it did at 2.95 s: 1.4 s after the ground's retry, 1.5 s after its
    // own copy), or the ground takes mode 5's ack for mode 4's.
    let mut w = World::with_router(|c| {
        c.command_redundancy = None;
        c.command_initial_rto = MS(1450);
    });
    let start = w.now;
    w.acks_down_lost = true;
    let plan = [(4.0, start), (5.0, start + MS(1500))];
    let answers = eager_ground(&mut w, SET_MODE, &plan, |w| {
        if w.now >= start + MS(3050) {
            w.acks_down_lost = false;
        }
    });
    assert_eq!(w.executions(SET_MODE), [4.0, 5.0]);
    assert_eq!(answers, [(4.0, 4), (5.0, 5)], "(ground's command, ack's)");
}
