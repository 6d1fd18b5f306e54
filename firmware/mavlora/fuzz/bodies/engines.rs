//! The bridge and router engines fed arbitrary bytes from both of their sides at arbitrary
//! times, wired to each other through a lossless wire. Invariants, on every input:
//! - nothing panics;
//! - with signing on, every frame either engine puts on the radio carries a valid signature
//!   with the link key (checked by an independent verifier, a `LinkSigner` of our own), so
//!   nothing unsigned ever reaches the radio, whatever the flight controller or ground sent;
//! - neither engine hands the radio more bytes than its budget allows: at most the burst plus
//!   the rate times the elapsed time (the token bucket's promise);
//! - ACCEPTED only for the plan the FC acked after receiving every item: a ground station
//!   with an upload open (its `MISSION_COUNT` of a type, until the first `MISSION_ACK` of that
//!   type it gets, or until it clears or partially writes that type) is told ACCEPTED only if
//!   the flight controller acked ACCEPTED, to the bridge, after the bridge had given it every
//!   item since its `MISSION_COUNT`, and those items are exactly the plan the ground sent
//!   (its first items in order after its count, as a vehicle takes them);
//! - each command runs at most once per ground intent: the flight controller is given a
//!   command (target, id, every parameter) no more often than the ground sent it anew
//!   (`COMMAND_LONG` with `confirmation` 0, or a first retry of one it never sent anew; every
//!   `COMMAND_INT`, which has no confirmation), however many copies and retries went.
//!
//! Input records `[op, advance, len, bytes...]`: ops below 0xF0 feed the bytes to one of the
//! four sides (or flush a side's partial frame); ops 0xF0.. are well-formed mission messages
//! built from the bytes (a ground's count, item, clear-all, partial write, legacy item; the
//! flight controller's heartbeat, request, ack; an honest autopilot's or ground's next step;
//! a `PARAM_VALUE` of the flight controller's list, which the bridge packs and the router
//! expands; a ground's command, new or a retry, and the flight controller's ack of the last
//! command it got), so whole uploads, lists and commands are a few records away from any
//! input.
//!
//! Inputs of odd length run the bridge with compact telemetry (its frames, made of whatever
//! the flight controller sent, are expanded by the router), even ones without.

// MISSION_ITEM is deprecated, and what some ground stations still send.
#![allow(deprecated)]
// Full literals keep `..Default::default()`: the dialect may grow.
#![allow(clippy::needless_update)]

use std::collections::HashMap;

use mavlink::MavlinkVersion;
use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::command::CommandId;
use mavlora::compact::CompactConfig;
use mavlora::dialect::{
    COMMAND_ACK_DATA, COMMAND_INT_DATA, COMMAND_LONG_DATA, HEARTBEAT_DATA, MISSION_ACK_DATA,
    MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA, MISSION_ITEM_DATA, MISSION_ITEM_INT_DATA,
    MISSION_REQUEST_INT_DATA, MISSION_WRITE_PARTIAL_LIST_DATA, MavAutopilot, MavCmd, MavFrame,
    MavMessage, MavMissionResult, MavMissionType, MavParamType, MavResult, MavType,
    PARAM_VALUE_DATA,
};
use mavlora::filter::Profile;
use mavlora::mission::plan::same_plan;
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::SchedulerConfig;
use mavlora::signing::{SigningConfig, SigningKey};
use mavlora::wire::{FrameReader, Integrity, OwnedFrame, Sender, ids, known};
use mavlora::{Duration, Instant};

const RATE: u32 = 683;
const BURST: u32 = 600;
const PROFILE: &str = include_str!("../../profiles/px4-normal.toml");

struct Budget {
    start: Instant,
    sent: u64,
}

impl Budget {
    fn check(&mut self, now: Instant, bytes: usize, who: &str) {
        self.sent += bytes as u64;
        let elapsed = now.saturating_duration_since(self.start).as_secs_f64();
        let allowed = f64::from(BURST) + f64::from(RATE) * elapsed + 1.0;
        assert!(
            self.sent as f64 <= allowed,
            "{who} sent {} B in {elapsed} s (budget {allowed})",
            self.sent
        );
    }
}

