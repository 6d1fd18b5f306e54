//! Mission uploads through the router and bridge engines on a virtual clock, against models
//! of the two autopilots they meet (ArduPilot 4.6: `opaque_id` always 0, `MISSION_REQUEST_INT`,
//! a second upload from the same partner restarts, partial writes; PX4 1.16: `opaque_id`
//! set, a second `MISSION_COUNT` mid-upload answered with an error) and of ground stations
//! (MAVSDK's retry rule among them). The invariant: **the ground is told ACCEPTED only for
//! the plan the vehicle holds**, that is, only when the autopilot acked, after receiving
//! every item, exactly the plan the ground sent last.
//!
//! Sans-IO, as the engines: bytes and `now` in, bytes out; the radio is a queue with a fixed
//! latency (and optional loss); nothing sleeps.

// Legacy MISSION_ITEM is deprecated, and what some ground stations still send.
#![allow(deprecated)]
// Full literals keep `..Default::default()`: the dialect may grow.
#![allow(clippy::needless_update)]

use std::collections::VecDeque;

use mavlink::MavlinkVersion;
use proptest::prelude::*;

use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::dialect::{
    HEARTBEAT_DATA, MISSION_ACK_DATA, MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA,
    MISSION_ITEM_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA,
    MISSION_WRITE_PARTIAL_LIST_DATA, MavAutopilot, MavMessage, MavMissionResult, MavMissionType,
    MavType,
};
use mavlora::filter::Profile;
use mavlora::mission::plan::{plan_hash, same_plan};
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::SchedulerConfig;
use mavlora::wire::{FrameReader, OwnedFrame, Sender};
use mavlora::{Duration, Instant};

const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;
const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;
const ACCEPTED: MavMissionResult = MavMissionResult::MAV_MISSION_ACCEPTED;
const VEHICLE: (u8, u8) = (1, 1);
const GROUND: (u8, u8) = (255, 190);
/// MAVSDK's ground station.
const MAVSDK: (u8, u8) = (245, 190);

fn slot(t: MavMissionType) -> usize {
    match t {
        MavMissionType::MAV_MISSION_TYPE_FENCE => 1,
        MavMissionType::MAV_MISSION_TYPE_RALLY => 2,
        _ => 0,
    }
}

/// Which autopilot the model plays.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    ArduPilot,
    Px4,
}

/// An upload the autopilot is receiving.
#[derive(Debug, Clone)]
struct Receiving {
    partner: (u8, u8),
    mission_type: MavMissionType,
    /// First and last seq asked for (a partial write: a range of the stored plan).
    first: u16,
    last: Option<u16>,
    items: Vec<MISSION_ITEM_INT_DATA>,
    next: u16,
    asked_at: Instant,
    started: Instant,
    partial: bool,
}

/// What the autopilot acked ACCEPTED, and the plan it then held: for the invariant.
#[derive(Debug, Clone)]
struct Acceptance {
    mission_type: MavMissionType,
    plan: Vec<MISSION_ITEM_INT_DATA>,
    at: Instant,
}

/// A model autopilot on the bridge's serial port: what both real ones do on the wire with
/// the mission protocol, one plan per type stored atomically at the end of an upload.
struct Fc {
    kind: Kind,
    sender: Sender,
    reader: FrameReader,
    out: VecDeque<OwnedFrame>,
    plans: [Vec<MISSION_ITEM_INT_DATA>; 3],
    upload: Option<Receiving>,
    /// An upload complete, stored after `store_delay` (a slow flash write): the autopilot's
    /// MAVLink thread is busy until then, what arrives meanwhile waits.
    storing: Option<(Instant, Receiving)>,
    backlog: VecDeque<((u8, u8), MavMessage)>,
    store_delay: Duration,
    next_heartbeat: Instant,
    accepted: Vec<Acceptance>,
    /// Every message the bridge sent it.
    got: Vec<MavMessage>,
}

impl Fc {
    fn new(kind: Kind, version: MavlinkVersion) -> Self {
        Self {
            kind,
            sender: Sender::new(VEHICLE.0, VEHICLE.1, version),
            reader: FrameReader::new(),
            out: VecDeque::new(),
            plans: Default::default(),
            upload: None,
            storing: None,
            backlog: VecDeque::new(),
            store_delay: Duration::ZERO,
            next_heartbeat: Instant::ZERO,
            accepted: Vec::new(),
            got: Vec::new(),
        }
    }

    fn plan(&self, t: MavMissionType) -> &[MISSION_ITEM_INT_DATA] {
        &self.plans[slot(t)]
    }

    fn send(&mut self, msg: MavMessage) {
        let f = self.sender.frame(&msg);
        self.out.push_back(f);
    }

