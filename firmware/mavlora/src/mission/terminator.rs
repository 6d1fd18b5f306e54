//! The router's side of mission uploads: it terminates the ground station's transfer
//! locally and streams the plan over the radio.
//!
//! Ground leg (standard protocol, answered as the vehicle): a `MISSION_COUNT` from the ground
//! opens a transfer (a count from the same ground again starts it over from item 0, except a
//! repeat before any item came, which is our lost request; a count from another ground while
//! one uploads is refused with `MAV_MISSION_DENIED`, as autopilots refuse a second partner);
//! the router asks for the items as the radio takes them (cut through: the next while no item
//! frame waits to leave, and at the latest [`HOLD_MAX`] after the ground's last send) and
//! for the plan's last [`HELD_ITEMS`] only once the bridge misses nothing sent before them,
//! so the ground's wait for the vehicle's answer after its last item is short whatever the
//! plan's size and the radio's losses. With the plan in, the ground waits for the vehicle's
//! answer on its own timeouts: the router does not on its own request an item it already has, since a ground station may count each repeated request against its
//! retries (MAVSDK does, and then gives up without a word while the vehicle takes the plan;
//! it sends nothing while it waits). A ground that resends its last item when its timer
//! fires (the protocol's retry; QGroundControl, pymavlink scripts, SDKs with 0.5 s × 3) has
//! shown its period: from then on it is asked for that item again at 4/5 of it
//! ([`KEEPALIVE_SHARE`]), so its timer never fires again while the radio leg works, and it
//! spent one retry of its own. The ground is told what the vehicle answered, never anything
//! the router made up: ACCEPTED only for the bridge's ack naming this transfer, once the
//! ground has sent every item (the bridge checked the plan against the poll's name), and no other `MISSION_ACK` of the
//! vehicle reaches a ground while it uploads that type (an autopilot's ack to something
//! else, `opaque_id` 0 as ArduPilot's always are, would read as the upload's answer). A
//! `MISSION_ACK` with an error from the ground cancels the transfer. Legacy `MISSION_ITEM`
//! answers are refused with `MAV_MISSION_UNSUPPORTED`: converting float coordinates is
//! autopilot-specific, and the vehicle must get exactly the plan the ground meant.
//!
//! Partial writes (`MISSION_WRITE_PARTIAL_LIST`) and `MISSION_CLEAR_ALL` are the autopilot's
//! business: they pass through, and so do the items of a partial write and the vehicle's
//! requests and acks for them (see [`MissionTerminator::from_vehicle`]).
//!
//! Radio leg: `MISSION_COUNT{opaque_id = transfer id}` as soon as the ground's count comes
//! (the id's plan part is 0: the plan is not known yet), then every item as it comes, one
//! behind the other (no round trip per item), packed several to a frame ([`super::pack`]) unless
//! [`TerminatorConfig::pack_bytes`] is `None`, each frame paced at its own length on the
//! radio; the bridge asks for the lost ones by range. A status poll goes right behind the
//! stream (and behind each batch of repairs): the radio keeps order, so when the poll arrives
//! every frame before it has arrived or is lost, and the bridge answers with what it misses,
//! "busy" or its ack (see [`super::relay`]); once the plan is complete the poll names it (the
//! low 24 bits of its CRC, [`pack::poll`]), and the bridge checks what it assembled against
//! that name. The poll is an item frame without items, packed or not (the bridge knows it for a poll even if it never saw the transfer; a count always
//! starts a transfer there). While the bridge stays silent the poll is repeated at a timeout
//! that follows the round trip measured from polls to their answers (RFC 6298; Karn's rule:
//! only a poll answered while it was the only one out, by a request that did not cross our
//! latest frames, is a sample), doubling after [`POLLS_BEFORE_BACKOFF`] unanswered polls (up to
//! [`TerminatorConfig::poll_max`]); before any is measured the timeout is the time two of
//! the largest stream frames take at the paced rate plus [`super::MARGIN`], within
//! [`TerminatorConfig::poll_min`] and [`TerminatorConfig::poll_initial`]. A request for an
//! item sent again less than the shortest measured round trip ago (before one is measured,
//! the unmeasured poll timeout) crossed that copy and is not answered twice.

use crate::time::Duration;
use std::collections::VecDeque;

use tracing::{debug, info, warn};

use mavlink::{MavHeader, MavlinkVersion};

use super::pack;
use super::plan::{plan_hash, transfer_id};
use super::relay::{ack, request};
use super::rtt::{RttEstimator, unmeasured_timeout};
use crate::dialect::{
    MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MavMessage, MavMissionResult, MavMissionType,
};
use crate::time::Instant;
use crate::wire::encode;

/// Router-side mission timeouts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TerminatorConfig {
    /// An item request to the ground (a local link) is repeated after this long...
    pub ground_timeout: Duration,
    /// ...this many times in all before the ground counts as gone.
    pub ground_attempts: u32,
    /// Status poll timeout (the stream left, the bridge silent) before a round trip is
    /// measured, at most.
    pub poll_initial: Duration,
    /// Shortest poll timeout.
    pub poll_min: Duration,
    /// Unanswered polls back off (doubling) up to this interval.
    pub poll_max: Duration,
    /// The bridge silent this long after the stream left: the ground is told MAV_MISSION_ERROR.
    pub silence_limit: Duration,
    /// Stream frames handed to the radio scheduler at most at once: the rest wait here, so
    /// a 100-item plan neither overflows the scheduler's queue nor bursts past the radio's
    /// buffer, a command still gets out between items, and a restart drops what never left.
    pub window: usize,
    /// The stream is released at most at this many bytes/s (the router sets its radio
    /// budget): the scheduler's burst allowance would otherwise pour a plan into a radio
    /// whose buffer (256 bytes on a LoRa modem) drops what does not fit. `None`: no pacing.
    pub pace_bytes_per_s: Option<u32>,
    /// Bytes the radio leg adds to each MAVLink 2 frame (13 when it signs): pacing counts
    /// each frame at its length on the radio.
    pub frame_extra_bytes: u32,
    /// Items go packed into `MAVLORA_MISSION_ITEMS` frames of at most this many data bytes
    /// (at most [`pack::MAX_DATA`]; a survey's waypoint costs ~8 bytes instead of a
    /// 49-byte `MISSION_ITEM_INT`); `None`: one `MISSION_ITEM_INT` per item.
    pub pack_bytes: Option<usize>,
}