fn key() -> SigningKey {
    SigningKey::parse(b"000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f")
        .expect("test key")
}

fn signing(link_id: u8) -> SigningConfig {
    SigningConfig {
        key: key(),
        link_id,
        epoch: 1_000_000,
        state: Default::default(),
    }
}

/// Every frame on the radio must verify with the key (an independent signer per sender, so
/// replay tracking does not cross the two directions).
fn assert_signed(
    checker: &mut mavlora::signing::LinkSigner,
    bytes: &[u8],
    now: Instant,
    who: &str,
) {
    let mut reader = FrameReader::new();
    reader.push(bytes);
    reader.finish();
    while let Some(rx) = reader.next_frame() {
        // Unknown message ids pass (the profiles' default) and no reader can check their
        // checksum: they come out `Unchecked`, and their signature is what vouches for them.
        assert!(
            rx.integrity == Integrity::Checked || known::crc_extra(rx.frame.message_id()).is_none(),
            "{who} sent a damaged frame"
        );
        assert!(
            checker.verify(&rx.frame, now).is_ok(),
            "{who} put an unsigned or badly signed frame on the radio: {:02x?}",
            rx.frame.as_bytes()
        );
    }
}

const ACCEPTED: MavMissionResult = MavMissionResult::MAV_MISSION_ACCEPTED;
/// The ground station of the structured ops, another one, the vehicle, the bridge.
const GROUND: (u8, u8) = (255, 190);
const OTHER_GROUND: (u8, u8) = (245, 190);
const FC: (u8, u8) = (1, 1);
const BRIDGE: (u8, u8) = (1, 191);

fn mission_type(b: u8) -> MavMissionType {
    match b % 3 {
        0 => MavMissionType::MAV_MISSION_TYPE_MISSION,
        1 => MavMissionType::MAV_MISSION_TYPE_FENCE,
        _ => MavMissionType::MAV_MISSION_TYPE_RALLY,
    }
}

/// A ground's upload open, as the router takes it: its items in order after its count.
struct OpenUpload {
    mission_type: MavMissionType,
    count: u16,
    items: Vec<MISSION_ITEM_INT_DATA>,
}

/// What the ground sides and the flight controller side said, for the mission invariant.
#[derive(Default)]
struct MissionWatch {
    /// Frames the router got from the ground (the engine frames the same stream).
    ground_in: FrameReader,
    /// Each ground's open upload, by (system, component).
    open: HashMap<(u8, u8), OpenUpload>,
    /// The bridge's upload to the flight controller: type, count, items given.
    wire: Option<(MavMissionType, u16, Vec<Option<MISSION_ITEM_INT_DATA>>)>,
    /// Flight controller bytes, and its ACCEPTED after every item: (type, plan).
    fc_in: FrameReader,
    accepted: Vec<(MavMissionType, Vec<MISSION_ITEM_INT_DATA>)>,
    /// The router's latest item request to the structured ground, for its honest step op:
    /// (type, seq).
    router_asked: Option<(MavMissionType, u16)>,
}

impl MissionWatch {
    /// Bytes fed to the router from the ground.
    fn ground_bytes(&mut self, bytes: &[u8]) {
        self.ground_in.push(bytes);
        while let Some(rx) = self.ground_in.next_frame() {
            // Only what the router's ground policy lets in (system ids 255 and 245).
            let from = (rx.frame.system_id(), rx.frame.component_id());
            if !matches!(from.0, 255 | 245) || !is_mission(rx.frame.message_id()) {
                continue;
            }
            let Ok(msg) = rx.frame.decode::<MavMessage>() else {
                continue;
            };
            let all = MavMissionType::MAV_MISSION_TYPE_ALL;
            match msg {
                MavMessage::MISSION_COUNT(c) => {
                    self.open.insert(
                        from,
                        OpenUpload {
                            mission_type: c.mission_type,
                            count: c.count,
                            items: Vec::new(),
                        },
                    );
                }
                MavMessage::MISSION_ITEM_INT(i) => {
                    if let Some(u) = self.open.get_mut(&from)
                        && u.mission_type == i.mission_type
                        && usize::from(i.seq) == u.items.len()
                        && u.items.len() < usize::from(u.count)
                    {
                        u.items.push(i);
                    }
                }
                // The ground moved on (or cancelled): its upload is over.
                MavMessage::MISSION_CLEAR_ALL(c) => {
                    self.open.retain(|g, u| {
                        *g != from || (u.mission_type != c.mission_type && c.mission_type != all)
                    });
                }
                MavMessage::MISSION_WRITE_PARTIAL_LIST(w) => {
                    self.open
                        .retain(|g, u| *g != from || u.mission_type != w.mission_type);
                }
                MavMessage::MISSION_ACK(a) if a.mavtype != ACCEPTED => {
                    self.open
                        .retain(|g, u| *g != from || u.mission_type != a.mission_type);
                }
                _ => {}
            }
        }
    }