    fn ack(&mut self, to: (u8, u8), t: MavMissionType, result: MavMissionResult, opaque_id: u32) {
        self.send(MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: to.0,
            target_component: to.1,
            mavtype: result,
            mission_type: t,
            opaque_id,
            ..Default::default()
        }));
    }

    fn request(&mut self, to: (u8, u8), t: MavMissionType, seq: u16) {
        self.send(MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            target_system: to.0,
            target_component: to.1,
            seq,
            mission_type: t,
            ..Default::default()
        }));
    }

    /// The id an ACCEPTED carries: ArduPilot none, PX4 its CRC of the plan (never 0 here).
    fn opaque(&self, t: MavMissionType, plan: &[MISSION_ITEM_INT_DATA]) -> u32 {
        match self.kind {
            Kind::ArduPilot => 0,
            Kind::Px4 => plan_hash(t, plan) | 1,
        }
    }

    fn bytes(&mut self, now: Instant, bytes: &[u8]) {
        self.reader.push(bytes);
        while let Some(rx) = self.reader.next_frame() {
            let from = (rx.frame.system_id(), rx.frame.component_id());
            if let Ok(msg) = rx.frame.decode::<MavMessage>() {
                self.got.push(msg.clone());
                if self.storing.is_some() {
                    self.backlog.push_back((from, msg));
                } else {
                    self.handle(now, from, msg);
                }
            }
        }
    }

    fn handle(&mut self, now: Instant, from: (u8, u8), msg: MavMessage) {
        match msg {
            MavMessage::MISSION_COUNT(c) if c.target_system == VEHICLE.0 => {
                let t = c.mission_type;
                if let Some(up) = &self.upload
                    && (up.partner != from || self.kind == Kind::Px4)
                {
                    if self.kind == Kind::Px4 && up.partner == from && up.next == 0 {
                        // PX4: "our request was lost": ask again.
                        let (p, ty) = (up.partner, up.mission_type);
                        self.request(p, ty, 0);
                        return;
                    }
                    // ArduPilot refuses another partner; PX4 any second count, with an error.
                    let r = match self.kind {
                        Kind::ArduPilot => MavMissionResult::MAV_MISSION_DENIED,
                        Kind::Px4 => MavMissionResult::MAV_MISSION_ERROR,
                    };
                    let p = up.partner;
                    self.ack(p, t, r, 0);
                    return;
                }
                if c.count == 0 {
                    self.upload = None;
                    self.plans[slot(t)].clear();
                    self.accepted.push(Acceptance {
                        mission_type: t,
                        plan: Vec::new(),
                        at: now,
                    });
                    self.ack(from, t, ACCEPTED, 0);
                    return;
                }
                self.upload = Some(Receiving {
                    partner: from,
                    mission_type: t,
                    first: 0,
                    last: Some(c.count - 1),
                    items: Vec::new(),
                    next: 0,
                    asked_at: now,
                    started: now,
                    partial: false,
                });
                self.request(from, t, 0);
            }
            MavMessage::MISSION_WRITE_PARTIAL_LIST(w) if self.kind == Kind::ArduPilot => {
                let t = w.mission_type;
                let len = self.plan(t).len() as i16;
                if w.start_index < 0 || w.end_index < w.start_index || w.end_index >= len {
                    self.ack(from, t, MavMissionResult::MAV_MISSION_ERROR, 0);
                    return;
                }
                self.upload = Some(Receiving {
                    partner: from,
                    mission_type: t,
                    first: w.start_index as u16,
                    last: Some(w.end_index as u16),
                    items: Vec::new(),
                    next: w.start_index as u16,
                    asked_at: now,
                    started: now,
                    partial: true,
                });
                self.request(from, t, w.start_index as u16);
            }
            MavMessage::MISSION_ITEM_INT(item) if item.target_system == VEHICLE.0 => {
                let Some(up) = &mut self.upload else {
                    return;
                };
                if from != up.partner || item.mission_type != up.mission_type {
                    return;
                }
                if item.seq != up.next {
                    if self.kind == Kind::ArduPilot {
                        let (p, t) = (up.partner, up.mission_type);
                        self.ack(p, t, MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, 0);
                    }
                    return;
                }
                up.items.push(item);
                up.next += 1;
                up.asked_at = now;
                if Some(up.next - 1) == up.last {
                    let done = self.upload.take().unwrap();
                    self.storing = Some((now + self.store_delay, done));
                } else {
                    let (p, t, n) = (up.partner, up.mission_type, up.next);
                    self.request(p, t, n);
                }
            }
            // PX4 ends an upload on its partner's cancel; ArduPilot ignores it.
            MavMessage::MISSION_ACK(a)
                if a.target_system == VEHICLE.0
                    && a.mavtype == MavMissionResult::MAV_MISSION_OPERATION_CANCELLED
                    && self.kind == Kind::Px4
                    && self.upload.as_ref().is_some_and(|u| u.partner == from) =>
            {
                self.upload = None;
            }
            MavMessage::MISSION_CLEAR_ALL(c) if c.target_system == VEHICLE.0 => {
                let t = c.mission_type;
                if t == MavMissionType::MAV_MISSION_TYPE_ALL {
                    self.plans = Default::default();
                } else {
                    self.plans[slot(t)].clear();
                }
                // PX4 1.16 names the (now empty) plan in its ack.
                let id = match self.kind {
                    Kind::ArduPilot => 0,
                    Kind::Px4 => 0x00C1_EA11,
                };
                self.ack(from, t, ACCEPTED, id);
            }
            _ => {}
        }
    }

    fn tick(&mut self, now: Instant) {
        if now >= self.next_heartbeat {
            self.next_heartbeat = now + Duration::from_secs(1);
            self.send(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: match self.kind {
                    Kind::ArduPilot => MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                    Kind::Px4 => MavAutopilot::MAV_AUTOPILOT_PX4,
                },
                mavlink_version: 3,
                ..Default::default()
            }));
        }
        if let Some((at, _)) = &self.storing
            && now >= *at
        {
            let (_, done) = self.storing.take().unwrap();
            let t = done.mission_type;
            let plan = if done.partial {
                let mut p = self.plans[slot(t)].clone();
                for (k, item) in done.items.iter().enumerate() {
                    p[usize::from(done.first) + k] = item.clone();
                }
                p
            } else {
                done.items.clone()
            };
            self.plans[slot(t)] = plan.clone();
            let id = self.opaque(t, &plan);
            self.accepted.push(Acceptance {
                mission_type: t,
                plan,
                at: now,
            });
            self.ack(done.partner, t, ACCEPTED, id);
            while self.storing.is_none()
                && let Some((from, msg)) = self.backlog.pop_front()
            {
                self.handle(now, from, msg);
            }
        }
        let retry = match self.kind {
            Kind::ArduPilot => Duration::from_secs(1),
            Kind::Px4 => Duration::from_millis(250),
        };
        if let Some(up) = &mut self.upload {
            if now.saturating_duration_since(up.started) > Duration::from_secs(30)
                && now.saturating_duration_since(up.asked_at) > Duration::from_secs(5)
            {
                self.upload = None;
            } else if now >= up.asked_at + retry {
                up.asked_at = now;
                let (p, t, n) = (up.partner, up.mission_type, up.next);
                self.request(p, t, n);
            }
        }
    }
}