impl Default for TerminatorConfig {
    fn default() -> Self {
        Self {
            ground_timeout: Duration::from_millis(500),
            ground_attempts: 5,
            poll_initial: Duration::from_millis(1500),
            poll_min: Duration::from_millis(200),
            // One poll every 2 s at most finds the end of a long fade within 2 s.
            poll_max: Duration::from_secs(2),
            silence_limit: Duration::from_secs(60),
            window: 4,
            pace_bytes_per_s: None,
            frame_extra_bytes: 13,
            // A 224-byte frame (237 signed): one air packet of SiK (250) or LoRa (251).
            pack_bytes: Some(pack::MAX_DATA),
        }
    }
}

/// A ground that resends its last item on its own timeout is asked for it again at this
/// share (numerator, denominator) of the period it showed: just before its timer fires again.
pub const KEEPALIVE_SHARE: (u32, u32) = (4, 5);
const KEEPALIVE_MIN: Duration = Duration::from_millis(100);
const KEEPALIVE_MAX: Duration = Duration::from_secs(10);

/// The ground's last items are asked for only once the bridge holds everything before them
/// (each asked for anyway, one at a time, when the ground has waited [`HOLD_MAX`]): the ground
/// then waits for the vehicle's answer no longer than a few frames and a poll take, even
/// when the radio lost part of the plan (MAVSDK gives up 2.5 s after its last send).
pub const HELD_ITEMS: u16 = 5;

/// The longest a ground waits for our next request while the radio is busy or we hold the
/// plan's tail back: the protocol's default step timeout (a ground that resends sooner is
/// asked at once).
pub const HOLD_MAX: Duration = Duration::from_millis(1500);

/// Items held back of a plan of `count`: never the only one.
fn held(count: u16) -> u16 {
    HELD_ITEMS.min(count.saturating_sub(1))
}

/// Unanswered polls after which the poll timeout starts doubling: a fade that swallows a
/// poll or its answer is not congestion, the next poll should follow one round trip later (a
/// poll is ~22 bytes); a bridge silent for longer is polled less and less often.
pub const POLLS_BEFORE_BACKOFF: u32 = 5;

/// Counters of the router's mission side.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TerminatorStats {
    /// Uploads the ground started (each `MISSION_COUNT`).
    pub uploads: u64,
    /// Uploads restarted by a new `MISSION_COUNT` before they finished.
    pub restarts: u64,
    /// Uploads the ground cancelled.
    pub cancelled: u64,
    /// Uploads the vehicle accepted (ground told ACCEPTED).
    pub accepted: u64,
    /// Uploads that ended in an error for the ground (the vehicle's or a silent radio).
    pub failed: u64,
    /// Items streamed over the radio (first sends).
    pub items_streamed: u64,
    /// Items sent again because the bridge asked (selective repair).
    pub items_repaired: u64,
    /// Status polls sent.
    pub polls: u64,
    /// Round trips measured from polls to their answers.
    pub poll_rtt_samples: u64,
    /// Uploads refused: a `MISSION_COUNT` from another ground while one uploads
    /// (`MAV_MISSION_DENIED`), legacy `MISSION_ITEM` answers (`MAV_MISSION_UNSUPPORTED`).
    pub refused: u64,
    /// The vehicle's own `MISSION_ACK`s held back from a ground while it uploads that type
    /// (only the bridge's ack naming the transfer answers an upload).
    pub vehicle_acks_held: u64,
    /// The last item requested again from a ground that resends it on its own timeout.
    pub keepalives: u64,
    /// Acks from the radio for an older transfer, dropped.
    pub stale_acks: u64,
}

#[derive(Debug)]
enum State {
    Idle,
    /// An upload in progress: the ground's items come in and stream over the radio.
    Relaying {
        ground: (u8, u8),
        vehicle: (u8, u8),
        mission_type: MavMissionType,
        /// Items in the plan (the ground's count).
        count: u16,
        /// The ground's items so far, in order: the whole plan once `plan` is set.
        items: Vec<MISSION_ITEM_INT_DATA>,
        /// Items put into stream frames; the rest wait to fill one.
        framed: usize,
        /// Items whose first copy has left for the radio.
        first_sent: usize,
        /// Our request for the next item, out to the ground: when, and how often asked.
        asked: Option<(Instant, u32)>,
        /// The plan's CRC part, once the ground has sent every item.
        plan: Option<u32>,
        id: u32,
        /// When the last of our frames left, or the bridge last spoke.
        quiet_since: Instant,
        /// Polls sent since the bridge last spoke.
        polls_unanswered: u32,
        /// When the last poll was queued.
        poll_sent: Instant,
        /// When each item was last released to the radio.
        sent_at: Vec<Option<Instant>>,
        /// When the bridge last spoke (or the first stream finished leaving).
        heard: Instant,
        /// Whether the first stream has left (polls do not count as news from the bridge).
        streamed: bool,
        /// When the ground last sent its last item.
        ground_sent: Instant,
        /// The ground's own retry period, once it resent its last item unasked: from then
        /// on it is asked for it again at 4/5 of that period (see [`KEEPALIVE_SHARE`]).
        keepalive: Option<Duration>,
        /// When we last asked for the last item again.
        asked_again: Option<Instant>,
        /// The bridge showed it holds every item sent before the plan's tail: the ground is
        /// asked for the rest of it.
        released: bool,
        /// A poll went behind what was sent when the tail was held back.
        hold_polled: bool,
        /// The bridge asked for items since our latest poll left (its answer to a poll lists
        /// the missing runs lowest first: a run above them is no news that all is there).
        repaired_since_poll: bool,
    },
    Done {
        ground: (u8, u8),
        vehicle: (u8, u8),
        mission_type: MavMissionType,
        count: u16,
        result: MavMissionResult,
    },
}

/// Sans-IO mission terminator of the router.
#[derive(Debug)]
pub struct MissionTerminator {
    config: TerminatorConfig,
    state: State,
    generation: u8,
    /// Transfer ids of recent transfers (acks for them are stale, not the ground's business).
    recent: VecDeque<u32>,
    to_ground: VecDeque<((u8, u8), MavMessage)>,
    /// Cancels: out at once.
    to_radio: VecDeque<MavMessage>,
    /// The stream (count, items, repairs, polls): out through the window.
    stream: VecDeque<MavMessage>,
    /// Stream frames in the scheduler, not yet on the radio.
    in_queue: usize,
    /// The next stream frame is not released before this (pacing).
    next_release: Instant,
    /// Largest stream frame released (bytes on the radio), for the unmeasured poll timeout.
    largest_frame: u64,
    /// A status poll waits to go behind the stream.
    poll_pending: bool,
    /// Shortest round trip measured: a request that comes back sooner after an item was sent
    /// cannot be about that send (it crossed it).
    min_rtt: Duration,
    /// Round trip to the bridge, measured from polls; kept across transfers.
    rtt: RttEstimator,
    /// Operations of the ground's that pass through to the autopilot (clear-alls, partial
    /// writes, downloads), latest last: the vehicle's acks answer these.
    ops: VecDeque<PassThrough>,
    stats: TerminatorStats,
}