    /// Bytes the flight controller sent.
    fn fc_bytes(&mut self, bytes: &[u8]) {
        self.fc_in.push(bytes);
        while let Some(rx) = self.fc_in.next_frame() {
            if rx.frame.message_id() != ids::MISSION_ACK {
                continue;
            }
            let Ok(MavMessage::MISSION_ACK(a)) = rx.frame.decode::<MavMessage>() else {
                continue;
            };
            if a.mavtype != ACCEPTED || a.target_component != BRIDGE.1 {
                continue;
            }
            if let Some((t, n, given)) = &self.wire
                && *t == a.mission_type
                && given.len() == usize::from(*n)
                && given.iter().all(Option::is_some)
            {
                let plan = given.iter().flatten().cloned().collect();
                self.accepted.push((*t, plan));
            }
        }
    }

    /// A frame the bridge sent the flight controller.
    fn fc_got(&mut self, frame: &OwnedFrame) {
        if !matches!(
            frame.message_id(),
            ids::MISSION_COUNT | ids::MISSION_ITEM_INT
        ) {
            return;
        }
        match frame.decode::<MavMessage>() {
            Ok(MavMessage::MISSION_COUNT(c)) => {
                self.wire = Some((c.mission_type, c.count, vec![None; usize::from(c.count)]));
            }
            Ok(MavMessage::MISSION_ITEM_INT(i)) => {
                if let Some((t, _, given)) = &mut self.wire
                    && *t == i.mission_type
                    && let Some(slot) = given.get_mut(usize::from(i.seq))
                {
                    *slot = Some(i);
                }
            }
            _ => {}
        }
    }

    /// A frame the router sent the ground stations.
    fn ground_got(&mut self, frame: &OwnedFrame) {
        if !matches!(
            frame.message_id(),
            ids::MISSION_ACK | ids::MISSION_REQUEST_INT
        ) {
            return;
        }
        let Ok(msg) = frame.decode::<MavMessage>() else {
            return;
        };
        if let MavMessage::MISSION_REQUEST_INT(r) = &msg {
            if (r.target_system, r.target_component) == GROUND {
                self.router_asked = Some((r.mission_type, r.seq));
            }
            return;
        }
        let MavMessage::MISSION_ACK(a) = msg else {
            return;
        };
        let to = |g: &(u8, u8)| {
            a.target_system == g.0 && (a.target_component == g.1 || a.target_component == 0)
        };
        let grounds: Vec<(u8, u8)> = self
            .open
            .iter()
            .filter(|(g, u)| to(g) && u.mission_type == a.mission_type)
            .map(|(g, _)| *g)
            .collect();
        for g in grounds {
            // The first ack of that type ends the ground's upload, whatever it says.
            let u = self.open.remove(&g).unwrap();
            if a.mavtype != ACCEPTED {
                continue;
            }
            assert!(
                u.items.len() == usize::from(u.count)
                    && self
                        .accepted
                        .iter()
                        .any(|(t, plan)| *t == u.mission_type && same_plan(plan, &u.items)),
                "ground {g:?} told ACCEPTED for a {:?} plan of {} items ({} sent) the flight \
                 controller never acked after receiving every item",
                u.mission_type,
                u.count,
                u.items.len()
            );
        }
    }
}

