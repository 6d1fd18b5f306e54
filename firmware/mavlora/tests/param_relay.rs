//! A parameter list through the bridge and router engines on a virtual clock: a model
//! autopilot streams its list (`PARAM_REQUEST_LIST`), answers reads by index and echoes sets
//! (ArduPilot's way, index 65535); a QGroundControl-like ground station asks for the list,
//! and once it has been quiet for 1 s reads what is missing by index (10 at a time, each
//! again after 1 s). The bridge packs the list (`MAVLORA_PARAM_VALUES`), the router gives
//! the ground the standard `PARAM_VALUE`s back.
//!
//! What must hold: every value reaches the ground byte for byte as the autopilot sent it
//! (name, value bits, type, count, index) from the autopilot's ids; a lost packed frame is
//! repaired the standard way; the answer to a `PARAM_SET` overtakes the list, and no older
//! copy of that parameter from the list follows it.
//!
//! Sans-IO, as the engines: bytes and `now` in, bytes out; the radio is a queue with a fixed
//! latency and an optional loss of chosen frames; nothing sleeps.

use std::collections::{BTreeMap, VecDeque};

use mavlink::MavlinkVersion;
use proptest::prelude::*;

use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::dialect::{
    HEARTBEAT_DATA, MavAutopilot, MavMessage, MavParamType, MavType, PARAM_REQUEST_LIST_DATA,
    PARAM_REQUEST_READ_DATA, PARAM_SET_DATA,
};
use mavlora::filter::Profile;
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::SchedulerConfig;
use mavlora::signing::{SigningConfig, SigningKey, SigningState};
use mavlora::wire::{FrameReader, OwnedFrame, Sender, ids, known};
use mavlora::{Duration, Instant};

/// One parameter as the autopilot holds it: its `PARAM_VALUE` payload without count and
/// index (name, value bytes, type).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Param {
    name: [u8; 16],
    value: [u8; 4],
    param_type: u8,
}

/// The payload the autopilot sends for parameter `index` of `count`, laid out by hand from
/// the spec (value, count, index, name, type).
fn payload(p: &Param, count: u16, index: u16) -> [u8; 25] {
    let mut out = [0u8; 25];
    out[..4].copy_from_slice(&p.value);
    out[4..6].copy_from_slice(&count.to_le_bytes());
    out[6..8].copy_from_slice(&index.to_le_bytes());
    out[8..24].copy_from_slice(&p.name);
    out[24] = p.param_type;
    out
}

/// A `PARAM_VALUE` frame built from raw bytes (any type byte, any value bits): MAVLink 1 in
/// full, MAVLink 2 with trailing zeros trimmed.
fn raw_frame(version: MavlinkVersion, from: (u8, u8), seq: u8, payload: &[u8; 25]) -> Vec<u8> {
    let mut bytes = match version {
        MavlinkVersion::V1 => {
            let mut b = vec![0xFE, 25, seq, from.0, from.1, 22];
            b.extend_from_slice(payload);
            b
        }
        MavlinkVersion::V2 => {
            let len = payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
            let mut b = vec![0xFD, len as u8, 0, 0, seq, from.0, from.1, 22, 0, 0];
            b.extend_from_slice(&payload[..len]);
            b
        }
    };
    let crc = mavlink::calculate_crc(&bytes[1..], known::crc_extra(22).unwrap());
    bytes.extend_from_slice(&crc.to_le_bytes());
    bytes
}

fn name(text: &[u8]) -> [u8; 16] {
    let mut n = [0u8; 16];
    n[..text.len()].copy_from_slice(text);
    n
}

/// A model autopilot: streams its list at `rate` values a second on `PARAM_REQUEST_LIST`,
/// answers `PARAM_REQUEST_READ` by index, stores a `PARAM_SET` and echoes it with index 65535
/// (ArduPilot), and sends a HEARTBEAT a second.
struct Fc {
    ids: (u8, u8),
    version: MavlinkVersion,
    params: Vec<Param>,
    rate: f64,
    seq: u8,
    hb: Sender,
    reader: FrameReader,
    out: VecDeque<Vec<u8>>,
    streaming: Option<(usize, Instant)>,
    next_heartbeat: Instant,
    /// When the list's value of each index left the autopilot.
    listed_at: BTreeMap<u16, Instant>,
    /// PX4's way: a `_HASH_CHECK` (`None`: ArduPilot's way, no hash, sets echoed with index
    /// 65535), leaving out these indices (PX4's volatile parameters).
    hash_check: Option<Vec<u16>>,
}

/// PX4's `_HASH_CHECK` name.
const HASH_NAME: &[u8] = b"_HASH_CHECK";

/// PX4's `crc32part`, written out again here (bit by bit) to judge the router's: CRC-32,
/// reflected polynomial 0xEDB88320, no inversion.
fn crc32_part(bytes: &[u8], mut crc: u32) -> u32 {
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    crc
}