/// How a ground station counts the vehicle's repeated requests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Retries {
    /// A repeated request restarts its timer (QGroundControl, pymavlink scripts).
    Refresh,
    /// Each repeated request is a retry, as a timeout is (MAVSDK).
    Mavsdk,
}

/// A ground station's upload in progress.
struct GroundUpload {
    mission_type: MavMissionType,
    items: Vec<MISSION_ITEM_INT_DATA>,
    /// Items sent: the next one to send.
    next: u16,
    retries: u32,
    at: Instant,
    /// Send legacy `MISSION_ITEM`s.
    legacy: bool,
}

/// An upload a ground station started: type, plan, and the answer it took for it.
type Upload = (
    MavMissionType,
    Vec<MISSION_ITEM_INT_DATA>,
    Option<(MavMissionResult, Instant)>,
);

/// A ground station on the router's ground side.
struct Ground {
    id: (u8, u8),
    sender: Sender,
    reader: FrameReader,
    out: VecDeque<OwnedFrame>,
    upload: Option<GroundUpload>,
    timeout: Duration,
    max_retries: u32,
    rule: Retries,
    /// Results of uploads, in order: (result, when).
    results: Vec<(MavMissionResult, Instant)>,
    /// Every message it received from the vehicle side.
    got: Vec<MavMessage>,
    /// The last plan it uploaded of each type.
    last: [Option<Vec<MISSION_ITEM_INT_DATA>>; 3],
    /// Every upload it started: type, plan, and the answer it took for it.
    uploads: Vec<Upload>,
}

impl Ground {
    fn new(id: (u8, u8)) -> Self {
        Self {
            id,
            sender: Sender::new(id.0, id.1, MavlinkVersion::V2),
            reader: FrameReader::new(),
            out: VecDeque::new(),
            upload: None,
            timeout: Duration::from_millis(1500),
            max_retries: 5,
            rule: Retries::Refresh,
            results: Vec::new(),
            got: Vec::new(),
            last: Default::default(),
            uploads: Vec::new(),
        }
    }

    fn mavsdk() -> Self {
        Self {
            timeout: Duration::from_millis(500),
            rule: Retries::Mavsdk,
            ..Self::new(MAVSDK)
        }
    }

    fn send(&mut self, msg: MavMessage) {
        let f = self.sender.frame(&msg);
        self.out.push_back(f);
    }