/// What the ground sent and what the flight controller was given, for the command invariant.
#[derive(Default)]
struct CommandWatch {
    ground_in: FrameReader,
    /// Ground intents per command: sends anew, and whether any send came at all.
    intents: HashMap<CommandId, (u32, bool)>,
    executed: HashMap<CommandId, u32>,
    /// The last command the flight controller got, for its honest ack op.
    last: Option<MavCmd>,
}

impl CommandWatch {
    fn ground_bytes(&mut self, bytes: &[u8]) {
        self.ground_in.push(bytes);
        while let Some(rx) = self.ground_in.next_frame() {
            let Ok(msg) = rx.frame.decode::<MavMessage>() else {
                continue;
            };
            let Some(id) = CommandId::of(&msg) else {
                continue;
            };
            let anew = match &msg {
                MavMessage::COMMAND_LONG(c) => c.confirmation == 0,
                _ => true,
            };
            let e = self.intents.entry(id).or_default();
            e.0 += u32::from(anew);
            e.1 = true;
        }
    }

    /// A frame the bridge gave the flight controller.
    fn fc_got(&mut self, frame: &OwnedFrame) {
        // The bridge's own stream-rate commands are its, not the ground's.
        if (frame.system_id(), frame.component_id()) == BRIDGE {
            return;
        }
        let Ok(msg) = frame.decode::<MavMessage>() else {
            return;
        };
        let Some(id) = CommandId::of(&msg) else {
            return;
        };
        self.last = match &msg {
            MavMessage::COMMAND_LONG(c) => Some(c.command),
            MavMessage::COMMAND_INT(c) => Some(c.command),
            _ => None,
        };
        let n = self.executed.entry(id).or_default();
        *n += 1;
        let (anew, any) = self.intents.get(&id).copied().unwrap_or_default();
        let intents = anew.max(u32::from(any));
        assert!(
            *n <= intents,
            "the flight controller got command {id:?} {n} times for {intents} ground intents"
        );
    }
}

fn is_mission(id: u32) -> bool {
    matches!(
        id,
        ids::MISSION_COUNT
            | ids::MISSION_ITEM_INT
            | ids::MISSION_ITEM
            | ids::MISSION_ACK
            | ids::MISSION_CLEAR_ALL
            | ids::MISSION_WRITE_PARTIAL_LIST
    )
}

