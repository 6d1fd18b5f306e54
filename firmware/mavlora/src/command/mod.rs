//! Commands over a lossy radio. A ground station retries a command after 1.5 s without an ack
//! (the MAVLink command protocol's default); at 10 % loss each way one command in five needs
//! that retry and one in a hundred needs two, so the 99th-percentile command-to-ack time sits
//! above 3 s, SORA's medium TMPR bound. The relay closes that gap on the radio leg itself:
//!
//! - [`CommandRetransmitter`] (router): resends a command over the radio after a timeout that
//!   follows the measured command round trip (RFC 6298's estimate, as the mission relay, but
//!   without its backoff: loss on a radio is not congestion), until the
//!   vehicle's `COMMAND_ACK` comes back; the ground station's own retries of a command still
//!   in flight are dropped (the router is already retrying).
//! - [`AckCache`] (bridge): a command the flight controller has already acknowledged, seen
//!   again because the ack was lost on the radio, is answered with the same ack instead of
//!   being executed twice; a copy that arrives before the flight controller's ack (however
//!   long it takes) is dropped.
//!
//! # The invariant
//!
//! Each command a ground station sends (one intent: its first send and its own retries,
//! however many copies the router puts on the radio) is executed by the flight controller
//! at most once, and every distinct intent is executed when the link carries it: one with
//! the same parameters as an earlier one, and one sent after the router or the bridge
//! restarted. Where an end cannot tell whether a command already ran (a restart lost what
//! it knew), it does not run it and sends no ack: the ground station's timeout is the
//! command protocol's own "outcome unknown". `tests/command_intents.rs` checks it case by
//! case, `tests/command_relay.rs` over random plans, loss and ack-loss bursts.
//!
//! # Identity and confirmation (the MAVLink command protocol)
//!
//! A command is its [`CommandId`]: target system, target component, command id and every
//! parameter. `COMMAND_LONG.confirmation` 0 is a new command, more is a retransmission of
//! the same one; a new command with identical parameters is executed again. `COMMAND_INT`
//! has no confirmation field: an identical `COMMAND_INT` is a retry while the first is
//! unanswered (a ground station retries only then), and a new command once the ground got
//! its ack (ARM, DISARM, ARM; twenty holds in a row).
//!
//! Between router and bridge (both ours) each copy carries a tag ([`ack_tag`]): the
//! router's epoch, `generation << 3 | attempt` ([`radio_confirmation`]) and the copy's age.
//! `attempt` counts the router's sends of one command (0 first, saturating at 7);
//! `generation` tells two commands with the same identity apart, so a re-issued command
//! whose first copy was lost is not taken for a retransmission of the previous one; the
//! epoch, drawn at random at each router start, tells this run's generations from a
//! previous run's, which the bridge may still hold (both start at 0). The bridge gives the
//! flight controller the command without the tag and with a plain `confirmation` (0).
//!
//! # Restarts
//!
//! - The router: its copies carry a new epoch, so the bridge never answers them from the
//!   previous run's acks, and acks tagged with another epoch answer nothing here. For a
//!   [`RETRANSMIT_WINDOW`] after it started, a ground retry (`confirmation` > 0) of a
//!   command it never saw is not sent: the previous run may have had it executed
//!   ([`CommandRetransmitter::with_epoch`]).
//! - The bridge: a copy of a command it never saw, whose first copy (by the copy's age)
//!   went before it started, is not forwarded: it may have been executed before the restart
//!   with its ack lost ([`AckCache::new`]).
//!
//! # Acks
//!
//! `COMMAND_ACK` carries only the command id, so the bridge tags each ack it sends on the
//! radio with the epoch and generation of the command it answers (see [`ack_tag`]) and the
//! router matches it to exactly that command, restoring the
//! autopilot's `result_param2` (and MAVLink version) before the ground sees it. The router
//! keeps at most one command per (target system, command id) on the radio, so the vehicle
//! runs them in the order the ground sent them; a newer one with the same id goes as soon as
//! the older one is acknowledged: a late copy's ack names the older generation and is
//! swallowed (counted), never given to the newer one.
//!
//! An untagged ack (an autopilot's `result_param2` too large to share with the tag) cannot
//! be told apart so:
//! after such an older command that was sent more than once, the newer one waits until its
//! late copies' acks can no longer arrive (one maximum timeout after its last send). The
//! ground thus sees the acks of two commands with the same id in the order it sent them,
//! each answering its own.
//!
//! The choice when the ground moves on: an older command whose ground station stopped
//! retrying it (no retry within the protocol's 1.5 s and a margin after its last copy) while
//! a newer one with the same id waits is abandoned: no more copies, its acks swallowed (a
//! station that gave up would take them for the newer one's). Until then the newer one
//! waits: a station that still retries the older one takes the first ack with that id for
//! the older one's. An ack of the older one that comes when the ground may be giving up on
//! it (1.4 s after its last copy) is swallowed, and the ground's retry, if it comes, sends
//! the older one again. A waiting command the ground stopped retrying
//! for two maximum timeouts is never sent. A ground retry (`confirmation` > 0) of a command
//! the router already finished is sent again as that command (same generation: the bridge
//! answers from its cache) within the window, and dropped after it.
//!
//! # Redundant copies on a lossy link
//!
//! On a TDM radio (SiK) each side sends in its own window, half a round (118 ms at 64 kbit/s)
//! after the other's, and a lost air packet takes every frame in it: a command and its ack
//! get one chance per round each way, so at 10 % loss each way one round in five fails and
//! resends are quantised to whole rounds (~237 ms). One resend more per round cannot bring
//! the 99th percentile under two rounds (at best 97 % of commands are answered within two);
//! copies in *separate air packets of the same round* can. While the measured loss (the
//! worse direction, [`link_loss`]) is at least [`Redundancy::min_loss`], was within the last
//! [`Redundancy::clean_for`], or is not measured yet:
//!
//! - the router sends each command at once, [`Redundancy::pair_gap`] later (past one full
//!   air packet: another packet of the same window when the radio may send; only if the
//!   radio budget carries the frame within that gap, see
//!   [`CommandRetransmitter::with_budget`]), [`Redundancy::spacing`] after the first (half a
//!   round and a margin: another packet whatever the TDM phase, in the same window when the
//!   first two waited for it) and twice that after the first (a copy in the second round's
//!   window); the ack ends the copies still planned;
//! - the bridge sends each ack twice, [`Redundancy::spacing`] apart (the first is queued
//!   while the vehicle's side waits for its window, the second goes in a later packet of
//!   that window), and a copy of the command that arrives before that repeat is answered
//!   by it, not by a third ack in the first one's packet; a later copy gets the cached ack
//!   and its own repeat.
//!
//! The bridge's cache makes every extra copy harmless: it is answered from the cache and
//! never executed again. Only tagged acks are repeated (an untagged one could be taken for
//! the next command's). On a link measured clean (below `min_loss` for `clean_for`) a
//! command goes once and is resent on its timeout only.
//!
//! The router's timeout runs from its last copy and is never shorter than
//! [`Redundancy::spacing`] (a resend sooner could share its previous copy's air packet).
//! Its round-trip samples are unambiguous: the bridge names in each ack which copy it
//! answers ([`ack_tag`]).
//!
//! # How long
//!
//! The router sends one command for at most [`RETRANSMIT_WINDOW`] (its
//! [`MAX_ATTEMPTS`] × [`MAX_RTO`]) after the first send, ground retries included; the
//! bridge keeps each command [`ACK_HOLD`] (that window plus one more maximum timeout for the
//! radio's latency) after it first arrived, so no copy can outlive its entry.

