//! An end that restarts without its signing state (the file lost) and a peer that keeps
//! running: a signed `COMMAND_LONG` ARM recorded on the air before the restart, replayed into
//! the restarted end's radio input within the spec's minute, must never reach the flight
//! controller; the live peer's own commands must, once it answered the restarted end's
//! challenge, with the link recovering by itself within a few seconds, also at 10 % radio
//! loss. Both ways: the bridge restarted (the router running), and the router restarted (the
//! bridge keeping its state).

use std::collections::VecDeque;

use mavlink::MavlinkVersion;

use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::dialect::{
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, HEARTBEAT_DATA, MavAutopilot, MavCmd, MavMessage,
    MavResult, MavType,
};
use mavlora::filter::Profile;
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::SchedulerConfig;
use mavlora::signing::{SigningConfig, SigningKey, SigningState};
use mavlora::wire::{FrameReader, OwnedFrame, Sender, ids};
use mavlora::{Duration, Instant};

const KEY: SigningKey = SigningKey([0x3c; 32]);
/// The signing clock (10 µs units since 2015) at the world's time zero; both ends' clocks
/// agree with it.
const CLOCK: u64 = 300_000_000_000;
const STEP: Duration = Duration::from_millis(10);
const LATENCY: Duration = Duration::from_millis(40);

fn budget() -> SchedulerConfig {
    SchedulerConfig {
        rate_bytes_per_s: 2000,
        burst_bytes: 600,
        max_queued_bytes: 8000,
    }
}

/// Signing as `link_id`, started at world time `at` with `state`.
fn signing(link_id: u8, at: Instant, state: SigningState) -> SigningConfig {
    SigningConfig {
        key: KEY,
        link_id,
        epoch: CLOCK + at.as_micros() / 10,
        state,
    }
}

/// A state that knows its peer (a previous run accepted its frames).
fn knowing(peer: u8) -> SigningState {
    let mut state = SigningState::default();
    state.streams.insert((peer, 255, 191), CLOCK - 100_000);
    state
}

fn bridge(at: Instant, state: SigningState) -> Bridge {
    let mut config = BridgeConfig::new(Profile::parse("", "empty").unwrap(), budget());
    config.signing = Some(signing(1, at, state));
    Bridge::new(config, Instant::ZERO).unwrap()
}

fn router(at: Instant, state: SigningState) -> Router {
    let mut config = RouterConfig::new(budget());
    config.signing = Some(signing(2, at, state));
    Router::new(config, Instant::ZERO).unwrap()
}

fn arm(param2: f32) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        param2,
        ..Default::default()
    })
}

/// A tiny deterministic generator for the radio's loss.
struct Rng(u64);

impl Rng {
    fn chance(&mut self, p: f64) -> bool {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 / ((1u64 << 53) as f64)) < p
    }
}

/// Autopilot, bridge, radio, router and ground on one virtual clock. Each engine counts its
/// time from its own start (`*_start`), as a restarted process does.
struct World {
    now: Instant,
    bridge: Bridge,
    bridge_start: Instant,
    router: Router,
    router_start: Instant,
    fc: Sender,
    ground: Sender,
    /// Router → bridge, bridge → router: (arrival, frame).
    up: VecDeque<(Instant, OwnedFrame)>,
    down: VecDeque<(Instant, OwnedFrame)>,
    rng: Rng,
    loss: f64,
    /// Every frame each end put on the air (what a recorder on the channel has).
    on_air_up: Vec<OwnedFrame>,
    on_air_down: Vec<OwnedFrame>,
    /// `param2` of each ARM the autopilot received.
    arms: Vec<f32>,
}

impl World {
    fn new(seed: u64) -> Self {
        // A previous run of each: both states know the peer.
        Self {
            now: Instant::ZERO,
            bridge: bridge(Instant::ZERO, knowing(2)),
            bridge_start: Instant::ZERO,
            router: router(Instant::ZERO, knowing(1)),
            router_start: Instant::ZERO,
            fc: Sender::new(1, 1, MavlinkVersion::V2),
            ground: Sender::new(255, 190, MavlinkVersion::V2),
            up: VecDeque::new(),
            down: VecDeque::new(),
            rng: Rng(seed | 1),
            loss: 0.0,
            on_air_up: Vec::new(),
            on_air_down: Vec::new(),
            arms: Vec::new(),
        }
    }

    fn bridge_now(&self) -> Instant {
        Instant::ZERO + self.now.saturating_duration_since(self.bridge_start)
    }

    fn router_now(&self) -> Instant {
        Instant::ZERO + self.now.saturating_duration_since(self.router_start)
    }