    fn count(&mut self, t: MavMissionType, n: u16) {
        self.send(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            target_system: VEHICLE.0,
            target_component: VEHICLE.1,
            count: n,
            mission_type: t,
            ..Default::default()
        }));
    }

    fn upload(&mut self, now: Instant, t: MavMissionType, items: Vec<MISSION_ITEM_INT_DATA>) {
        self.last[slot(t)] = Some(items.clone());
        self.uploads.push((t, items.clone(), None));
        self.count(t, items.len() as u16);
        self.upload = Some(GroundUpload {
            mission_type: t,
            items,
            next: 0,
            retries: 0,
            at: now,
            legacy: false,
        });
    }

    fn send_item(&mut self, seq: u16) {
        let up = self.upload.as_ref().unwrap();
        let item = MISSION_ITEM_INT_DATA {
            target_system: VEHICLE.0,
            target_component: VEHICLE.1,
            ..up.items[usize::from(seq)].clone()
        };
        let msg = if up.legacy {
            MavMessage::MISSION_ITEM(MISSION_ITEM_DATA {
                seq: item.seq,
                x: item.x as f32 * 1e-7,
                y: item.y as f32 * 1e-7,
                z: item.z,
                command: item.command,
                frame: item.frame,
                autocontinue: item.autocontinue,
                target_system: item.target_system,
                target_component: item.target_component,
                mission_type: item.mission_type,
                ..Default::default()
            })
        } else {
            MavMessage::MISSION_ITEM_INT(item)
        };
        self.send(msg);
    }

    /// The upload in progress ended with `result`.
    fn done(&mut self, result: MavMissionResult, now: Instant) {
        self.results.push((result, now));
        if let Some(last) = self.uploads.last_mut() {
            last.2 = Some((result, now));
        }
    }

    /// Gives its upload up without a word (it does something else now).
    fn abandon(&mut self) {
        self.upload = None;
    }

    fn result(&self) -> Option<MavMissionResult> {
        self.results.last().map(|r| r.0)
    }

    fn bytes(&mut self, now: Instant, bytes: &[u8]) {
        self.reader.push(bytes);
        while let Some(rx) = self.reader.next_frame() {
            let Ok(msg) = rx.frame.decode::<MavMessage>() else {
                continue;
            };
            self.got.push(msg.clone());
            self.handle(now, msg);
        }
    }

    fn handle(&mut self, now: Instant, msg: MavMessage) {
        let id = self.id;
        let Some(up) = &mut self.upload else {
            return;
        };
        match msg {
            MavMessage::MISSION_REQUEST_INT(r)
                if r.target_system == id.0 && r.mission_type == up.mission_type =>
            {
                if usize::from(r.seq) >= up.items.len() {
                    return;
                }
                if r.seq >= up.next {
                    // MAVSDK counts the first send of an item as one of its tries too.
                    up.retries = u32::from(self.rule == Retries::Mavsdk);
                    up.next = r.seq + 1;
                } else if self.rule == Retries::Mavsdk {
                    // MAVSDK: a request for an item already sent is a retry.
                    if up.retries >= self.max_retries {
                        self.upload = None;
                        self.done(MavMissionResult::MAV_MISSION_ERROR, now);
                        return;
                    }
                    up.retries += 1;
                }
                up.at = now;
                self.send_item(r.seq);
            }
            MavMessage::MISSION_ACK(a)
                if a.target_system == id.0 && a.mission_type == up.mission_type =>
            {
                self.upload = None;
                self.done(a.mavtype, now);
            }
            _ => {}
        }
    }

    fn tick(&mut self, now: Instant) {
        let Some(up) = &mut self.upload else {
            return;
        };
        if now < up.at + self.timeout {
            return;
        }
        if up.retries >= self.max_retries {
            // Gives up without a word, as MAVSDK does.
            self.upload = None;
            self.done(MavMissionResult::MAV_MISSION_OPERATION_CANCELLED, now);
            return;
        }
        up.retries += 1;
        up.at = now;
        let (t, n, next) = (up.mission_type, up.items.len() as u16, up.next);
        match (self.rule, next) {
            (_, 0) => self.count(t, n),
            // MAVSDK waits for the next request without sending anything.
            (Retries::Mavsdk, _) => {}
            (Retries::Refresh, _) => self.send_item(next - 1),
        }
    }
}

/// Router and bridge engines joined by a radio of fixed latency, an autopilot model on the
/// bridge, ground stations on the router.
struct World {
    now: Instant,
    router: Router,
    bridge: Bridge,
    fc: Fc,
    grounds: Vec<Ground>,
    latency: Duration,
    /// Frames in the air: (arrival, towards the bridge, bytes).
    air: VecDeque<(Instant, bool, Vec<u8>)>,
    /// Each frame is lost with this probability (xorshift state).
    loss: f64,
    rng: u64,
}

fn budget() -> SchedulerConfig {
    SchedulerConfig {
        rate_bytes_per_s: 2000,
        burst_bytes: 600,
        max_queued_bytes: 16_000,
    }
}

fn router_config() -> RouterConfig {
    RouterConfig::new(budget())
}

impl World {
    fn new(fc: Fc) -> Self {
        let bridge = Bridge::new(
            BridgeConfig::new(Profile::parse("", "all passes").unwrap(), budget()),
            Instant::ZERO,
        )
        .unwrap();
        Self {
            now: Instant::ZERO,
            router: Router::new(router_config(), Instant::ZERO).unwrap(),
            bridge,
            fc,
            grounds: vec![Ground::new(GROUND)],
            latency: Duration::from_millis(100),
            air: VecDeque::new(),
            loss: 0.0,
            rng: 0x9E37_79B9_7F4A_7C15,
        }
    }

    fn lost(&mut self) -> bool {
        if self.loss == 0.0 {
            return false;
        }
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 7;
        self.rng ^= self.rng << 17;
        ((self.rng >> 11) as f64 / (1u64 << 53) as f64) < self.loss
    }

    /// One 5 ms step of everything.
    fn step(&mut self) {
        self.now += Duration::from_millis(5);
        let now = self.now;
        self.fc.tick(now);
        while let Some(f) = self.fc.out.pop_front() {
            self.bridge.handle_fc_bytes(now, f.as_bytes());
        }
        for g in &mut self.grounds {
            g.tick(now);
            while let Some(f) = g.out.pop_front() {
                let _ = self.router.handle_gcs_bytes(now, f.as_bytes());
            }
        }
        while self.air.front().is_some_and(|(at, _, _)| *at <= now) {
            let (_, up, bytes) = self.air.pop_front().unwrap();
            if up {
                self.bridge.handle_radio_bytes(now, &bytes);
            } else {
                self.router.handle_radio_bytes(now, &bytes);
            }
        }
        self.bridge.handle_timeout(now);
        self.router.handle_timeout(now);
        while let Some(f) = self.bridge.poll_radio_transmit(now, 4096) {
            if !self.lost() {
                let at = now + self.latency;
                self.air.push_back((at, false, f.as_bytes().to_vec()));
            }
        }
        while let Some(f) = self.router.poll_radio_transmit(now, 4096) {
            if !self.lost() {
                let at = now + self.latency;
                self.air.push_back((at, true, f.as_bytes().to_vec()));
            }
        }
        while let Some(f) = self.bridge.poll_fc_transmit(now) {
            self.fc.bytes(now, f.as_bytes());
        }
        while let Some(f) = self.router.poll_gcs_transmit() {
            for g in &mut self.grounds {
                g.bytes(now, f.as_bytes());
            }
        }
    }