impl Fc {
    fn new(ids: (u8, u8), version: MavlinkVersion, params: Vec<Param>, rate: f64) -> Self {
        Self {
            ids,
            version,
            params,
            rate,
            seq: 0,
            hb: Sender::new(ids.0, ids.1, version),
            reader: FrameReader::new(),
            out: VecDeque::new(),
            streaming: None,
            next_heartbeat: Instant::ZERO,
            listed_at: BTreeMap::new(),
            hash_check: None,
        }
    }

    /// PX4's way: `_HASH_CHECK` over every parameter but the `volatile` indices; sets echoed
    /// with their index.
    fn px4(mut self, volatile: Vec<u16>) -> Self {
        self.hash_check = Some(volatile);
        self
    }

    /// PX4's `param_hash_check()`: CRC-32 over each name (up to its first zero) and value.
    fn hash(&self) -> u32 {
        let volatile = self.hash_check.as_deref().unwrap_or_default();
        self.params
            .iter()
            .enumerate()
            .filter(|(i, _)| !volatile.contains(&(*i as u16)))
            .fold(0, |h, (_, p)| {
                let len = p.name.iter().position(|&b| b == 0).unwrap_or(16);
                crc32_part(&p.value, crc32_part(&p.name[..len], h))
            })
    }

    /// The `_HASH_CHECK` `PARAM_VALUE` (type UINT32, index -1).
    fn send_hash(&mut self) {
        let p = Param {
            name: name(HASH_NAME),
            value: self.hash().to_le_bytes(),
            param_type: 5,
        };
        let bytes = raw_frame(
            self.version,
            self.ids,
            self.seq,
            &payload(&p, self.count(), u16::MAX),
        );
        self.seq = self.seq.wrapping_add(1);
        self.out.push_back(bytes);
    }

    /// The autopilot changes parameter `index` by itself; `broadcast`: it tells of it (PX4
    /// does), else its `PARAM_VALUE` is as good as lost.
    fn change(&mut self, index: u16, value: f32, broadcast: bool) {
        self.params[usize::from(index)].value = value.to_le_bytes();
        if broadcast {
            self.send_param(index, false);
        }
    }

    fn count(&self) -> u16 {
        self.params.len() as u16
    }

    fn send_param(&mut self, index: u16, echo: bool) {
        let p = self.params[usize::from(index)];
        let at = if echo { u16::MAX } else { index };
        let bytes = raw_frame(
            self.version,
            self.ids,
            self.seq,
            &payload(&p, self.count(), at),
        );
        self.seq = self.seq.wrapping_add(1);
        self.out.push_back(bytes);
    }

    fn handle(&mut self, now: Instant, bytes: &[u8]) {
        self.reader.push(bytes);
        while let Some(rx) = self.reader.next_frame() {
            match rx.frame.decode::<MavMessage>() {
                Ok(MavMessage::PARAM_REQUEST_LIST(r)) if r.target_system == self.ids.0 => {
                    // PX4 sends its hash first
                    if self.hash_check.is_some() {
                        self.send_hash();
                    }
                    self.streaming = Some((0, now));
                }
                Ok(MavMessage::PARAM_REQUEST_READ(r))
                    if r.target_system == self.ids.0
                        && r.param_index == -1
                        && *r.param_id == name(HASH_NAME)
                        && self.hash_check.is_some() =>
                {
                    self.send_hash();
                }
                Ok(MavMessage::PARAM_REQUEST_READ(r)) if r.target_system == self.ids.0 => {
                    if let Ok(i) = u16::try_from(r.param_index)
                        && i < self.count()
                    {
                        self.send_param(i, false);
                    }
                }
                Ok(MavMessage::PARAM_SET(s)) if s.target_system == self.ids.0 => {
                    let wanted: [u8; 16] = s.param_id.into();
                    if let Some(i) = self.params.iter().position(|p| p.name == wanted) {
                        self.params[i].value = s.param_value.to_le_bytes();
                        // ArduPilot echoes with index 65535, PX4 with the index
                        self.send_param(i as u16, self.hash_check.is_none());
                    }
                }
                _ => {}
            }
        }
    }

    fn tick(&mut self, now: Instant) {
        if now >= self.next_heartbeat {
            self.next_heartbeat = now + Duration::from_secs(1);
            let hb = self.hb.frame(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                mavlink_version: 3,
                ..Default::default()
            }));
            self.out.push_back(hb.into_inner());
        }
        while let Some((next, due)) = self.streaming
            && now >= due
        {
            self.listed_at.insert(next as u16, now);
            self.send_param(next as u16, false);
            self.streaming = (next + 1 < self.params.len())
                .then(|| (next + 1, due + Duration::from_secs_f64(1.0 / self.rate)));
        }
    }

    fn deadline(&self) -> Instant {
        let stream = self.streaming.map_or(self.next_heartbeat, |(_, due)| due);
        stream.min(self.next_heartbeat)
    }
}