/// The well-formed message structured op `op` (0xF0..) builds from `b`, and who sends it
/// (the flight controller, or a ground station), by (system, component).
fn structured(
    op: u8,
    b: &[u8],
    watch: &MissionWatch,
    commands: &CommandWatch,
) -> Option<(MavMessage, (u8, u8))> {
    let at = |k: usize| b.get(k).copied().unwrap_or(0);
    let t = mission_type(at(1));
    let to_fc = |msg| Some((msg, FC));
    Some(match op & 0x0F {
        0 => (
            MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
                mavlink_version: 3,
                ..Default::default()
            }),
            FC,
        ),
        1 | 10 => (
            MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count: u16::from(at(0) % 8),
                target_system: FC.0,
                target_component: FC.1,
                mission_type: t,
                ..Default::default()
            }),
            if op & 0x0F == 1 { GROUND } else { OTHER_GROUND },
        ),
        2 => (
            MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                seq: u16::from(at(0) % 8),
                x: i32::from(at(2)),
                target_system: FC.0,
                target_component: FC.1,
                mission_type: t,
                ..Default::default()
            }),
            GROUND,
        ),
        3 => {
            return to_fc(MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq: u16::from(at(0) % 8),
                target_system: BRIDGE.0,
                target_component: BRIDGE.1,
                mission_type: t,
                ..Default::default()
            }));
        }
        4 => {
            let to = if at(3) & 1 == 0 { BRIDGE } else { GROUND };
            return to_fc(MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                target_system: to.0,
                target_component: to.1,
                mavtype: if at(0) < 128 {
                    ACCEPTED
                } else {
                    ack_result(at(0))
                },
                mission_type: t,
                opaque_id: u32::from(at(2)),
                ..Default::default()
            }));
        }
        5 => (
            MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
                target_system: FC.0,
                target_component: FC.1,
                mission_type: if at(0) & 4 == 0 {
                    mission_type(at(0))
                } else {
                    MavMissionType::MAV_MISSION_TYPE_ALL
                },
                ..Default::default()
            }),
            GROUND,
        ),
        6 => (
            MavMessage::MISSION_WRITE_PARTIAL_LIST(MISSION_WRITE_PARTIAL_LIST_DATA {
                start_index: i16::from(at(0) % 8),
                end_index: i16::from(at(2) % 8),
                target_system: FC.0,
                target_component: FC.1,
                mission_type: t,
                ..Default::default()
            }),
            GROUND,
        ),
        7 => (
            MavMessage::MISSION_ITEM(MISSION_ITEM_DATA {
                seq: u16::from(at(0) % 8),
                x: f32::from(at(2)),
                target_system: FC.0,
                target_component: FC.1,
                mission_type: t,
                ..Default::default()
            }),
            GROUND,
        ),
        // An honest autopilot's next step of the bridge's upload: the next item it lacks, or
        // its ACCEPTED once it has them all.
        8 => {
            let (t, n, given) = watch.wire.as_ref()?;
            return to_fc(match given.iter().position(Option::is_none) {
                Some(seq) => MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                    seq: seq as u16,
                    target_system: BRIDGE.0,
                    target_component: BRIDGE.1,
                    mission_type: *t,
                    ..Default::default()
                }),
                None => MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                    target_system: BRIDGE.0,
                    target_component: BRIDGE.1,
                    mavtype: ACCEPTED,
                    mission_type: *t,
                    opaque_id: u32::from(*n > 0) * u32::from(at(0)),
                    ..Default::default()
                }),
            });
        }
        // An honest ground's answer to the router's latest request.
        9 => {
            let (t, seq) = watch.router_asked?;
            (
                MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                    seq,
                    x: i32::from(at(0)) + i32::from(seq),
                    target_system: FC.0,
                    target_component: FC.1,
                    mission_type: t,
                    ..Default::default()
                }),
                GROUND,
            )
        }
        // A value of the flight controller's parameter list.
        11 => {
            let mut name = [0u8; 16];
            for (c, &x) in name.iter_mut().zip(b.iter().skip(5)) {
                *c = x;
            }
            return to_fc(MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
                param_value: f32::from_le_bytes([at(2), at(3), at(4), at(1)]),
                param_count: 900,
                param_index: u16::from(at(0)),
                param_id: name.into(),
                param_type: match at(3) % 3 {
                    0 => MavParamType::MAV_PARAM_TYPE_REAL32,
                    1 => MavParamType::MAV_PARAM_TYPE_INT32,
                    _ => MavParamType::MAV_PARAM_TYPE_UINT8,
                },
            }));
        }
        // A ground's command: one of a few, its parameter from the bytes, new
        // (`confirmation` 0) or a retry, as COMMAND_LONG or COMMAND_INT.
        12 => {
            let command = match at(0) % 3 {
                0 => MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                1 => MavCmd::MAV_CMD_DO_SET_MODE,
                _ => MavCmd::MAV_CMD_NAV_LAND,
            };
            let param1 = f32::from(at(2) % 4);
            let msg = if at(1) & 0x80 == 0 {
                MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                    target_system: FC.0,
                    target_component: at(3) % 2,
                    command,
                    confirmation: at(1) % 3,
                    param1,
                    ..Default::default()
                })
            } else {
                MavMessage::COMMAND_INT(COMMAND_INT_DATA {
                    target_system: FC.0,
                    target_component: at(3) % 2,
                    frame: MavFrame::MAV_FRAME_GLOBAL,
                    command,
                    param1,
                    ..Default::default()
                })
            };
            (msg, if at(3) & 2 == 0 { GROUND } else { OTHER_GROUND })
        }
        // The flight controller's ack of the last command it was given.
        13 => {
            return to_fc(MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                command: commands.last?,
                result: MavResult::MAV_RESULT_ACCEPTED,
                target_system: GROUND.0,
                target_component: GROUND.1,
                ..Default::default()
            }));
        }
        _ => return None,
    })
}