    fn run_for(&mut self, d: Duration) {
        let until = self.now + d;
        while self.now < until {
            self.step();
        }
    }

    /// Runs until ground `g` has a result for its upload (at most `limit`).
    fn finish(&mut self, g: usize, limit: Duration) -> Option<MavMissionResult> {
        let until = self.now + limit;
        let before = self.grounds[g].results.len();
        while self.now < until && self.grounds[g].results.len() == before {
            self.step();
        }
        self.grounds[g].results.get(before).map(|r| r.0)
    }

    /// A router started again (killed and restarted: what was in its queues is gone).
    fn restart_router(&mut self) {
        self.air.retain(|(_, up, _)| !*up);
        self.router = Router::new(router_config(), self.now).unwrap();
    }

    /// The invariant after ground `g`'s upload of `t` ended with `result`: ACCEPTED iff the
    /// autopilot acked, after receiving every item, exactly the plan the ground sent, and
    /// holds it.
    fn check(&self, g: usize, t: MavMissionType, result: Option<MavMissionResult>) {
        let sent = self.grounds[g].last[slot(t)].clone().unwrap();
        let holds = same_plan(self.fc.plan(t), &sent);
        let acked = self
            .fc
            .accepted
            .iter()
            .any(|a| a.mission_type == t && same_plan(&a.plan, &sent));
        if result == Some(ACCEPTED) {
            assert!(
                holds && acked,
                "ground told ACCEPTED; the autopilot holds the plan: {holds}, acked it: {acked}"
            );
        }
    }
}

fn plan(n: u16, salt: i32, t: MavMissionType) -> Vec<MISSION_ITEM_INT_DATA> {
    (0..n)
        .map(|seq| MISSION_ITEM_INT_DATA {
            seq,
            x: 553_700_000 + i32::from(seq) * 1000 + salt,
            y: 103_000_000 + salt,
            z: 50.0,
            mission_type: t,
            autocontinue: 1,
            ..Default::default()
        })
        .collect()
}

/// The frames ground `g` got of one kind.
fn acks_at(w: &World, g: usize) -> Vec<MavMissionResult> {
    w.grounds[g]
        .got
        .iter()
        .filter_map(|m| match m {
            MavMessage::MISSION_ACK(a) => Some(a.mavtype),
            _ => None,
        })
        .collect()
}

fn world(kind: Kind) -> World {
    let mut w = World::new(Fc::new(kind, MavlinkVersion::V2));
    // the autopilot is found and the link carries both ways
    w.run_for(Duration::from_secs(2));
    w
}

#[test]
fn an_upload_reaches_both_autopilots_and_the_ground_hears_accepted() {
    for kind in [Kind::ArduPilot, Kind::Px4] {
        let mut w = world(kind);
        let p = plan(12, 0, MISSION);
        w.grounds[0].upload(w.now, MISSION, p.clone());
        let r = w.finish(0, Duration::from_secs(30));
        assert_eq!(r, Some(ACCEPTED), "{kind:?}");
        w.check(0, MISSION, r);
        assert!(same_plan(w.fc.plan(MISSION), &p));
    }
}

/// Item 1. Regression: while the router took a ground upload it forwarded any vehicle
/// MISSION_ACK whose `opaque_id` was 0 (ArduPilot's always are): the ground heard ACCEPTED,
/// then the real answer, while the autopilot kept its old plan.
#[test]
fn an_autopilot_ack_with_opaque_id_zero_never_answers_a_ground_upload() {
    let mut w = world(Kind::ArduPilot);
    let old = plan(3, 0, MISSION);
    w.fc.plans[0] = old.clone();
    // the autopilot's slow answer to something else, addressed to the ground
    w.fc.store_delay = Duration::from_millis(400);
    let new = plan(6, 77, MISSION);
    w.grounds[0].upload(w.now, MISSION, new.clone());
    for _ in 0..4 {
        w.run_for(Duration::from_millis(60));
        w.fc.ack(GROUND, MISSION, ACCEPTED, 0);
    }
    let r = w.finish(0, Duration::from_secs(30));
    w.check(0, MISSION, r);
    assert_eq!(r, Some(ACCEPTED));
    assert_eq!(
        acks_at(&w, 0),
        vec![ACCEPTED],
        "one answer, the vehicle's to this upload"
    );
    assert!(same_plan(w.fc.plan(MISSION), &new));
    assert!(w.router.stats().mission.vehicle_acks_held >= 4);
}