mod ack_cache;
pub mod ack_tag;
mod retransmit;

use crate::command::ack_tag::Epoch;
use crate::time::{Duration, Instant};

pub use ack_cache::{AckCache, AckCacheStats, CacheVerdict};
pub use ack_tag::{AckTag, CommandTag};
pub use retransmit::{Admission, CommandRetransmitter, RetransmitStats};

use crate::dialect::{COMMAND_LONG_DATA, MavMessage};

/// The most sends of one command over the radio (the attempt field has 3 bits).
pub const MAX_ATTEMPTS: u32 = 8;
/// The router's longest retransmission timeout (a ground station's own 1.5 s retry).
pub const MAX_RTO: Duration = Duration::from_millis(1500);
/// How long after its first send the router may still send a copy of a command.
pub const RETRANSMIT_WINDOW: Duration = Duration::from_millis(1500 * MAX_ATTEMPTS as u64);
/// How long the bridge keeps a command and its ack after the first copy arrived.
pub const ACK_HOLD: Duration = Duration::from_millis(1500 * (MAX_ATTEMPTS as u64 + 1));

/// Redundant copies of commands (router) and acks (bridge) on a lossy link: see the module
/// doc. The times are the radio's; [`Redundancy::SIK_64K`] is the default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Redundancy {
    /// Measured loss (the worse direction) from which commands and acks go redundantly. Two
    /// rounds of single copies both fail for (1 − (1 − p)²)² of the commands: 0.16 % at 2 %
    /// loss each way (within the 1 % a 99th percentile leaves, with room for the spread of
    /// 200 commands), 1 % at 5 %, 3.6 % at 10 %.
    pub min_loss: f64,
    /// The router's second copy of a command, this long after the first: past one full air
    /// packet and the radio's gap after it, so that it leaves in a packet of its own when the
    /// radio may send at once.
    pub pair_gap: Duration,
    /// A copy this long after another leaves in another air packet whatever the TDM phase:
    /// half the radio's round (one window and its silence) and a margin. The router's third
    /// copy, the bridge's repeat of an ack, and the shortest resend timeout.
    pub spacing: Duration,
    /// Redundancy stops only once the link was measured below `min_loss` this long without
    /// a break. A loss estimate over a few seconds of a slow link's frames often reads 0 at
    /// 10 % loss (a third of the 4 s windows of SiK's compact telemetry); 30 s without a
    /// lost frame does not happen at 10 % (0.9^85 air packets).
    pub clean_for: Duration,
}