/// What the ground station got of one index: the payload last received, and when first.
#[derive(Debug, Clone, Copy)]
struct Got {
    payload: [u8; 25],
    first: Instant,
}

/// A QGroundControl-like ground station (255/190): the list, then reads by index once it
/// has been quiet for 1 s, 10 outstanding, each again after 1 s; a `PARAM_SET` on request.
struct Ground {
    sender: Sender,
    reader: FrameReader,
    out: VecDeque<OwnedFrame>,
    vehicle: (u8, u8),
    got: BTreeMap<u16, Got>,
    by_name: BTreeMap<[u8; 16], u16>,
    count: Option<u16>,
    listed_at: Instant,
    last_new: Instant,
    rereading: bool,
    outstanding: BTreeMap<u16, Instant>,
    rereads: u64,
    /// Every `PARAM_VALUE` received: from whom, and its payload.
    received: Vec<((u8, u8), [u8; 25])>,
    /// A set in flight: name, value, sent at; and when its echo came.
    set: Option<([u8; 16], f32, Instant)>,
    echoed_at: Option<Instant>,
}

impl Ground {
    fn new(vehicle: (u8, u8)) -> Self {
        Self {
            sender: Sender::new(255, 190, MavlinkVersion::V2),
            reader: FrameReader::new(),
            out: VecDeque::new(),
            vehicle,
            got: BTreeMap::new(),
            by_name: BTreeMap::new(),
            count: None,
            listed_at: Instant::ZERO,
            last_new: Instant::ZERO,
            rereading: false,
            outstanding: BTreeMap::new(),
            rereads: 0,
            received: Vec::new(),
            set: None,
            echoed_at: None,
        }
    }

    fn send(&mut self, msg: MavMessage) {
        let f = self.sender.frame(&msg);
        self.out.push_back(f);
    }

    fn list(&mut self, now: Instant) {
        self.listed_at = now;
        self.last_new = now;
        self.send(MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
            target_system: self.vehicle.0,
            target_component: self.vehicle.1,
        }));
    }

    fn set(&mut self, now: Instant, param: &[u8], value: f32) {
        self.set = Some((name(param), value, now));
        self.send(MavMessage::PARAM_SET(PARAM_SET_DATA {
            target_system: self.vehicle.0,
            target_component: self.vehicle.1,
            param_id: name(param).into(),
            param_value: value,
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        }));
    }

    fn complete(&self) -> bool {
        self.count.is_some_and(|n| self.got.len() == usize::from(n))
    }

    fn handle(&mut self, now: Instant, bytes: &[u8]) {
        self.reader.push(bytes);
        while let Some(rx) = self.reader.next_frame() {
            let f = rx.frame;
            if f.message_id() != ids::PARAM_VALUE {
                continue;
            }
            let mut p = [0u8; 25];
            p[..f.payload().len()].copy_from_slice(f.payload());
            self.received.push(((f.system_id(), f.component_id()), p));
            let n: [u8; 16] = p[8..24].try_into().unwrap();
            let index = u16::from_le_bytes([p[6], p[7]]);
            let count = u16::from_le_bytes([p[4], p[5]]);
            if let Some((set, _, _)) = self.set
                && set == n
                && self.echoed_at.is_none()
            {
                self.echoed_at = Some(now);
            }
            // an echo (index 65535) updates the parameter by name
            let index = if index == u16::MAX {
                match self.by_name.get(&n) {
                    Some(&i) => i,
                    None => continue,
                }
            } else {
                index
            };
            if index >= count {
                continue;
            }
            self.count = Some(count);
            self.by_name.insert(n, index);
            self.outstanding.remove(&index);
            let first = match self.got.get(&index) {
                Some(g) => g.first,
                None => {
                    self.last_new = now;
                    now
                }
            };
            self.got.insert(index, Got { payload: p, first });
        }
    }

    fn tick(&mut self, now: Instant) {
        let Some(count) = self.count else { return };
        self.rereading |= now.saturating_duration_since(self.last_new) >= Duration::from_secs(1);
        if !self.rereading || self.complete() {
            return;
        }
        let due: Vec<u16> = self
            .outstanding
            .iter()
            .filter(|(_, at)| now.saturating_duration_since(**at) >= Duration::from_secs(1))
            .map(|(i, _)| *i)
            .collect();
        let missing: Vec<u16> = (0..count)
            .filter(|i| !self.got.contains_key(i) && !self.outstanding.contains_key(i))
            .take(10usize.saturating_sub(self.outstanding.len()))
            .collect();
        for i in due.into_iter().chain(missing) {
            self.outstanding.insert(i, now);
            self.rereads += 1;
            self.send(MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                target_system: self.vehicle.0,
                target_component: self.vehicle.1,
                param_index: i as i16,
                ..Default::default()
            }));
        }
    }
}