/// A ground's operation passed through to the autopilot, which answers it.
#[derive(Debug, Clone, Copy)]
struct PassThrough {
    ground: (u8, u8),
    mission_type: MavMissionType,
    /// A partial write: the ground's items are the autopilot's.
    partial: bool,
    /// Its start or its latest message.
    at: Instant,
}

/// An operation with nothing from its ground for this long is over (ArduPilot gives an
/// upload up after 8 s without an item, PX4 any operation after 5 s).
const OP_IDLE: Duration = Duration::from_secs(10);

/// Operations remembered at most (a ground has one or two at a time).
const OPS_KEPT: usize = 8;

impl MissionTerminator {
    /// An idle terminator.
    pub fn new(config: TerminatorConfig) -> Self {
        Self {
            config,
            state: State::Idle,
            generation: 0,
            recent: VecDeque::new(),
            to_ground: VecDeque::new(),
            to_radio: VecDeque::new(),
            stream: VecDeque::new(),
            in_queue: 0,
            next_release: Instant::ZERO,
            largest_frame: 0,
            poll_pending: false,
            min_rtt: Duration::ZERO,
            rtt: RttEstimator::new(config.poll_initial, config.poll_min, config.poll_max),
            ops: VecDeque::new(),
            stats: TerminatorStats::default(),
        }
    }

    /// The same terminator numbering its transfers after `generation`. A router started
    /// again numbers from where its seed says, not from 0: the bridge may still hold the ack
    /// of a transfer numbered before the restart, and the same plan under the same id would
    /// read there as that finished transfer (the router seeds it from its signing clock).
    pub fn with_generation(mut self, generation: u8) -> Self {
        self.generation = generation;
        self
    }

    /// The round trip to the bridge, as measured from polls.
    pub fn rtt(&self) -> &RttEstimator {
        &self.rtt
    }

    /// A request for an item sent less than this long ago crossed that copy: the shortest
    /// round trip measured, or before one is, the round trip of the largest frame at the
    /// paced rate (a poll's answer can cross a repair queued behind that poll).
    fn crossing_window(&self) -> Duration {
        if self.stats.poll_rtt_samples > 0 {
            return self.min_rtt;
        }
        match self.config.pace_bytes_per_s.filter(|r| *r > 0) {
            Some(rate) if self.largest_frame > 0 => unmeasured_timeout(self.largest_frame, rate),
            _ => Duration::ZERO,
        }
    }

    /// Poll timeout with no poll unanswered: the measured one, or before any is measured
    /// two of the largest stream frames at the paced rate plus the margin.
    fn poll_base(&self) -> Duration {
        if self.rtt.samples() > 0 {
            return self.rtt.rto();
        }
        match self.config.pace_bytes_per_s.filter(|r| *r > 0) {
            Some(rate) if self.largest_frame > 0 => unmeasured_timeout(self.largest_frame, rate)
                .clamp(self.config.poll_min, self.config.poll_initial),
            _ => self.config.poll_initial,
        }
    }

    /// The poll timeout after `unanswered` unanswered polls: the base up to
    /// [`POLLS_BEFORE_BACKOFF`], then doubling, at most [`TerminatorConfig::poll_max`].
    fn poll_after(&self, unanswered: u32) -> Duration {
        let doublings = unanswered.saturating_sub(POLLS_BEFORE_BACKOFF).min(16);
        (self.poll_base() * 2u32.pow(doublings)).min(self.config.poll_max)
    }

    /// Counters so far.
    pub fn stats(&self) -> TerminatorStats {
        self.stats
    }

    /// A message from the ground station `from` (system, component); `autopilot` is the
    /// component that answers for a vehicle addressed as component 0. Returns whether it was
    /// taken (else the caller forwards it).
    // MISSION_ITEM is deprecated but older ground stations still send it.
    #[allow(deprecated)]
    pub fn from_ground(
        &mut self,
        now: Instant,
        from: (u8, u8),
        autopilot: u8,
        msg: &MavMessage,
    ) -> bool {
        let vehicle = |system: u8, component: u8| {
            let component = if component == 0 { autopilot } else { component };
            (system, component)
        };
        match msg {
            MavMessage::MISSION_COUNT(c) => {
                let v = vehicle(c.target_system, c.target_component);
                self.ground_count(now, from, v, c);
                true
            }
            MavMessage::MISSION_ITEM_INT(item) => self.ground_item(now, from, item),
            MavMessage::MISSION_ITEM(item) => {
                self.ground_legacy_item(now, from, item.seq, item.mission_type)
            }
            MavMessage::MISSION_ACK(a) if a.mavtype != MavMissionResult::MAV_MISSION_ACCEPTED => {
                self.end_op(from, a.mission_type);
                self.ground_cancel(from, a.mission_type)
            }
            // A download's last word.
            MavMessage::MISSION_ACK(a) => {
                self.end_op(from, a.mission_type);
                false
            }
            // The ground moved on from its own upload of that type: the vehicle must not get
            // it now. The operation itself is the autopilot's.
            MavMessage::MISSION_CLEAR_ALL(c) => {
                self.ground_moved_on(from, c.mission_type);
                self.start_op(now, from, c.mission_type, false);
                false
            }
            MavMessage::MISSION_WRITE_PARTIAL_LIST(w) => {
                self.ground_moved_on(from, w.mission_type);
                self.start_op(now, from, w.mission_type, true);
                false
            }
            // Downloads: the autopilot answers them (an error in a `MISSION_ACK`).
            MavMessage::MISSION_REQUEST_LIST(r) => {
                self.start_op(now, from, r.mission_type, false);
                false
            }
            MavMessage::MISSION_REQUEST_PARTIAL_LIST(r) => {
                self.start_op(now, from, r.mission_type, false);
                false
            }
            MavMessage::MISSION_REQUEST_INT(r) => {
                self.touch_op(now, from, r.mission_type);
                false
            }
            MavMessage::MISSION_REQUEST(r) => {
                self.touch_op(now, from, r.mission_type);
                false
            }
            _ => false,
        }
    }