/// Item 2. Regression: the bridge's upload to the autopilot ended on any MISSION_ACK of that
/// type, even before the autopilot asked for the last item: an autopilot storing plan A
/// slowly acked A after plan B's count, the ground was told B was ACCEPTED, and the
/// autopilot never got B's items.
#[test]
fn a_slow_ack_of_the_previous_plan_is_not_the_answer_to_the_next() {
    for kind in [Kind::ArduPilot, Kind::Px4] {
        let mut w = world(kind);
        w.fc.store_delay = Duration::from_millis(1500);
        let a = plan(8, 1, MISSION);
        w.grounds[0].upload(w.now, MISSION, a.clone());
        // plan A is in the autopilot and being stored when the ground sends plan B
        let until = w.now + Duration::from_secs(10);
        while w.fc.storing.is_none() && w.now < until {
            w.step();
        }
        assert!(w.fc.storing.is_some(), "{kind:?}: A reached the autopilot");
        let b = plan(5, 2, MISSION);
        w.grounds[0].upload(w.now, MISSION, b.clone());
        let r = w.finish(0, Duration::from_secs(30));
        w.check(0, MISSION, r);
        // the store of A finished after B's count went out; B followed
        w.run_for(Duration::from_secs(5));
        assert!(
            r != Some(ACCEPTED) || same_plan(w.fc.plan(MISSION), &b),
            "{kind:?}: ground told ACCEPTED, autopilot holds {:?}",
            w.fc.plan(MISSION).len()
        );
        assert_eq!(r, Some(ACCEPTED), "{kind:?}");
    }
}

/// Item 3. Regression: the bridge answered a MISSION_COUNT whose transfer id matched its
/// last finished transfer from memory, and transfer ids restarted with the router: upload
/// A, MISSION_CLEAR_ALL, restart the router, upload A again: ACCEPTED at once, no count
/// reached the autopilot, which held nothing.
#[test]
fn after_a_clear_all_and_a_router_restart_the_same_plan_is_uploaded_again() {
    let mut w = world(Kind::ArduPilot);
    let a = plan(6, 3, MISSION);
    w.grounds[0].upload(w.now, MISSION, a.clone());
    assert_eq!(w.finish(0, Duration::from_secs(30)), Some(ACCEPTED));
    w.grounds[0].send(MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
        target_system: VEHICLE.0,
        target_component: VEHICLE.1,
        mission_type: MISSION,
        ..Default::default()
    }));
    w.run_for(Duration::from_secs(2));
    assert!(w.fc.plan(MISSION).is_empty(), "cleared");
    w.restart_router();
    w.run_for(Duration::from_secs(2));
    let counts_before =
        w.fc.got
            .iter()
            .filter(|m| matches!(m, MavMessage::MISSION_COUNT(_)))
            .count();
    w.grounds[0].upload(w.now, MISSION, a.clone());
    let r = w.finish(0, Duration::from_secs(30));
    w.check(0, MISSION, r);
    let counts_after =
        w.fc.got
            .iter()
            .filter(|m| matches!(m, MavMessage::MISSION_COUNT(_)))
            .count();
    assert_eq!(
        counts_after,
        counts_before + 1,
        "the autopilot got the upload"
    );
    assert_eq!(r, Some(ACCEPTED));
    assert!(same_plan(w.fc.plan(MISSION), &a));
}

/// Item 4. Regression: with a MAVLink 1 autopilot `mission_type` was lost converting
/// frames: a fence MISSION_CLEAR_ALL or an empty fence upload reached it as a mission
/// operation and deleted the flight plan. Both are refused with MAV_MISSION_UNSUPPORTED.
#[test]
fn fence_operations_never_touch_a_mavlink1_autopilots_mission() {
    let mut w = World::new(Fc::new(Kind::ArduPilot, MavlinkVersion::V1));
    w.run_for(Duration::from_secs(2));
    let mission = plan(4, 5, MISSION);
    w.fc.plans[0] = mission.clone();
    // a fence clear-all, passed through by the router
    w.grounds[0].send(MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
        target_system: VEHICLE.0,
        target_component: VEHICLE.1,
        mission_type: FENCE,
        ..Default::default()
    }));
    w.run_for(Duration::from_secs(2));
    assert!(same_plan(w.fc.plan(MISSION), &mission), "clear-all");
    assert_eq!(
        acks_at(&w, 0),
        vec![MavMissionResult::MAV_MISSION_UNSUPPORTED]
    );
    // an empty fence upload and a fence upload, relayed
    for n in [0, 3] {
        w.grounds[0].upload(w.now, FENCE, plan(n, 9, FENCE));
        let r = w.finish(0, Duration::from_secs(30));
        assert_eq!(
            r,
            Some(MavMissionResult::MAV_MISSION_UNSUPPORTED),
            "{n} items"
        );
        assert!(same_plan(w.fc.plan(MISSION), &mission), "{n} fence items");
    }
    assert!(
        !w.fc.got.iter().any(|m| matches!(
            m,
            MavMessage::MISSION_COUNT(_) | MavMessage::MISSION_CLEAR_ALL(_)
        )),
        "nothing of it reached the autopilot"
    );
    // the mission itself still goes
    let p = plan(3, 11, MISSION);
    w.grounds[0].upload(w.now, MISSION, p.clone());
    assert_eq!(w.finish(0, Duration::from_secs(30)), Some(ACCEPTED));
    assert!(same_plan(w.fc.plan(MISSION), &p));
}