impl Redundancy {
    /// SiK at 64 kbit/s (ArduPilot SiK `tdm.c`): 114.2 ms windows and 4.2 ms silences, a
    /// 118.4 ms half round; a full 250-byte air packet is on air 33 ms, with a 2 ms gap
    /// after it.
    pub const SIK_64K: Self = Self {
        min_loss: 0.02,
        pair_gap: Duration::from_millis(40),
        spacing: Duration::from_millis(125),
        clean_for: Duration::from_secs(30),
    };
}

/// Whether the link calls for redundant copies: yes until it was measured below
/// [`Redundancy::min_loss`] for [`Redundancy::clean_for`] without a break (a reading at or
/// above it, or none, starts over).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct LossGate {
    /// Start of the current run of clean readings.
    clean_since: Option<Instant>,
}

impl LossGate {
    /// A loss reading at `now` (`None`: not measured).
    pub(crate) fn observe(&mut self, now: Instant, loss: Option<f64>, r: &Redundancy) {
        if loss.is_some_and(|l| l < r.min_loss) {
            self.clean_since.get_or_insert(now);
        } else {
            self.clean_since = None;
        }
    }

    /// Whether copies go redundantly at `now`.
    pub(crate) fn lossy(&self, now: Instant, r: &Redundancy) -> bool {
        self.clean_since
            .is_none_or(|t| now.saturating_duration_since(t) < r.clean_for)
    }
}

impl Default for Redundancy {
    fn default() -> Self {
        Self::SIK_64K
    }
}

/// The loss a command meets: the worse of the two directions (this side's own estimate of
/// what it receives, and the peer's report of what it receives); `None` until both are
/// measured.
pub fn link_loss(own: Option<f64>, peer: Option<f64>) -> Option<f64> {
    Some(own?.max(peer?))
}