    /// `ground` started an operation of type `t` the autopilot answers.
    fn start_op(&mut self, now: Instant, ground: (u8, u8), t: MavMissionType, partial: bool) {
        self.ops
            .retain(|o| !(o.ground == ground && o.mission_type == t));
        if self.ops.len() == OPS_KEPT {
            self.ops.pop_front();
        }
        self.ops.push_back(PassThrough {
            ground,
            mission_type: t,
            partial,
            at: now,
        });
    }

    /// `ground` goes on with its operation of type `t` (a download's next request), or
    /// starts one (a download whose list request we did not see).
    fn touch_op(&mut self, now: Instant, ground: (u8, u8), t: MavMissionType) {
        match self.live_op(now, ground, t) {
            Some(k) => self.ops[k].at = now,
            None => self.start_op(now, ground, t, false),
        }
    }

    fn end_op(&mut self, ground: (u8, u8), t: MavMissionType) {
        self.ops
            .retain(|o| !(o.ground == ground && o.mission_type == t));
    }

    /// The operation of `ground` of type `t` still going on at `now`.
    fn live_op(&self, now: Instant, ground: (u8, u8), t: MavMissionType) -> Option<usize> {
        self.ops.iter().position(|o| {
            o.ground == ground
                && o.mission_type == t
                && now.saturating_duration_since(o.at) < OP_IDLE
        })
    }

    /// Whether an item from `ground` of type `t` belongs to a partial write it started
    /// (recently: an autopilot gives one up after seconds of silence).
    fn partial_item(&mut self, now: Instant, ground: (u8, u8), t: MavMissionType) -> bool {
        match self.live_op(now, ground, t) {
            Some(k) if self.ops[k].partial => {
                self.ops[k].at = now;
                true
            }
            _ => false,
        }
    }