/// Item 5: a partial write completes end to end. Regression: the router consumed the
/// autopilot's MISSION_REQUEST_INTs (they looked like the bridge's), and the bridge took the
/// ground's items for its own stream.
#[test]
fn a_partial_write_completes_through_router_and_bridge() {
    let mut w = world(Kind::ArduPilot);
    // after an upload of the same ground (its answer still held for a repeat of its item)
    let mut stored = plan(6, 0, MISSION);
    w.grounds[0].upload(w.now, MISSION, stored.clone());
    assert_eq!(w.finish(0, Duration::from_secs(30)), Some(ACCEPTED));
    w.grounds[0].got.clear();
    w.grounds[0].send(MavMessage::MISSION_WRITE_PARTIAL_LIST(
        MISSION_WRITE_PARTIAL_LIST_DATA {
            target_system: VEHICLE.0,
            target_component: VEHICLE.1,
            start_index: 2,
            end_index: 3,
            mission_type: MISSION,
            ..Default::default()
        },
    ));
    let replaced = plan(6, 500, MISSION);
    let until = w.now + Duration::from_secs(10);
    let mut answered = 0;
    while w.now < until && acks_at(&w, 0).is_empty() {
        w.step();
        let asked: Vec<u16> = w.grounds[0]
            .got
            .iter()
            .filter_map(|m| match m {
                MavMessage::MISSION_REQUEST_INT(r) => Some(r.seq),
                _ => None,
            })
            .collect();
        for seq in asked.into_iter().skip(answered) {
            answered += 1;
            w.grounds[0].send(MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                target_system: VEHICLE.0,
                target_component: VEHICLE.1,
                ..replaced[usize::from(seq)].clone()
            }));
        }
    }
    assert_eq!(acks_at(&w, 0), vec![ACCEPTED]);
    stored[2] = replaced[2].clone();
    stored[3] = replaced[3].clone();
    assert!(same_plan(w.fc.plan(MISSION), &stored));
}

/// Item 5. Regression: the router swallowed a MISSION_ACK with `opaque_id` ≠ 0 (PX4 names
/// the cleared plan) answering a ground's MISSION_CLEAR_ALL.
#[test]
fn a_clear_all_ack_with_an_opaque_id_reaches_the_ground() {
    let mut w = world(Kind::Px4);
    w.fc.plans[0] = plan(3, 0, MISSION);
    w.grounds[0].send(MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
        target_system: VEHICLE.0,
        target_component: VEHICLE.1,
        mission_type: MISSION,
        ..Default::default()
    }));
    w.run_for(Duration::from_secs(2));
    assert_eq!(acks_at(&w, 0), vec![ACCEPTED]);
    assert!(w.fc.plan(MISSION).is_empty());
}

/// Item 5. Regression: a legacy MISSION_ITEM from a ground station leaked to the autopilot
/// and the upload ended without an ack. It is refused with MAV_MISSION_UNSUPPORTED.
#[test]
fn a_legacy_mission_item_upload_is_refused_and_never_reaches_the_autopilot() {
    let mut w = world(Kind::ArduPilot);
    let old = plan(2, 0, MISSION);
    w.fc.plans[0] = old.clone();
    w.grounds[0].upload(w.now, MISSION, plan(3, 1, MISSION));
    w.grounds[0].upload.as_mut().unwrap().legacy = true;
    let r = w.finish(0, Duration::from_secs(20));
    assert_eq!(r, Some(MavMissionResult::MAV_MISSION_UNSUPPORTED));
    assert!(
        !w.fc.got.iter().any(|m| matches!(
            m,
            MavMessage::MISSION_ITEM(_) | MavMessage::MISSION_COUNT(_)
        )),
        "nothing of it reached the autopilot"
    );
    assert!(same_plan(w.fc.plan(MISSION), &old));
}

/// Item 5. Regression: `item.seq + 1` overflowed: one ground frame (seq 65535) panicked a
/// debug build, mid-upload and after it.
#[test]
fn an_item_numbered_65535_is_harmless() {
    let mut w = world(Kind::ArduPilot);
    let item = |seq| {
        MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
            seq,
            target_system: VEHICLE.0,
            target_component: VEHICLE.1,
            ..Default::default()
        })
    };
    w.grounds[0].count(MISSION, 2);
    w.run_for(Duration::from_millis(50));
    w.grounds[0].send(item(u16::MAX));
    w.run_for(Duration::from_millis(50));
    // and once the upload is over (an empty plan: count 0)
    w.grounds[0].upload(w.now, MISSION, Vec::new());
    assert_eq!(w.finish(0, Duration::from_secs(20)), Some(ACCEPTED));
    w.grounds[0].send(item(u16::MAX));
    w.run_for(Duration::from_millis(50));
}

/// Item 6. Regression: MAVSDK uploads failed. With the plan in, the router re-requested the
/// last item every 250 ms while the vehicle side worked; MAVSDK counts each repeat against
/// its 5 retries, so it gave up after ~1.25 s without a cancel while the vehicle went on to
/// take the plan. Now the ground waits on its own timeouts (MAVSDK: 0.5 s, 5 retries).
#[test]
fn mavsdk_waits_for_a_vehicle_that_takes_two_seconds() {
    let mut w = world(Kind::Px4);
    w.grounds = vec![Ground::mavsdk()];
    w.latency = Duration::from_millis(300);
    w.fc.store_delay = Duration::from_millis(600);
    let p = plan(20, 4, MISSION);
    w.grounds[0].upload(w.now, MISSION, p.clone());
    let r = w.finish(0, Duration::from_secs(30));
    w.check(0, MISSION, r);
    assert_eq!(r, Some(ACCEPTED));
    let repeats = w.grounds[0]
        .got
        .iter()
        .filter(|m| matches!(m, MavMessage::MISSION_REQUEST_INT(_)))
        .count();
    assert_eq!(repeats, 20, "each item asked for once");
}