    fn step(&mut self) {
        let (bnow, rnow) = (self.bridge_now(), self.router_now());
        if self.now.as_millis().is_multiple_of(1000) {
            let hb = self.fc.frame(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
                ..Default::default()
            }));
            self.bridge.handle_fc_bytes(bnow, hb.as_bytes());
        }
        while self.up.front().is_some_and(|(at, _)| *at <= self.now) {
            let (_, f) = self.up.pop_front().unwrap();
            self.bridge.handle_radio_bytes(bnow, f.as_bytes());
        }
        self.bridge.handle_timeout(bnow);
        while let Some(f) = self.bridge.poll_fc_transmit(bnow) {
            self.autopilot(bnow, &f);
        }
        while let Some(f) = self.bridge.poll_radio_transmit(bnow, usize::MAX) {
            self.on_air_down.push(f.clone());
            if !self.rng.chance(self.loss) {
                self.down.push_back((self.now + LATENCY, f));
            }
        }
        while self.down.front().is_some_and(|(at, _)| *at <= self.now) {
            let (_, f) = self.down.pop_front().unwrap();
            self.router.handle_radio_bytes(rnow, f.as_bytes());
        }
        self.router.handle_timeout(rnow);
        while let Some(f) = self.router.poll_radio_transmit(rnow, usize::MAX) {
            self.on_air_up.push(f.clone());
            if !self.rng.chance(self.loss) {
                self.up.push_back((self.now + LATENCY, f));
            }
        }
        while self.router.poll_gcs_transmit().is_some() {}
        self.now += STEP;
    }

    /// The autopilot: records each ARM and acknowledges it.
    fn autopilot(&mut self, now: Instant, frame: &OwnedFrame) {
        let mut r = FrameReader::new();
        r.push(frame.as_bytes());
        let Some(rx) = r.next_frame() else { return };
        if let Ok(MavMessage::COMMAND_LONG(c)) = rx.frame.decode::<MavMessage>()
            && c.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM
        {
            self.arms.push(c.param2);
            let ack = self.fc.frame(&MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                command: c.command,
                result: MavResult::MAV_RESULT_ACCEPTED,
                target_system: rx.frame.system_id(),
                target_component: rx.frame.component_id(),
                ..Default::default()
            }));
            self.bridge.handle_fc_bytes(now, ack.as_bytes());
        }
    }

    fn run_for(&mut self, d: Duration) {
        let until = self.now + d;
        while self.now < until {
            self.step();
        }
    }

    fn pilot_sends(&mut self, msg: &MavMessage) {
        let f = self.ground.frame(msg);
        let rnow = self.router_now();
        self.router.handle_gcs_bytes(rnow, f.as_bytes());
    }

    /// The pilot's ARM as the router signed it on the air (the recording).
    fn recorded_arm(&self) -> OwnedFrame {
        self.on_air_up
            .iter()
            .find(|f| f.message_id() == ids::COMMAND_LONG)
            .expect("the ARM went on the air")
            .clone()
    }

    /// A first run: the pilot arms (param2 0), the autopilot runs it once; returns the
    /// recording of that ARM.
    fn first_run(&mut self) -> OwnedFrame {
        self.run_for(Duration::from_secs(2));
        self.pilot_sends(&arm(0.0));
        self.run_for(Duration::from_secs(3));
        assert_eq!(self.arms, vec![0.0], "the first run's ARM");
        self.recorded_arm()
    }

    /// The recording played into the bridge's radio input, as a transmitter on the channel
    /// would, then the world run a while: whether the autopilot got it again.
    fn replay_reaches_fc(&mut self, recorded: &OwnedFrame) -> bool {
        let before = self.arms.iter().filter(|&&p| p == 0.0).count();
        let bnow = self.bridge_now();
        self.bridge.handle_radio_bytes(bnow, recorded.as_bytes());
        self.run_for(Duration::from_millis(200));
        self.arms.iter().filter(|&&p| p == 0.0).count() > before
    }

    /// The pilot arms again (param2 7) a few seconds after the restart: whether the
    /// autopilot got it within `within`.
    fn live_arm_reaches_fc(&mut self, within: Duration) -> bool {
        self.pilot_sends(&arm(7.0));
        let until = self.now + within;
        while self.now < until {
            self.step();
            if self.arms.contains(&7.0) {
                return true;
            }
        }
        false
    }
}

/// How long after the restart the live link is taken again at most: a challenge a second,
/// each crossing the radio twice.
const RECOVERY: Duration = Duration::from_secs(4);