const KEY: [u8; 32] = [7; 32];

/// Signing as `link_id` (1 or 2), from a state that knows the other end (no freshness
/// handshake holding the first frames back).
fn signing(link_id: u8) -> SigningConfig {
    let mut state = SigningState::default();
    state.streams.insert((3 - link_id, 0, 0), 1);
    SigningConfig {
        key: SigningKey(KEY),
        link_id,
        epoch: 3_000_000_000,
        state,
    }
}

/// Bridge and router with a radio budget of `rate` bytes/s, signed as the binaries run.
fn engines(rate: u32, packed: bool) -> (Bridge, Router) {
    let budget = SchedulerConfig::for_radio(rate, 600);
    let profile = Profile::parse("", "empty").unwrap();
    let mut b = BridgeConfig::new(profile, budget);
    b.signing = Some(signing(1));
    if !packed {
        b.param_pack = None;
    }
    let mut r = RouterConfig::new(budget);
    r.signing = Some(signing(2));
    (
        Bridge::new(b, Instant::ZERO).unwrap(),
        Router::new(r, Instant::ZERO).unwrap(),
    )
}

/// The world: autopilot, bridge, radio (a latency, and frames `lose` says are lost), router,
/// ground.
struct World {
    now: Instant,
    fc: Fc,
    bridge: Bridge,
    router: Router,
    ground: Ground,
    /// Another ground station on the same router (it gets every frame too).
    ground2: Option<Ground>,
    down: VecDeque<(Instant, OwnedFrame)>,
    up: VecDeque<(Instant, OwnedFrame)>,
    lose: Box<dyn FnMut(&OwnedFrame) -> bool>,
    /// Frames the bridge put on the radio, by message id.
    down_frames: BTreeMap<u32, u64>,
    /// What was lost.
    lost: Vec<OwnedFrame>,
}

const LATENCY: Duration = Duration::from_millis(30);

impl World {
    fn new(fc: Fc, rate: u32, packed: bool) -> Self {
        let (bridge, router) = engines(rate, packed);
        let vehicle = fc.ids;
        Self {
            now: Instant::ZERO,
            fc,
            bridge,
            router,
            ground: Ground::new(vehicle),
            ground2: None,
            down: VecDeque::new(),
            up: VecDeque::new(),
            lose: Box::new(|_| false),
            down_frames: BTreeMap::new(),
            lost: Vec::new(),
        }
    }

    fn step(&mut self) {
        let now = self.now;
        self.fc.tick(now);
        while let Some(bytes) = self.fc.out.pop_front() {
            self.bridge.handle_fc_bytes(now, &bytes);
        }
        while let Some((at, _)) = self.up.front()
            && *at <= now
        {
            let (_, f) = self.up.pop_front().unwrap();
            self.bridge.handle_radio_bytes(now, f.as_bytes());
        }
        self.bridge.handle_timeout(now);
        while let Some(f) = self.bridge.poll_fc_transmit(now) {
            self.fc.handle(now, f.as_bytes());
        }
        while let Some(f) = self.bridge.poll_radio_transmit(now, usize::MAX) {
            *self.down_frames.entry(f.message_id()).or_default() += 1;
            if (self.lose)(&f) {
                self.lost.push(f);
            } else {
                self.down.push_back((now + LATENCY, f));
            }
        }
        while let Some((at, _)) = self.down.front()
            && *at <= now
        {
            let (_, f) = self.down.pop_front().unwrap();
            self.router.handle_radio_bytes(now, f.as_bytes());
        }
        self.ground.tick(now);
        while let Some(f) = self.ground.out.pop_front() {
            self.router.handle_gcs_bytes(now, f.as_bytes());
        }
        if let Some(g) = &mut self.ground2 {
            g.tick(now);
            while let Some(f) = g.out.pop_front() {
                self.router.handle_gcs_bytes(now, f.as_bytes());
            }
        }
        self.router.handle_timeout(now);
        while let Some(f) = self.router.poll_gcs_transmit() {
            self.ground.handle(now, f.as_bytes());
            if let Some(g) = &mut self.ground2 {
                g.handle(now, f.as_bytes());
            }
        }
        while let Some(f) = self.router.poll_radio_transmit(now, usize::MAX) {
            self.up.push_back((now + LATENCY, f));
        }
        // the next thing due, at most 10 ms on (the ground's timers)
        let next = [
            self.bridge.poll_timeout(),
            self.router.poll_timeout(),
            Some(self.fc.deadline()),
            self.down.front().map(|d| d.0),
            self.up.front().map(|d| d.0),
            Some(now + Duration::from_millis(10)),
        ]
        .into_iter()
        .flatten()
        .min()
        .unwrap();
        self.now = next.max(now + Duration::from_micros(1));
    }