    // `..Default::default()` on a full literal: the dialect may grow.
    #[allow(clippy::needless_update)]
    fn ground_count(
        &mut self,
        now: Instant,
        ground: (u8, u8),
        vehicle: (u8, u8),
        c: &MISSION_COUNT_DATA,
    ) {
        let busy = match &self.state {
            State::Relaying {
                ground: g,
                mission_type,
                count,
                items,
                ..
            } => Some((*g, *mission_type, (*count, items.is_empty()))),
            _ => None,
        };
        if let Some((g, t, fresh)) = busy {
            if g != ground {
                // Another ground station while one uploads: refused, as an autopilot refuses
                // a second partner; the upload in progress goes on.
                warn!(
                    ?ground,
                    uploading = ?g,
                    "mission upload refused: another ground station is uploading"
                );
                self.stats.refused += 1;
                let denied = ack(
                    ground,
                    MavMissionResult::MAV_MISSION_DENIED,
                    c.mission_type,
                    0,
                );
                self.to_ground.push_back((vehicle, denied));
                return;
            }
            // The same count again before any item came (or an empty plan's while the
            // vehicle has not answered): our answer was lost, not a new plan.
            if t == c.mission_type && fresh == (c.count, true) {
                self.ask_again(now);
                return;
            }
            self.stats.restarts += 1;
            self.cancel_radio();
        }
        self.end_op(ground, c.mission_type);
        self.stats.uploads += 1;
        // Generation 0 would make the id 0, which names no transfer.
        self.generation = self.generation.wrapping_add(1).max(1);
        // The plan part is 0: the count leaves before the plan is known, and the poll names
        // the plan once the ground has sent it all.
        let id = transfer_id(self.generation, 0);
        self.recent.push_back(id);
        if self.recent.len() > 16 {
            self.recent.pop_front();
        }
        info!(count = c.count, mission_type = ?c.mission_type, id, "mission upload from the ground");
        self.stream
            .push_back(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count: c.count,
                target_system: vehicle.0,
                target_component: vehicle.1,
                mission_type: c.mission_type,
                opaque_id: id,
                ..Default::default()
            }));
        self.state = State::Relaying {
            ground,
            vehicle,
            mission_type: c.mission_type,
            count: c.count,
            items: Vec::with_capacity(c.count.into()),
            framed: 0,
            first_sent: 0,
            asked: None,
            plan: None,
            released: false,
            hold_polled: false,
            repaired_since_poll: false,
            id,
            quiet_since: now,
            polls_unanswered: 0,
            poll_sent: now,
            sent_at: vec![None; usize::from(c.count)],
            heard: now,
            streamed: false,
            ground_sent: now,
            keepalive: None,
            asked_again: None,
        };
        self.advance(now);
    }

    /// Asks the ground for the next item again now (our request or its answer was lost, or
    /// the ground's own timer fired while we waited for the radio: a new request restarts
    /// any ground's timer).
    fn ask_again(&mut self, now: Instant) {
        if let State::Relaying {
            ground,
            vehicle,
            mission_type,
            count,
            items,
            asked,
            ..
        } = &mut self.state
            && items.len() < usize::from(*count)
        {
            *asked = Some((now, asked.map_or(1, |(_, n)| n)));
            let next = request(*ground, items.len() as u16, *mission_type);
            self.to_ground.push_back((*vehicle, next));
        }
    }

    fn ground_item(&mut self, now: Instant, from: (u8, u8), item: &MISSION_ITEM_INT_DATA) -> bool {
        // An item of a partial write goes to the autopilot, which asked for it (the ground's
        // own upload of that type, if any, ended when the partial write began).
        if self.partial_item(now, from, item.mission_type) {
            return false;
        }
        match &mut self.state {
            State::Relaying {
                ground,
                mission_type,
                count,
                items,
                asked,
                ground_sent,
                keepalive,
                asked_again,
                hold_polled,
                ..
            } if *ground == from && item.mission_type == *mission_type => {
                let next = items.len();
                let complete = next == usize::from(*count);
                if !complete && usize::from(item.seq) == next {
                    items.push(item.clone());
                    *asked = None;
                    *ground_sent = now;
                    *hold_polled = false;
                    self.advance(now);
                } else if !complete && next.checked_sub(1) == Some(usize::from(item.seq)) {
                    // Our request for the next one was lost, or we held it back while the
                    // radio was busy and the ground's timer fired: ask for it now.
                    self.ask_again(now);
                } else if complete && next.checked_sub(1) == Some(usize::from(item.seq)) {
                    // The ground's own retry of its last item: the vehicle has not answered
                    // yet. Unasked (not the answer to our request again): the ground's own
                    // timeout fired, and it retries by resending. That shows its period.
                    let unasked = asked_again.is_none_or(|at| at < *ground_sent);
                    if keepalive.is_none() && unasked {
                        let period = now.saturating_duration_since(*ground_sent);
                        let ask = (period * KEEPALIVE_SHARE.0 / KEEPALIVE_SHARE.1)
                            .clamp(KEEPALIVE_MIN, KEEPALIVE_MAX);
                        debug!(?period, ?ask, "the ground resends on its own timeout");
                        *keepalive = Some(ask);
                    }
                    *ground_sent = now;
                }
                true
            }
            State::Done {
                ground,
                vehicle,
                mission_type,
                count,
                result,
            } if *ground == from && item.mission_type == *mission_type => {
                if count.checked_sub(1) == Some(item.seq) {
                    // Our ack was lost: the ground repeats its last item.
                    let again = ack(*ground, *result, *mission_type, 0);
                    self.to_ground.push_back((*vehicle, again));
                }
                true
            }
            // An item nobody asked for is nobody's business.
            _ => true,
        }
    }

    /// A legacy `MISSION_ITEM` (float coordinates) from the ground. In its own upload it is
    /// refused with `MAV_MISSION_UNSUPPORTED` (how x and y become `MISSION_ITEM_INT`'s
    /// integers differs between autopilots); in a partial write it is the autopilot's.
    fn ground_legacy_item(
        &mut self,
        now: Instant,
        from: (u8, u8),
        seq: u16,
        t: MavMissionType,
    ) -> bool {
        if self.partial_item(now, from, t) {
            return false;
        }
        match &self.state {
            State::Relaying {
                ground,
                vehicle,
                mission_type,
                count,
                items,
                ..
            } if *ground == from && *mission_type == t && items.len() < usize::from(*count) => {
                warn!(
                    seq,
                    "legacy MISSION_ITEM in a mission upload refused (MISSION_ITEM_INT only)"
                );
                self.stats.refused += 1;
                let (g, v, count) = (*ground, *vehicle, *count);
                // The bridge has the count and perhaps items already: it must drop them.
                self.cancel_radio();
                self.to_ground
                    .push_back((v, ack(g, MavMissionResult::MAV_MISSION_UNSUPPORTED, t, 0)));
                self.state = State::Done {
                    ground: g,
                    vehicle: v,
                    mission_type: t,
                    count,
                    result: MavMissionResult::MAV_MISSION_UNSUPPORTED,
                };
                true
            }
            State::Done {
                ground,
                vehicle,
                mission_type,
                result: MavMissionResult::MAV_MISSION_UNSUPPORTED,
                ..
            } if *ground == from && *mission_type == t => {
                let again = ack(*ground, MavMissionResult::MAV_MISSION_UNSUPPORTED, t, 0);
                self.to_ground.push_back((*vehicle, again));
                true
            }
            State::Relaying {
                ground,
                mission_type,
                ..
            } if *ground == from && *mission_type == t => true,
            _ => true,
        }
    }

    fn ground_cancel(&mut self, from: (u8, u8), mission_type: MavMissionType) -> bool {
        let ours = self.uploading(from, mission_type);
        if ours {
            info!("the ground cancelled its mission upload");
            self.stats.cancelled += 1;
            self.cancel_radio();
            self.state = State::Idle;
        }
        ours
    }

    /// Whether `ground` is uploading a plan of type `t` (collecting or relaying it).
    fn uploading(&self, ground: (u8, u8), t: MavMissionType) -> bool {
        match &self.state {
            State::Relaying {
                ground: g,
                mission_type,
                ..
            } => *g == ground && *mission_type == t,
            _ => false,
        }
    }

    /// `ground` started another operation on type `t` (or all types): its own upload of that
    /// type, if any, is over and the vehicle must not get it.
    fn ground_moved_on(&mut self, ground: (u8, u8), t: MavMissionType) {
        let current = match &self.state {
            State::Relaying {
                ground: g,
                mission_type,
                ..
            } if *g == ground => Some(*mission_type),
            _ => None,
        };
        if let Some(current) = current
            && (current == t || t == MavMissionType::MAV_MISSION_TYPE_ALL)
        {
            info!(
                ?t,
                "the ground left its mission upload for another operation"
            );
            self.stats.cancelled += 1;
            self.cancel_radio();
            self.state = State::Idle;
        }
    }

    /// A mission message from the vehicle (its autopilot, not the bridge's radio leg) for
    /// the ground at `now`: whether to forward it. Requests pass (a partial write's, which
    /// the ground answers with items for the autopilot). A `MISSION_ACK` passes only as the
    /// answer to an operation its ground passed through (a clear-all, a partial write, a
    /// download) and never to a ground uploading that type: only the bridge's ack naming the
    /// transfer answers an upload, and an autopilot's ack to something else (`opaque_id` 0,
    /// as ArduPilot's always are) would read as its answer.
    pub fn from_vehicle(&mut self, now: Instant, msg: &MavMessage) -> bool {
        let MavMessage::MISSION_ACK(a) = msg else {
            return true;
        };
        let all = MavMissionType::MAV_MISSION_TYPE_ALL;
        let op = self.ops.iter().position(|o| {
            a.target_system == o.ground.0
                && (a.target_component == o.ground.1 || a.target_component == 0)
                && (a.mission_type == o.mission_type || o.mission_type == all)
                && now.saturating_duration_since(o.at) < OP_IDLE
        });
        let uploading = match &self.state {
            State::Relaying {
                ground,
                mission_type,
                ..
            } => {
                (a.target_system == ground.0 || a.target_system == 0)
                    && (a.mission_type == *mission_type || a.mission_type == all)
            }
            _ => false,
        };
        match op {
            Some(k) if !uploading => {
                // The autopilot's answer ends the operation.
                self.ops.remove(k);
                true
            }
            _ => {
                debug!(result = ?a.mavtype, "a MISSION_ACK of the vehicle's answering nothing of the ground's, held back");
                self.stats.vehicle_acks_held += 1;
                false
            }
        }
    }

    /// Tells the bridge a transfer in flight is cancelled.
    fn cancel_radio(&mut self) {
        if let State::Relaying {
            vehicle,
            mission_type,
            id,
            ..
        } = &self.state
        {
            let cancel = ack(
                *vehicle,
                MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
                *mission_type,
                *id,
            );
            self.to_radio.push_back(cancel);
        }
        // What has not left yet is of no use to anyone.
        self.stream.clear();
        self.poll_pending = false;
    }

    /// Frames the items that wait (a packed frame once it is full, all of them once the plan
    /// is complete), names the plan once complete, and asks the ground for the next item
    /// while no frame waits to leave: the ground's requests follow the radio's progress, so
    /// the ground never waits long for the next (MAVSDK gives up 2.5 s after its last send,
    /// without a word, and a whole plan takes longer than that over LoRa), and its last item
    /// is asked for only when little but that item is left to send.
    fn advance(&mut self, now: Instant) {
        let hold = self.holding();
        let State::Relaying {
            ground,
            vehicle,
            mission_type,
            count,
            items,
            framed,
            asked,
            plan,
            id,
            hold_polled,
            first_sent,
            ..
        } = &mut self.state
        else {
            return;
        };
        let complete = items.len() == usize::from(*count);
        if *framed < items.len() {
            let run = &items[*framed..];
            let mut frames = item_frames(&self.config, *id, *vehicle, *mission_type, *count, run);
            if !complete && !hold && self.config.pack_bytes.is_some() {
                // The last frame may have room for the items still to come.
                frames.pop();
            }
            let n: usize = frames.iter().map(items_in).sum();
            *framed += n;
            self.stats.items_streamed += n as u64;
            self.stream.extend(frames);
        }
        if complete {
            if plan.is_none() {
                *plan = Some(plan_hash(*mission_type, items) & 0x00FF_FFFF);
                info!(
                    count = items.len(),
                    id = *id,
                    "plan from the ground complete, a poll behind its stream names it"
                );
                // A poll right behind the stream: a lost tail is asked for one round trip
                // later, and the bridge learns what plan it must have assembled.
                self.poll_pending = !items.is_empty();
            }
            return;
        }
        if hold {
            // Everything asked for so far is on its way: a poll behind it, and the bridge's
            // answer tells whether it all arrived.
            if !*hold_polled {
                *hold_polled = true;
                self.poll_pending = true;
            }
            return;
        }
        // Repairs waiting do not hold the ground up: only items not sent once do.
        if asked.is_none() && *first_sent == *framed {
            *asked = Some((now, 1));
            let next = request(*ground, items.len() as u16, *mission_type);
            self.to_ground.push_back((*vehicle, next));
        }
    }

    /// Whether the plan's tail is held back (see [`HELD_ITEMS`]).
    fn holding(&self) -> bool {
        match &self.state {
            State::Relaying {
                count,
                items,
                released,
                ..
            } => {
                let remaining = *count - items.len() as u16;
                remaining > 0 && remaining <= held(*count) && !*released
            }
            _ => false,
        }
    }

    /// A mission message from the radio. Returns whether it was taken (else the caller
    /// forwards it to the ground).
    // MISSION_REQUEST is deprecated but older autopilots and tools still send it.
    #[allow(deprecated)]
    pub fn from_radio(&mut self, now: Instant, msg: &MavMessage) -> bool {
        match msg {
            // Only our bridge requests items from the ground side: uploads end here.
            MavMessage::MISSION_REQUEST_INT(r) => {
                self.bridge_request(now, r.seq, r.mission_type);
                true
            }
            MavMessage::MISSION_REQUEST(r) => {
                self.bridge_request(now, r.seq, r.mission_type);
                true
            }
            // The bridge's repair request on the radio leg: items start..=end again.
            MavMessage::MISSION_REQUEST_PARTIAL_LIST(r) => {
                self.bridge_range(
                    now,
                    r.start_index as u16,
                    r.end_index as u16,
                    r.mission_type,
                );
                true
            }
            MavMessage::MISSION_ACK(a) if a.opaque_id != 0 => {
                self.bridge_ack(now, a.opaque_id, a.mavtype);
                true
            }
            _ => false,
        }
    }

    fn bridge_request(&mut self, now: Instant, seq: u16, t: MavMissionType) {
        // seq == count: "all items here, the autopilot is busy": alive, nothing to send.
        self.bridge_range(now, seq, seq, t);
    }

    /// The bridge spoke about the transfer: it is alive, and (with `sample`) a poll it
    /// answered while it was the only one out is a round-trip sample.
    fn bridge_heard(&mut self, now: Instant, sample: bool) {
        let State::Relaying {
            quiet_since,
            polls_unanswered,
            poll_sent,
            heard,
            ..
        } = &mut self.state
        else {
            return;
        };
        if *polls_unanswered == 1 && sample {
            let rtt = now.saturating_duration_since(*poll_sent);
            self.rtt.sample(rtt);
            self.min_rtt = match self.stats.poll_rtt_samples {
                0 => rtt,
                _ => self.min_rtt.min(rtt),
            };
            self.stats.poll_rtt_samples += 1;
        }
        *polls_unanswered = 0;
        *heard = now;
        *quiet_since = now;
    }

    /// Items `start..=end` again, those not already waiting to leave, ahead of the rest of
    /// the stream (the bridge only looks for gaps above what it has seen).
    fn bridge_range(&mut self, now: Instant, start: u16, end: u16, t: MavMissionType) {
        let State::Relaying {
            vehicle,
            mission_type,
            count,
            items,
            framed,
            id,
            sent_at,
            ..
        } = &self.state
        else {
            return;
        };
        if t != *mission_type {
            return;
        }
        let nothing_lower = match &self.state {
            State::Relaying {
                repaired_since_poll,
                ..
            } => !*repaired_since_poll && self.stream.is_empty(),
            _ => false,
        };
        if self.holding()
            && nothing_lower
            && usize::from(start) >= *framed
            && *framed == items.len()
        {
            // The bridge misses nothing we sent: the ground's tail now.
            debug!(
                start,
                "the bridge holds everything sent, asking the ground for the rest"
            );
            if let State::Relaying { released, .. } = &mut self.state {
                *released = true;
            }
            self.bridge_heard(now, true);
            self.advance(now);
            return;
        }
        // Not what still waits to leave, nor what left less than the shortest round trip
        // ago (the request was sent before that copy could have arrived).
        let waiting = |seq: usize| self.stream.iter().any(|m| covers(m, seq));
        let window = self.crossing_window();
        let crossed =
            |seq: usize| sent_at[seq].is_some_and(|t| now.saturating_duration_since(t) < window);
        let mut crossed_any = false;
        let mut runs: Vec<(usize, usize)> = Vec::new();
        // Items not framed yet have not been sent: they go with the stream.
        let last = (*framed).min(usize::from(end) + 1);
        for seq in usize::from(start)..last {
            if waiting(seq) {
                continue;
            }
            if crossed(seq) {
                crossed_any = true;
                continue;
            }
            match runs.last_mut() {
                Some((_, e)) if *e + 1 == seq => *e = seq,
                _ => runs.push((seq, seq)),
            }
        }
        let mut repairs = Vec::new();
        for (a, b) in runs {
            self.stats.items_repaired += (b - a + 1) as u64;
            repairs.extend(item_frames(
                &self.config,
                *id,
                *vehicle,
                *mission_type,
                *count,
                &items[a..=b],
            ));
        }
        // A request that crossed our latest frames was sent before our poll arrived: it is
        // not the poll's answer, its time no round-trip sample.
        self.bridge_heard(now, !crossed_any);
        let at = usize::from(
            self.stream
                .front()
                .is_some_and(|m| matches!(m, MavMessage::MISSION_COUNT(_))),
        );
        if !repairs.is_empty() {
            // ...and a poll behind them.
            self.poll_pending = true;
            if let State::Relaying {
                repaired_since_poll,
                ..
            } = &mut self.state
            {
                *repaired_since_poll = true;
            }
        }
        for (k, frame) in repairs.into_iter().enumerate() {
            self.stream.insert(at + k, frame);
        }
    }

    fn bridge_ack(&mut self, now: Instant, opaque_id: u32, result: MavMissionResult) {
        let State::Relaying {
            ground,
            vehicle,
            mission_type,
            items,
            plan,
            id,
            ..
        } = &self.state
        else {
            self.stats.stale_acks += u64::from(self.recent.contains(&opaque_id));
            return;
        };
        if opaque_id != *id {
            self.stats.stale_acks += 1;
            debug!(opaque_id, "ack for an older transfer dropped");
            return;
        }
        if result == MavMissionResult::MAV_MISSION_ACCEPTED && plan.is_none() {
            // The bridge cannot hold a plan the ground has not finished sending.
            warn!(opaque_id, "ACCEPTED for a plan not complete yet, dropped");
            self.stats.stale_acks += 1;
            return;
        }
        let (g, v, t, n) = (*ground, *vehicle, *mission_type, items.len() as u16);
        self.bridge_heard(now, true);
        self.finish(g, v, t, n, result);
    }

    fn finish(
        &mut self,
        ground: (u8, u8),
        vehicle: (u8, u8),
        mission_type: MavMissionType,
        count: u16,
        result: MavMissionResult,
    ) {
        if result == MavMissionResult::MAV_MISSION_ACCEPTED {
            self.stats.accepted += 1;
            info!(count, "the vehicle holds the plan, ground told ACCEPTED");
        } else {
            self.stats.failed += 1;
            warn!(?result, "mission upload failed at the vehicle");
        }
        self.to_ground
            .push_back((vehicle, ack(ground, result, mission_type, 0)));
        self.poll_pending = false;
        self.state = State::Done {
            ground,
            vehicle,
            mission_type,
            count,
            result,
        };
    }

    /// One of the frames it queued for the radio left (the caller tells it by the frame's
    /// sender and id): the status poll waits for the whole stream to be on the air.
    pub fn radio_frame_left(&mut self, now: Instant) {
        self.in_queue = self.in_queue.saturating_sub(1);
        let outstanding = self.outstanding();
        if let State::Relaying {
            quiet_since,
            heard,
            streamed,
            plan,
            ..
        } = &mut self.state
        {
            *quiet_since = now;
            if outstanding == 0 && !*streamed && plan.is_some() {
                *streamed = true;
                *heard = (*heard).max(now);
            }
        }
    }

    /// Stream frames (the poll included) not yet on the radio.
    fn outstanding(&self) -> usize {
        self.stream.len() + self.in_queue + usize::from(self.poll_pending)
    }

    /// The status poll of the transfer being relayed: an item frame without items, packed or
    /// not (the bridge knows it for a poll even if it never saw the count). Never the count
    /// again: a count always starts a transfer at the bridge, which never answers one from
    /// memory.
    fn poll_message(&self) -> Option<MavMessage> {
        let State::Relaying {
            vehicle,
            mission_type,
            count,
            plan,
            id,
            ..
        } = &self.state
        else {
            return None;
        };
        Some(pack::poll(*id, *count, *vehicle, *mission_type, *plan))
    }

    /// When something is due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let release = ((!self.stream.is_empty() || self.poll_pending)
            && self.in_queue < self.config.window)
            .then_some(self.next_release);
        self.state_timeout().into_iter().chain(release).min()
    }

    fn state_timeout(&self) -> Option<Instant> {
        let outstanding = self.outstanding();
        let holding = self.holding();
        match &self.state {
            State::Relaying {
                quiet_since,
                polls_unanswered,
                ground_sent,
                keepalive,
                asked,
                plan,
                hold_polled,
                ..
            } => {
                let ground = asked.map(|(at, _)| at + self.config.ground_timeout);
                // Polls once the whole plan is streaming, or its tail is held back: before,
                // the stream is not over.
                let poll = (outstanding == 0 && (plan.is_some() || (holding && *hold_polled)))
                    .then(|| *quiet_since + self.poll_after(*polls_unanswered));
                let ask = keepalive.map(|k| *ground_sent + k);
                // However busy the radio, the ground is asked for its next item before it
                // has waited longer than it may.
                let release = (plan.is_none() && asked.is_none()).then(|| *ground_sent + HOLD_MAX);
                [ground, poll, ask, release].into_iter().flatten().min()
            }
            _ => None,
        }
    }

    /// Keep-alives, polls and give-ups due at `now`.
    // `..Default::default()` on full literals: the dialect may grow.
    #[allow(clippy::needless_update)]
    pub fn handle_timeout(&mut self, now: Instant) {
        let outstanding = self.outstanding();
        let holding = self.holding();
        let poll_after = match &self.state {
            State::Relaying {
                polls_unanswered, ..
            } => self.poll_after(*polls_unanswered),
            _ => Duration::ZERO,
        };
        if let State::Relaying {
            asked: None,
            plan: None,
            ground_sent,
            ..
        } = &self.state
            && now >= *ground_sent + HOLD_MAX
        {
            // The ground has waited as long as it may for our next request (the radio
            // busy with repairs, or the tail held back): one more item.
            debug!("the ground waited long enough, asking for one more item");
            self.ask_again(now);
        }
        if let State::Relaying {
            ground,
            vehicle,
            mission_type,
            items,
            asked: Some((at, asks)),
            ..
        } = &mut self.state
            && now >= *at + self.config.ground_timeout
        {
            if *asks >= self.config.ground_attempts {
                // As an autopilot does when an upload stalls: the ground is told, and the
                // bridge drops what it has of the plan.
                warn!("the ground stopped sending its items, upload dropped");
                self.stats.failed += 1;
                let cancelled = ack(
                    *ground,
                    MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
                    *mission_type,
                    0,
                );
                self.to_ground.push_back((*vehicle, cancelled));
                self.cancel_radio();
                self.state = State::Idle;
                return;
            }
            *asks += 1;
            *at = now;
            let again = request(*ground, items.len() as u16, *mission_type);
            self.to_ground.push_back((*vehicle, again));
        }
        match &mut self.state {
            State::Relaying {
                ground,
                vehicle,
                mission_type,
                items,
                id,
                quiet_since,
                heard,
                ground_sent,
                keepalive,
                asked_again,
                plan,
                hold_polled,
                ..
            } if plan.is_some() || (holding && *hold_polled) => {
                if let Some(k) = keepalive
                    && now >= *ground_sent + *k
                    && let Some(last) = items.len().checked_sub(1)
                {
                    self.stats.keepalives += 1;
                    *asked_again = Some(now);
                    // Not answered yet: ask again no sooner than one period on.
                    *ground_sent = now;
                    let again = request(*ground, last as u16, *mission_type);
                    self.to_ground.push_back((*vehicle, again));
                }
                if outstanding > 0 || now < *quiet_since + poll_after {
                    return;
                }
                if now.saturating_duration_since(*heard) >= self.config.silence_limit {
                    warn!(id = *id, "the vehicle side stayed silent, upload failed");
                    let (g, v, t, n) = (*ground, *vehicle, *mission_type, items.len() as u16);
                    self.finish(g, v, t, n, MavMissionResult::MAV_MISSION_ERROR);
                    return;
                }
                debug!(%now, after = ?poll_after, "bridge quiet, polling");
                *quiet_since = now;
                self.poll_pending = true;
            }
            _ => {}
        }
    }

    /// Next message for the ground station, with the (system, component) it must come from
    /// (the vehicle the ground addressed).
    pub fn poll_ground(&mut self) -> Option<((u8, u8), MavMessage)> {
        self.to_ground.pop_front()
    }

    /// Next message for the radio: cancels at once, the stream while fewer than
    /// [`TerminatorConfig::window`] of its frames wait in the scheduler (each one that
    /// leaves is reported with [`radio_frame_left`](Self::radio_frame_left)).
    pub fn poll_radio(&mut self, now: Instant) -> Option<MavMessage> {
        if let Some(msg) = self.to_radio.pop_front() {
            return Some(msg);
        }
        if self.in_queue >= self.config.window || now < self.next_release {
            return None;
        }
        let msg = match self.stream.pop_front() {
            Some(msg) => msg,
            // The poll goes behind everything queued: when it arrives, all before it has
            // arrived or is lost.
            None if self.poll_pending => {
                self.poll_pending = false;
                let msg = self.poll_message()?;
                if let State::Relaying {
                    polls_unanswered,
                    poll_sent,
                    repaired_since_poll,
                    ..
                } = &mut self.state
                {
                    *repaired_since_poll = false;
                    self.stats.polls += 1;
                    *polls_unanswered += 1;
                    *poll_sent = now;
                }
                msg
            }
            None => return None,
        };
        self.in_queue += 1;
        let mut new_items = false;
        if let State::Relaying {
            sent_at,
            first_sent,
            ..
        } = &mut self.state
        {
            for (seq, at) in sent_at.iter_mut().enumerate() {
                if covers(&msg, seq) {
                    *at = Some(now);
                    if seq >= *first_sent {
                        *first_sent = seq + 1;
                        new_items = true;
                    }
                }
            }
        }
        if new_items {
            // The stream has room for the ground's next items.
            self.advance(now);
        }
        let len = radio_len(&msg) + u64::from(self.config.frame_extra_bytes);
        self.largest_frame = self.largest_frame.max(len);
        if let Some(rate) = self.config.pace_bytes_per_s.filter(|r| *r > 0) {
            let gap = Duration::from_micros(len * 1_000_000 / u64::from(rate));
            self.next_release = self.next_release.max(now) + gap;
        }
        Some(msg)
    }
}