fn ack_result(b: u8) -> MavMissionResult {
    match b % 4 {
        0 => MavMissionResult::MAV_MISSION_ERROR,
        1 => MavMissionResult::MAV_MISSION_NO_SPACE,
        2 => MavMissionResult::MAV_MISSION_INVALID_SEQUENCE,
        _ => MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
    }
}

pub fn run(data: &[u8]) {
    let start = Instant::ZERO;
    let scheduler = SchedulerConfig::for_radio(RATE, BURST);
    let profile = Profile::parse(PROFILE, "px4-normal.toml").expect("shipped profile");
    let mut bconf = BridgeConfig::new(profile, scheduler);
    bconf.signing = Some(signing(1));
    if data.len() % 2 == 1 {
        bconf.compact = Some(CompactConfig::default());
    }
    let mut rconf = RouterConfig::new(scheduler);
    rconf.signing = Some(signing(2));
    let mut bridge = Bridge::new(bconf, start).expect("bridge");
    let mut router = Router::new(rconf, start).expect("router");
    let (mut bridge_budget, mut router_budget) =
        (Budget { start, sent: 0 }, Budget { start, sent: 0 });
    let mut check_bridge = signing(9).signer();
    let mut check_router = signing(9).signer();
    let mut watch = MissionWatch::default();
    let mut commands = CommandWatch::default();
    let mut senders: HashMap<(u8, u8), Sender> = HashMap::new();
    let mut now = start;
    // Input: records of [op, advance_ms, len, bytes...].
    let mut rest = data;
    while let [op, advance, len, tail @ ..] = rest {
        let n = usize::from(*len).min(tail.len());
        let (bytes, next) = tail.split_at(n);
        rest = next;
        now += Duration::from_millis(u64::from(*advance) * 4);
        if *op >= 0xF0 {
            if let Some((msg, from)) = structured(*op, bytes, &watch, &commands) {
                let sender = senders
                    .entry(from)
                    .or_insert_with(|| Sender::new(from.0, from.1, MavlinkVersion::V2));
                let frame = sender.frame(&msg);
                if from == FC {
                    watch.fc_bytes(frame.as_bytes());
                    bridge.handle_fc_bytes(now, frame.as_bytes());
                } else {
                    watch.ground_bytes(frame.as_bytes());
                    commands.ground_bytes(frame.as_bytes());
                    let _ = router.handle_gcs_bytes(now, frame.as_bytes());
                }
            }
        } else {
            match op % 6 {
                0 => {
                    watch.fc_bytes(bytes);
                    bridge.handle_fc_bytes(now, bytes);
                }
                1 => {
                    watch.ground_bytes(bytes);
                    commands.ground_bytes(bytes);
                    let _ = router.handle_gcs_bytes(now, bytes);
                }
                2 => bridge.handle_radio_bytes(now, bytes),
                3 => router.handle_radio_bytes(now, bytes),
                4 => {
                    // The bridge drops a partial frame its reader holds: so does ours.
                    if watch.fc_in.flush_partial() {
                        watch.fc_bytes(&[]);
                    }
                    bridge.handle_fc_idle(now);
                }
                _ => router.handle_radio_idle(now),
            }
        }
        bridge.handle_timeout(now);
        router.handle_timeout(now);
        while let Some(frame) = bridge.poll_radio_transmit(now, 4096) {
            bridge_budget.check(now, frame.as_bytes().len(), "bridge");
            assert_signed(&mut check_bridge, frame.as_bytes(), now, "bridge");
            router.handle_radio_bytes(now, frame.as_bytes());
        }
        while let Some(frame) = router.poll_radio_transmit(now, 4096) {
            router_budget.check(now, frame.as_bytes().len(), "router");
            assert_signed(&mut check_router, frame.as_bytes(), now, "router");
            bridge.handle_radio_bytes(now, frame.as_bytes());
        }
        while let Some(f) = bridge.poll_fc_transmit(now) {
            watch.fc_got(&f);
            commands.fc_got(&f);
        }
        while let Some(f) = router.poll_gcs_transmit() {
            watch.ground_got(&f);
        }
    }
}