    fn run_until(&mut self, until: Instant, mut done: impl FnMut(&World) -> bool) -> bool {
        while self.now < until {
            if done(self) {
                return true;
            }
            self.step();
        }
        done(self)
    }
}

fn secs(s: f64) -> Instant {
    Instant::from_micros((s * 1e6) as u64)
}

/// A list shaped like ArduCopter's: groups of unique names sharing prefixes, mostly zeros
/// and short floats.
fn ardupilot_like(n: usize) -> Vec<Param> {
    let groups = [
        "ATC_RAT_", "INS_ACC_", "SERIAL", "BATT_", "EK3_SRC_", "SR1_", "PSC_",
    ];
    (0..n)
        .map(|i| {
            let g = groups[i / 20 % groups.len()];
            let text = format!("{g}{i}");
            let v = match i % 4 {
                0 => 0.0f32,
                1 => 1.0,
                2 => 0.135 * i as f32,
                _ => 400.0,
            };
            Param {
                name: name(&text.as_bytes()[..text.len().min(16)]),
                value: v.to_le_bytes(),
                param_type: if i % 3 == 0 { 2 } else { 9 },
            }
        })
        .collect()
}

/// Checks that the ground holds every parameter exactly as the autopilot does, each heard
/// from the autopilot's ids, and nothing the autopilot never sent.
fn assert_exact(w: &World) {
    let count = w.fc.count();
    assert!(
        w.ground.complete(),
        "{} of {count} at the ground",
        w.ground.got.len()
    );
    for (i, p) in w.fc.params.iter().enumerate() {
        let got = w.ground.got[&(i as u16)].payload;
        assert_eq!(got, payload(p, count, i as u16), "index {i}");
    }
    for (from, p) in &w.ground.received {
        assert_eq!(*from, w.fc.ids, "a PARAM_VALUE not from the autopilot");
        if p[8..24] == name(HASH_NAME) {
            // PX4's hash of its set, as it sent it: no parameter
            assert!(
                w.fc.hash_check.is_some(),
                "a hash from an autopilot without one"
            );
            continue;
        }
        let index = u16::from_le_bytes([p[6], p[7]]);
        let i = if index == u16::MAX {
            w.fc.params.iter().position(|q| q.name == p[8..24]).unwrap() as u16
        } else {
            index
        };
        let q = w.fc.params[usize::from(i)];
        assert!(
            p[8..24] == q.name && p[24] == q.param_type && p[4..6] == count.to_le_bytes(),
            "the ground got a PARAM_VALUE the autopilot never sent: {p:02x?}"
        );
    }
}