#[test]
fn a_bridge_restarted_without_its_state_never_runs_an_arm_recorded_before_and_recovers() {
    for (seed, loss) in [(1, 0.0), (2, 0.1), (3, 0.1), (4, 0.1), (5, 0.1)] {
        let mut w = World::new(seed);
        let recorded = w.first_run();
        // The bridge restarts without its state file; the router keeps running.
        let restart = w.now;
        w.bridge_start = restart;
        w.bridge = bridge(restart, SigningState::default());
        w.up.clear();
        w.loss = loss;
        assert!(
            !w.replay_reaches_fc(&recorded),
            "seed {seed}: the recorded ARM ran on the restarted bridge"
        );
        // The link is back once the router's frames count as received again (nothing of
        // the peer counts before it proved it is live).
        while w.bridge.stats().radio_reader.frames() == 0 && w.now < restart + RECOVERY {
            w.step();
        }
        assert!(
            w.bridge.stats().radio_reader.frames() > 0,
            "seed {seed}: no frame of the live router taken {RECOVERY:?} after the restart"
        );
        // Replayed again after the handshake: below the router's proven floor.
        let replayed = w.bridge.stats().signing.replayed;
        assert!(
            !w.replay_reaches_fc(&recorded),
            "seed {seed}: after the handshake"
        );
        assert!(w.bridge.stats().signing.replayed > replayed, "seed {seed}");
        assert!(
            w.live_arm_reaches_fc(Duration::from_secs(5)),
            "seed {seed}: the live pilot's ARM did not reach the autopilot"
        );
        assert_eq!(
            w.arms.iter().filter(|&&p| p == 0.0).count(),
            1,
            "seed {seed}: {:?}",
            w.arms
        );
        let s = w.bridge.stats().signing;
        assert!(s.unproven > 0, "seed {seed}: {s:?}");
        // What it stores now knows the router: a next restart with the file is as before.
        let state = w.bridge.signing_state(w.bridge_now()).unwrap();
        assert!(
            state.streams.keys().any(|&(link, _, _)| link == 2),
            "{state:?}"
        );
    }
}

#[test]
fn a_router_restarted_without_its_state_never_forwards_a_recorded_frame_and_recovers() {
    for (seed, loss) in [(11, 0.0), (12, 0.1), (13, 0.1), (14, 0.1), (15, 0.1)] {
        let mut w = World::new(seed);
        let recorded = w.first_run();
        // The router restarts without its state file (the bridge keeps its own): its fresh
        // state must take nothing of the bridge's until the bridge answered.
        let restart = w.now;
        w.router_start = restart;
        w.router = router(restart, SigningState::default());
        w.down.clear();
        w.loss = loss;
        // The autopilot's heartbeat recorded on the air before the restart, played to the
        // restarted router: nothing of it reaches the ground.
        let heartbeat = w
            .on_air_down
            .iter()
            .rfind(|f| f.message_id() == ids::HEARTBEAT && f.system_id() == 1)
            .expect("the autopilot's heartbeat went on the air")
            .clone();
        while w.router.poll_gcs_transmit().is_some() {}
        let rnow = w.router_now();
        w.router.handle_radio_bytes(rnow, heartbeat.as_bytes());
        let to_ground: Vec<OwnedFrame> =
            std::iter::from_fn(|| w.router.poll_gcs_transmit()).collect();
        assert!(
            to_ground.iter().all(|f| f.message_id() != ids::HEARTBEAT),
            "seed {seed}: the recorded heartbeat reached the ground"
        );
        let unproven = w.router.stats().signing.unproven;
        assert!(unproven > 0, "seed {seed}");
        // The ARM recorded on the air, signed by the router's previous run: the bridge's
        // state holds that stream.
        assert!(!w.replay_reaches_fc(&recorded), "seed {seed}");
        while w.router.stats().radio_reader.frames() == 0 && w.now < restart + RECOVERY {
            w.step();
        }
        assert!(
            w.router.stats().radio_reader.frames() > 0,
            "seed {seed}: no frame of the bridge taken {RECOVERY:?} after the restart"
        );
        let replayed = w.router.stats().signing.replayed;
        let rnow = w.router_now();
        w.router.handle_radio_bytes(rnow, heartbeat.as_bytes());
        assert!(
            w.router.stats().signing.replayed > replayed,
            "seed {seed}: below the proven floor"
        );
        assert!(
            w.live_arm_reaches_fc(Duration::from_secs(5)),
            "seed {seed}: the live pilot's ARM did not reach the autopilot"
        );
        assert_eq!(
            w.arms.iter().filter(|&&p| p == 0.0).count(),
            1,
            "seed {seed}"
        );
    }
}

/// A first install: neither end has a state. Each proves the other live, and the pilot's
/// ARM goes through within a few seconds, also at 10 % loss.
#[test]
fn two_fresh_ends_prove_each_other_and_carry_commands() {
    for (seed, loss) in [(21, 0.0), (22, 0.1), (23, 0.1)] {
        let mut w = World::new(seed);
        w.bridge = bridge(Instant::ZERO, SigningState::default());
        w.router = router(Instant::ZERO, SigningState::default());
        w.loss = loss;
        let counted = |w: &World| {
            w.bridge.stats().radio_reader.frames() > 0 && w.router.stats().radio_reader.frames() > 0
        };
        while !counted(&w) && w.now < Instant::ZERO + RECOVERY {
            w.step();
        }
        assert!(
            counted(&w),
            "seed {seed}: a link not proven within {RECOVERY:?}"
        );
        assert!(
            w.live_arm_reaches_fc(Duration::from_secs(5)),
            "seed {seed}: the pilot's ARM did not reach the autopilot"
        );
        // Each stores the other: a restart with the files needs no handshake.
        let knows = |state: SigningState, peer: u8| state.streams.keys().any(|k| k.0 == peer);
        assert!(knows(w.bridge.signing_state(w.bridge_now()).unwrap(), 2));
        assert!(knows(w.router.signing_state(w.router_now()).unwrap(), 1));
    }
}