/// The other kind of ground (QGroundControl, pymavlink scripts, SDKs with 0.5 s x 3): it
/// resends its last item when its timer fires, and a request for it restarts its timer.
/// Its first retry shows its period; from then on it is kept waiting however long the
/// vehicle takes (5 s here), having spent one retry of its own.
#[test]
fn an_impatient_ground_that_resends_is_kept_waiting_for_a_slow_vehicle() {
    let mut w = world(Kind::Px4);
    w.grounds[0].timeout = Duration::from_millis(500);
    w.grounds[0].max_retries = 3;
    w.fc.store_delay = Duration::from_secs(5);
    let p = plan(20, 12, MISSION);
    w.grounds[0].upload(w.now, MISSION, p.clone());
    let r = w.finish(0, Duration::from_secs(30));
    w.check(0, MISSION, r);
    assert_eq!(r, Some(ACCEPTED));
    assert!(w.router.stats().mission.keepalives > 5);
}

/// Item 7. Regression: a second MISSION_COUNT silently dropped the upload in progress.
/// A count from another ground station while one uploads is refused (MAV_MISSION_DENIED,
/// as autopilots refuse a second partner) and the first upload completes.
#[test]
fn a_second_ground_cannot_drop_the_upload_in_progress() {
    let mut w = world(Kind::Px4);
    w.grounds.push(Ground::mavsdk());
    let first = plan(10, 6, MISSION);
    w.grounds[0].upload(w.now, MISSION, first.clone());
    w.run_for(Duration::from_millis(20));
    w.grounds[1].upload(w.now, MISSION, plan(10, 7, MISSION));
    let r = w.finish(0, Duration::from_secs(30));
    w.check(0, MISSION, r);
    assert_eq!(r, Some(ACCEPTED), "the first upload completes");
    assert!(same_plan(w.fc.plan(MISSION), &first));
    assert_eq!(
        w.grounds[1].result(),
        Some(MavMissionResult::MAV_MISSION_DENIED),
        "the second ground is told"
    );
}

/// The same ground starting over with another plan (it gave up, or the operator edited the
/// plan) still replaces its own upload, as ArduPilot lets its partner restart.
#[test]
fn the_same_ground_may_start_over() {
    let mut w = world(Kind::Px4);
    w.grounds[0].upload(w.now, MISSION, plan(10, 8, MISSION));
    w.run_for(Duration::from_millis(15));
    let second = plan(10, 9, MISSION);
    w.grounds[0].upload(w.now, MISSION, second.clone());
    let r = w.finish(0, Duration::from_secs(30));
    w.check(0, MISSION, r);
    assert_eq!(r, Some(ACCEPTED));
    assert!(same_plan(w.fc.plan(MISSION), &second));
}

/// What a ground may do next in the property.
#[derive(Debug, Clone)]
enum Op {
    Upload { n: u16, salt: i32, fence: bool },
    ClearAll,
    Wait { ms: u64 },
    RestartRouter,
    StrayAck,
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => (0u16..12, 0i32..1000, prop::bool::weighted(0.2))
            .prop_map(|(n, salt, fence)| Op::Upload { n, salt, fence }),
        1 => Just(Op::ClearAll),
        3 => (0u64..3000).prop_map(|ms| Op::Wait { ms }),
        1 => Just(Op::RestartRouter),
        1 => Just(Op::StrayAck),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Whatever the ground does (uploads that replace each other, clear-alls, router
    /// restarts, autopilot acks to nothing, on a link losing frames), every ACCEPTED the
    /// ground hears is for the plan the autopilot acked after receiving every item, and
    /// holds.
    #[test]
    fn accepted_only_for_the_plan_the_autopilot_acked_after_every_item(
        px4 in any::<bool>(),
        store_ms in 0u64..1500,
        loss in prop::sample::select(vec![0.0, 0.05, 0.15]),
        ops in prop::collection::vec(op(), 1..8),
    ) {
        let kind = if px4 { Kind::Px4 } else { Kind::ArduPilot };
        let mut w = world(kind);
        w.loss = loss;
        w.fc.store_delay = Duration::from_millis(store_ms);
        for op in ops {
            match op {
                Op::Upload { n, salt, fence } => {
                    let t = if fence { FENCE } else { MISSION };
                    w.grounds[0].upload(w.now, t, plan(n, salt, t));
                }
                Op::ClearAll => {
                    w.grounds[0].abandon();
                    w.grounds[0].send(MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
                        target_system: VEHICLE.0,
                        target_component: VEHICLE.1,
                        mission_type: MISSION,
                        ..Default::default()
                    }));
                }
                Op::Wait { ms } => w.run_for(Duration::from_millis(ms)),
                Op::RestartRouter => w.restart_router(),
                Op::StrayAck => w.fc.ack(GROUND, MISSION, ACCEPTED, 0),
            }
            w.run_for(Duration::from_millis(20));
            check_results(&w);
        }
        w.run_for(Duration::from_secs(30));
        check_results(&w);
    }
}

/// Every upload the ground was told ACCEPTED for: the autopilot acked exactly that plan,
/// after receiving every item, before the ground heard it.
fn check_results(w: &World) {
    for (t, sent, answer) in &w.grounds[0].uploads {
        let Some((ACCEPTED, told_at)) = answer else {
            continue;
        };
        let acked =
            w.fc.accepted
                .iter()
                .any(|a| a.mission_type == *t && a.at <= *told_at && same_plan(&a.plan, sent));
        assert!(
            acked,
            "ground told ACCEPTED at {told_at} for a {t:?} plan of {} items the autopilot never acked",
            sent.len()
        );
    }
}