/// Which command a `COMMAND_LONG` or `COMMAND_INT` is, `confirmation` aside.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CommandId {
    /// Target system.
    pub target_system: u8,
    /// Target component (0: all).
    pub target_component: u8,
    /// Command id.
    pub command: u32,
    /// `COMMAND_INT` (frame, current, autocontinue), or `None` for `COMMAND_LONG`.
    int: Option<(u8, u8, u8)>,
    /// The seven parameters' bits.
    params: [u32; 7],
}

impl CommandId {
    /// The identity of a `COMMAND_LONG` or `COMMAND_INT`.
    pub fn of(msg: &MavMessage) -> Option<Self> {
        match msg {
            MavMessage::COMMAND_LONG(c) => Some(Self {
                target_system: c.target_system,
                target_component: c.target_component,
                command: c.command as u32,
                int: None,
                params: [
                    c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                ]
                .map(f32::to_bits),
            }),
            MavMessage::COMMAND_INT(c) => Some(Self {
                target_system: c.target_system,
                target_component: c.target_component,
                command: c.command as u32,
                int: Some((c.frame as u8, c.current, c.autocontinue)),
                params: [
                    c.param1.to_bits(),
                    c.param2.to_bits(),
                    c.param3.to_bits(),
                    c.param4.to_bits(),
                    c.x as u32,
                    c.y as u32,
                    c.z.to_bits(),
                ],
            }),
            _ => None,
        }
    }

    /// The (target system, command id) an ack names: one command per slot on the radio.
    pub fn slot(&self) -> (u8, u32) {
        (self.target_system, self.command)
    }

    /// Whether a `COMMAND_ACK` for `command` from (`system`, `component`) can answer this.
    /// A target of 0 is a broadcast: every receiver acks it with its own ids, so any system's
    /// (and any component's) ack answers it.
    pub fn answered_by(&self, system: u8, component: u8, command: u32) -> bool {
        (self.target_system == 0 || self.target_system == system)
            && self.command == command
            && (self.target_component == 0 || self.target_component == component)
    }
}

/// A router run's epoch ([`CommandRetransmitter::with_epoch`]): random, from the seed std
/// draws from the operating system for its hash maps, mixed with the wall clock. The
/// engines take it as configuration, so a run stays deterministic.
pub fn random_epoch() -> Epoch {
    use std::hash::BuildHasher;
    let clock = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let h = std::collections::hash_map::RandomState::new().hash_one(clock);
    (h ^ (h >> 16) ^ (h >> 32) ^ (h >> 48)) as Epoch
}

/// `COMMAND_LONG.confirmation`, `None` for `COMMAND_INT` and other messages.
pub fn confirmation(msg: &MavMessage) -> Option<u8> {
    match msg {
        MavMessage::COMMAND_LONG(c) => Some(c.confirmation),
        _ => None,
    }
}

/// The confirmation the router puts on the radio: `generation` (0..32) and `attempt` (0 for
/// the first send; saturates at 7).
pub fn radio_confirmation(generation: u8, attempt: u32) -> u8 {
    ((generation & 0x1f) << 3) | attempt.min(7) as u8
}

/// (generation, attempt) of a radio confirmation.
pub fn split_confirmation(confirmation: u8) -> (u8, u8) {
    (confirmation >> 3, confirmation & 7)
}

/// `frame` (decoded: `msg`) encoded again from its fields, a `COMMAND_LONG` with its
/// confirmation set: a radio tag after the fields ([`ack_tag`]) is gone. Other frames
/// unchanged.
pub fn with_confirmation(
    frame: &crate::wire::OwnedFrame,
    msg: &MavMessage,
    confirmation: u8,
) -> crate::wire::OwnedFrame {
    let msg = match msg {
        MavMessage::COMMAND_LONG(c) => MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            confirmation,
            ..c.clone()
        }),
        MavMessage::COMMAND_INT(_) => msg.clone(),
        _ => return frame.clone(),
    };
    crate::wire::encode(frame.version(), frame.header(), &msg)
}