fn arb_param() -> impl Strategy<Value = Param> {
    (
        // 1..=16 name bytes, any (zeros inside too); some all zero (not packable: raw)
        prop_oneof![
            9 => proptest::collection::vec(any::<u8>(), 1..=16),
            1 => Just(vec![0u8; 4]),
        ],
        prop_oneof![
            any::<u32>(),
            // NaNs, signalling ones included, with any payload
            (any::<bool>(), 1u32..0x0080_0000)
                .prop_map(|(s, m)| (u32::from(s) << 31) | 0x7F80_0000 | m),
            Just(0u32),
            Just(0x3F80_0000),
            (0u32..256),
        ],
        // types a frame carries, and a few it cannot (raw)
        prop_oneof![9 => 0u8..=15, 1 => 16u8..=255],
    )
        .prop_map(|(n, v, t)| Param {
            name: name(&n),
            value: v.to_le_bytes(),
            param_type: t,
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Any list (arbitrary names of up to 16 bytes, NaN bit patterns, any type byte, MAVLink 1
    /// or 2, any component) reaches the ground exactly as the autopilot sent it, from its
    /// ids, packed several values to a radio frame.
    #[test]
    fn every_value_reaches_the_ground_byte_for_byte(
        params in proptest::collection::vec(arb_param(), 1..250),
        v1 in any::<bool>(),
        component in prop_oneof![Just(1u8), any::<u8>()],
        rate in prop_oneof![Just(250u32), Just(2400)],
    ) {
        let version = if v1 { MavlinkVersion::V1 } else { MavlinkVersion::V2 };
        let n = params.len();
        let fc = Fc::new((1, component), version, params, 300.0);
        let mut w = World::new(fc, rate, true);
        w.ground.list(Instant::ZERO);
        let done = w.run_until(secs(30.0 + n as f64 * 50.0 / f64::from(rate)), |w| w.ground.complete());
        prop_assert!(done, "{} of {n} after {:?}", w.ground.got.len(), w.now);
        assert_exact(&w);
        let packed = w.down_frames.get(&ids::MAVLORA_PARAM_VALUES).copied().unwrap_or(0);
        let raw = w.down_frames.get(&ids::PARAM_VALUE).copied().unwrap_or(0);
        let unpackable = w.fc.params.iter().filter(|p| p.param_type > 15 || p.name == [0; 16]).count();
        prop_assert!(packed > 0 || unpackable == n, "nothing went packed");
        prop_assert_eq!(raw as usize, unpackable, "what a frame can carry went raw");
        prop_assert_eq!(w.ground.rereads, 0);
    }
}

/// A packed frame lost on the radio is repaired the standard way: the ground reads the
/// missing indices with `PARAM_REQUEST_READ` once the list went quiet, and the answers come.
#[test]
fn a_lost_packed_frame_is_read_again_by_index() {
    let fc = Fc::new((1, 1), MavlinkVersion::V2, ardupilot_like(400), 270.0);
    let mut w = World::new(fc, 2400, true);
    let mut packed = 0;
    w.lose = Box::new(move |f| {
        if f.message_id() != ids::MAVLORA_PARAM_VALUES {
            return false;
        }
        packed += 1;
        packed == 3 || packed == 7
    });
    w.ground.list(Instant::ZERO);
    assert!(
        w.run_until(secs(20.0), |w| w.ground.complete()),
        "{} of 400",
        w.ground.got.len()
    );
    assert_exact(&w);
    assert_eq!(w.lost.len(), 2);
    let missing: usize = w
        .lost
        .iter()
        .map(|f| match f.decode::<MavMessage>() {
            Ok(MavMessage::MAVLORA_PARAM_VALUES(p)) => usize::from(p.values),
            _ => 0,
        })
        .sum();
    assert!(missing > 10, "{missing} values lost");
    // each answered once, raw, ahead of anything else
    assert_eq!(w.ground.rereads as usize, missing);
    assert_eq!(w.bridge.stats().param_answers as usize, missing);
    eprintln!(
        "400 values, {missing} lost in 2 frames, all at the ground after {:?}",
        w.now
    );
}

/// The echo of a `PARAM_SET` sent while a long list crosses a slow radio (LoRa SF7's budget:
/// the autopilot has streamed everything long before the radio carried it) reaches the ground
/// within 1 s, and the list's older value of that parameter, still waiting at the bridge, never
/// follows it: the ground ends with the value it set. Before, the older value left after the
/// echo and the ground showed it.
#[test]
fn a_param_set_echo_overtakes_the_packed_list_and_no_older_copy_follows() {
    let list = ardupilot_like(1396);
    let target = 500usize;
    let fc = Fc::new((1, 1), MavlinkVersion::V2, list, 270.0);
    let mut w = World::new(fc, 250, true);
    w.ground.list(Instant::ZERO);
    w.run_until(secs(10.0), |_| false);
    assert!(
        w.fc.listed_at.contains_key(&(target as u16))
            && !w.ground.got.contains_key(&(target as u16)),
        "the autopilot has sent it, the ground does not have it yet"
    );
    let set_name = w.fc.params[target].name;
    let text = set_name
        .iter()
        .take_while(|&&b| b != 0)
        .copied()
        .collect::<Vec<u8>>();
    w.ground.set(w.now, &text, 1234.5);
    let set_at = w.now;
    assert!(w.run_until(secs(200.0), |w| w.ground.complete()
        && w.ground.echoed_at.is_some()));
    let echo = w
        .ground
        .echoed_at
        .unwrap()
        .saturating_duration_since(set_at);
    assert!(echo <= Duration::from_secs(1), "echo after {echo:?}");
    // the list goes on to the end, then the ground holds the value it set
    w.run_until(w.now + Duration::from_secs(5), |_| false);
    let at_ground = w.ground.got[&(target as u16)].payload;
    assert_eq!(
        &at_ground[..4],
        &1234.5f32.to_le_bytes(),
        "the list's older value followed the echo"
    );
    assert_exact(&w);
    assert!(w.bridge.stats().params.superseded >= 1);
    eprintln!("echo after {echo:?}; list complete at {:?}", w.now);
}

/// A list shaped like PX4's: names in ASCII order, int32 (type 6) and float (type 9) values,
/// `seed` moving the values (another vehicle, a reboot with other parameters).
fn px4_like(n: usize, seed: u32) -> Vec<Param> {
    let groups = [
        "ASPD_",
        "CAL_ACC0_",
        "COM_",
        "EKF2_",
        "MC_",
        "MPC_",
        "NAV_",
        "RTL_",
    ];
    (0..n)
        .map(|i| {
            let g = groups[i * groups.len() / n];
            let text = format!("{g}{i:04}");
            let (value, param_type) = if i % 3 == 0 {
                ((i as u32 % 7 + seed).to_le_bytes(), 6)
            } else {
                ((0.25 * i as f32 + seed as f32).to_le_bytes(), 9)
            };
            Param {
                name: name(&text.as_bytes()[..text.len().min(16)]),
                value,
                param_type,
            }
        })
        .collect()
}

/// PX4's volatile parameters in the model (left out of its hash).
const VOLATILE: [u16; 3] = [3, 17, 200];

/// A PX4-like autopilot (1, 1) with `n` parameters behind a radio of `rate` bytes/s.
fn px4_world(n: usize, rate: u32) -> World {
    let fc = Fc::new((1, 1), MavlinkVersion::V2, px4_like(n, 0), 300.0).px4(VOLATILE.to_vec());
    World::new(fc, rate, true)
}

/// The ground station asks for the list; how long until it holds every value.
fn download(w: &mut World, limit: f64) -> Duration {
    let start = w.now;
    w.ground.list(start);
    let until = start + Duration::from_secs_f64(limit);
    assert!(
        w.run_until(until, |w| w.ground.complete()),
        "{} of {} after {limit} s",
        w.ground.got.len(),
        w.fc.count()
    );
    w.now.saturating_duration_since(start)
}

/// A ground station connects afresh (a reconnect, or another station) and downloads the
/// list; how long it took.
fn reconnect(w: &mut World, limit: f64) -> Duration {
    w.ground = Ground::new(w.fc.ids);
    download(w, limit)
}

/// Lets checks and their answers cross the radio.
fn settle(w: &mut World) {
    w.run_until(w.now + Duration::from_secs(4), |_| false);
}

/// Packed parameter frames the bridge put on the radio so far.
fn packed_down(w: &World) -> u64 {
    w.down_frames
        .get(&ids::MAVLORA_PARAM_VALUES)
        .copied()
        .unwrap_or(0)
}

/// After a first download, a ground station that connects again gets PX4's whole list from the
/// router in at most 5 s on LoRa SF7's budget and on SiK's, byte for byte, and the list does
/// not cross the radio again. Before, every list crossed the radio: ~60 s on LoRa SF7.
#[test]
fn a_reconnecting_ground_gets_px4s_list_from_the_router_within_5_s() {
    for rate in [250, 2400] {
        let mut w = px4_world(904, rate);
        let first = download(&mut w, 300.0);
        assert_exact(&w);
        settle(&mut w);
        let packed = packed_down(&w);
        let second = reconnect(&mut w, 60.0);
        assert_exact(&w);
        assert!(
            second <= Duration::from_secs(5),
            "{rate} B/s: second list after {second:?} (first {first:?})"
        );
        assert_eq!(packed_down(&w), packed, "the list crossed the radio again");
        assert_eq!(w.ground.rereads, 0);
        eprintln!("{rate} B/s: 904 values, first list {first:?}, second {second:?}");
    }
}

/// A value the autopilot changes while the list is in flight (a value already delivered),
/// the echo of a ground's `PARAM_SET` after it, and a change the autopilot broadcasts by
/// itself: each updates the cache, which still answers the next station, with the new
/// values.
#[test]
fn changes_during_and_after_the_download_are_served_from_the_cache() {
    let mut w = px4_world(300, 2400);
    w.ground.list(Instant::ZERO);
    assert!(w.run_until(secs(30.0), |w| w.ground.got.contains_key(&10)
        && !w.ground.complete()));
    w.fc.change(10, 42.0, true);
    assert!(w.run_until(secs(60.0), |w| w.ground.complete()));
    settle(&mut w);
    // a set from the ground: PX4 echoes it with its index
    let set_name = w.fc.params[50].name;
    let text: Vec<u8> = set_name.iter().take_while(|&&b| b != 0).copied().collect();
    w.ground.set(w.now, &text, 1234.5);
    settle(&mut w);
    assert!(w.ground.echoed_at.is_some());
    w.fc.change(60, -7.5, true);
    settle(&mut w);
    let packed = packed_down(&w);
    let second = reconnect(&mut w, 60.0);
    assert_exact(&w);
    for (i, v) in [(10, 42.0f32), (50, 1234.5), (60, -7.5)] {
        assert_eq!(w.ground.got[&i].payload[..4], v.to_le_bytes(), "index {i}");
    }
    assert!(
        second <= Duration::from_secs(5),
        "second list after {second:?}"
    );
    assert_eq!(packed_down(&w), packed, "the list crossed the radio again");
}

/// A cache hit first; then `stale` makes the vehicle's set differ from the cache without the
/// router hearing of it: the next station must get the vehicle's values, the list crossing the
/// radio again, never a cached one; and the list after that is cached again.
fn never_served_stale(stale: impl FnOnce(&mut World)) {
    let mut w = px4_world(300, 2400);
    download(&mut w, 60.0);
    settle(&mut w);
    let hit = reconnect(&mut w, 60.0);
    assert!(hit <= Duration::from_secs(5), "a hit after {hit:?}");
    stale(&mut w);
    settle(&mut w);
    let packed = packed_down(&w);
    reconnect(&mut w, 60.0);
    assert_exact(&w);
    assert!(packed_down(&w) > packed, "served from the cache");
    settle(&mut w);
    let packed = packed_down(&w);
    let again = reconnect(&mut w, 60.0);
    assert_exact(&w);
    assert!(again <= Duration::from_secs(5), "cached again: {again:?}");
    assert_eq!(packed_down(&w), packed);
}

/// A change whose `PARAM_VALUE` never reached the router: the vehicle's hash differs.
#[test]
fn a_change_whose_value_was_lost_is_never_served_stale() {
    never_served_stale(|w| w.fc.change(120, 3.25, false));
}

/// A change of a value PX4 leaves out of its hash and one that is in it, both lost: the
/// hash moved by more than a volatile value explains.
#[test]
fn a_lost_change_beside_a_volatile_one_is_never_served_stale() {
    never_served_stale(|w| {
        w.fc.change(VOLATILE[1], 5.0, true);
        w.fc.change(121, 9.0, false);
    });
}

/// The vehicle rebooted with other parameters (new values, same names and count).
#[test]
fn a_vehicle_rebooted_with_other_parameters_is_never_served_stale() {
    never_served_stale(|w| {
        let mut params = w.fc.params.clone();
        for i in [5, 150, 299] {
            params[i].value = [0x11, 0x22, 0x33, 0x44];
        }
        w.fc = Fc::new(w.fc.ids, MavlinkVersion::V2, params, 300.0).px4(VOLATILE.to_vec());
    });
}

/// Another vehicle with the same system id: the same list's names with other values, or
/// another list altogether.
#[test]
fn another_vehicle_with_the_same_system_id_is_never_served_stale() {
    never_served_stale(|w| {
        w.fc =
            Fc::new(w.fc.ids, MavlinkVersion::V2, px4_like(300, 1), 300.0).px4(VOLATILE.to_vec());
    });
    never_served_stale(|w| {
        w.fc =
            Fc::new(w.fc.ids, MavlinkVersion::V2, px4_like(280, 2), 300.0).px4(VOLATILE.to_vec());
    });
}

/// A second station asks while the first one's download is in flight: the cache does not
/// answer a list it does not hold whole, both get every value, and a third station is then
/// served from the cache.
#[test]
fn a_list_asked_for_while_a_download_is_in_flight_reaches_both_then_is_cached() {
    let mut w = px4_world(904, 2400);
    w.ground.list(Instant::ZERO);
    w.run_until(secs(2.0), |_| false);
    assert!(!w.ground.complete() && !w.ground.got.is_empty());
    let mut second = Ground::new(w.fc.ids);
    second.list(w.now);
    w.ground2 = Some(second);
    assert!(w.run_until(secs(120.0), |w| w.ground.complete()
        && w.ground2.as_ref().is_some_and(Ground::complete)));
    assert_exact(&w);
    let g2 = w.ground2.take().unwrap();
    for (i, p) in w.fc.params.iter().enumerate() {
        assert_eq!(g2.got[&(i as u16)].payload, payload(p, 904, i as u16));
    }
    // PX4 streams the list again from its start for the second request; what still waits at
    // the bridge is not sent twice, what left already is (SiK: most of the first 2 s)
    let carried = w.router.stats().param_values_expanded;
    assert!(carried < 2 * 904, "{carried} values crossed the radio");
    settle(&mut w);
    let packed = packed_down(&w);
    let third = reconnect(&mut w, 60.0);
    assert_exact(&w);
    assert!(
        third <= Duration::from_secs(5),
        "third list after {third:?}"
    );
    assert_eq!(packed_down(&w), packed);
}

/// ArduPilot answers no `_HASH_CHECK`: its lists cross the radio every time, exact, and no
/// list waits for a check. (Unchanged behaviour: this held before the cache too.)
#[test]
fn an_autopilot_without_a_hash_check_lists_over_the_radio_every_time() {
    let fc = Fc::new((1, 1), MavlinkVersion::V2, ardupilot_like(300), 300.0);
    let mut w = World::new(fc, 2400, true);
    let first = download(&mut w, 60.0);
    settle(&mut w);
    let packed = packed_down(&w);
    let second = reconnect(&mut w, 60.0);
    assert_exact(&w);
    assert!(packed_down(&w) > packed);
    assert!(
        second <= first + Duration::from_millis(500),
        "{second:?} vs {first:?}"
    );
}