/// The frames that carry `run` (consecutive items of `plan`): packed, or one each.
fn item_frames(
    config: &TerminatorConfig,
    id: u32,
    vehicle: (u8, u8),
    mission_type: MavMissionType,
    count: u16,
    run: &[MISSION_ITEM_INT_DATA],
) -> Vec<MavMessage> {
    match config.pack_bytes {
        Some(cap) => pack::frames(id, count, vehicle, mission_type, run, cap),
        None => run
            .iter()
            .map(|i| MavMessage::MISSION_ITEM_INT(to_vehicle(i, vehicle)))
            .collect(),
    }
}

/// Items a stream frame carries.
fn items_in(msg: &MavMessage) -> usize {
    match msg {
        MavMessage::MISSION_ITEM_INT(_) => 1,
        MavMessage::MAVLORA_MISSION_ITEMS(p) => usize::from(p.items),
        _ => 0,
    }
}

/// Whether a stream frame carries item `seq`.
fn covers(msg: &MavMessage, seq: usize) -> bool {
    match msg {
        MavMessage::MISSION_ITEM_INT(i) => usize::from(i.seq) == seq,
        MavMessage::MAVLORA_MISSION_ITEMS(p) => pack::span(p).contains(&(seq as u32)),
        _ => false,
    }
}

/// Bytes `msg` takes as a MAVLink 2 frame (trailing zeros trimmed), unsigned.
fn radio_len(msg: &MavMessage) -> u64 {
    encode(MavlinkVersion::V2, MavHeader::default(), msg)
        .as_bytes()
        .len() as u64
}

fn to_vehicle(item: &MISSION_ITEM_INT_DATA, vehicle: (u8, u8)) -> MISSION_ITEM_INT_DATA {
    MISSION_ITEM_INT_DATA {
        target_system: vehicle.0,
        target_component: vehicle.1,
        ..item.clone()
    }
}

#[cfg(test)]
#[path = "terminator_tests.rs"]
mod tests;
