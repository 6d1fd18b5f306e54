//! The bridge's mission relay: receiver of the router's item stream on the radio leg,
//! sender with the standard protocol on the wire leg (the flight controller).
//!
//! Radio leg (router → bridge), our own use of standard messages:
//! - `MISSION_COUNT{count, mission_type, opaque_id = transfer id}` opens a transfer; the
//!   router streams every item behind it without waiting for requests, several to a frame
//!   (`MAVLORA_MISSION_ITEMS`, see [`super::pack`]; each names its transfer and the plan's
//!   size, so it also opens the transfer when the count was lost), or one `MISSION_ITEM_INT`
//!   each.
//! - A gap in the item sequence (the radio keeps order) is a loss: the bridge at once asks
//!   for each missing run, `MISSION_REQUEST_PARTIAL_LIST{start_index, end_index}` (both
//!   included; selective repair); the items the tail of the stream lost are requested when
//!   nothing arrived for one retransmission timeout, or at the router's poll.
//! - All items in: their CRC must match the plan the transfer names (no item of another
//!   plan mixed in), else all are requested again; then the wire leg runs. A transfer id
//!   carries the plan's CRC part, or 0 there when the router started streaming before the
//!   ground had sent the whole plan: then the router's poll names the plan once it has it,
//!   and the bridge waits for that poll.
//! - The router's status poll (a `MAVLORA_MISSION_ITEMS` without items, which also opens a
//!   transfer the bridge never saw) comes behind everything the router sent before it: every
//!   missing item is requested, however recently asked (the request or its answer was lost),
//!   "all here, the autopilot is busy" is `MISSION_REQUEST_INT{seq = count}`, a finished
//!   transfer repeats its `MISSION_ACK{opaque_id}`. A late item frame of a transfer that is
//!   over never reopens it. A count always opens its transfer, even one that finished here:
//!   it is never answered from memory (the autopilot may not hold that plan any more, and a
//!   restarted router may number a new upload as an old one); a router restart (its uptime
//!   going back, [`MissionRelay::router_restarted`]) also forgets the finished transfer.
//! - `MISSION_ACK{error, opaque_id}` from the router: the ground cancelled.
//! - A ground's own partial write (`MISSION_WRITE_PARTIAL_LIST`) and its items pass through
//!   to the autopilot.
//!
//! Wire leg: `MISSION_COUNT` to the autopilot, items on its requests (its 250 ms repeats are
//! harmless on a wire), its `MISSION_ACK` goes to the router with the transfer id. An
//! ACCEPTED answers the upload only once the autopilot asked for every item since our count
//! (an autopilot storing the previous plan slowly acks it after our next count went out);
//! an error ends it at any point. Every request and ack the autopilot addresses to us is
//! ours: one that answers no upload in progress is dropped, never passed to the radio. An
//! autopilot reboot mid-upload restarts the wire leg from `MISSION_COUNT`. A MAVLink 1
//! autopilot gets missions only: fence and rally plans are refused with
//! `MAV_MISSION_UNSUPPORTED` ([`MissionRelay::set_fc_mavlink1`]), as MAVLink 1 frames cannot
//! carry `mission_type` and it would take them for its mission.

use crate::time::Duration;
use std::collections::{BTreeMap, VecDeque};

use mavlink::Message as _;
use tracing::{debug, info, warn};

use super::pack;
use super::plan::{plan_hash, plan_part};
use super::rtt::RttEstimator;
use crate::dialect::{
    MAVLORA_MISSION_ITEMS_DATA, MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA,
    MISSION_REQUEST_INT_DATA, MISSION_REQUEST_PARTIAL_LIST_DATA, MavMessage, MavMissionResult,
    MavMissionType,
};
use crate::time::Instant;
use crate::wire::MAX_FRAME_LEN;

/// Relay timeouts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionConfig {
    /// Radio round trip assumed before one is measured.
    pub initial_rtt: Duration,
    /// Lower bound of the radio timeout (queueing jitter).
    pub min_rto: Duration,
    /// Upper bound of the radio timeout after backoff.
    pub max_rto: Duration,
    /// Repair rounds without any progress before the transfer is abandoned.
    pub radio_attempts: u32,
    /// Items requested at most per repair round (bounds what one round asks the router to
    /// send again; one request frame per run of missing items).
    pub repair_batch: usize,
    /// Wire leg timeout (MAVLink mission protocol default: 1500 ms).
    pub wire_timeout: Duration,
    /// Wire leg attempts per step (protocol: up to 5 retries).
    pub wire_attempts: u32,
}

impl Default for MissionConfig {
    fn default() -> Self {
        Self {
            initial_rtt: Duration::from_millis(1500),
            min_rto: Duration::from_millis(300),
            max_rto: Duration::from_secs(8),
            radio_attempts: 10,
            // A whole plan's worth: runs cost one request each, and the router paces what it
            // sends again.
            repair_batch: 256,
            wire_timeout: Duration::from_millis(1500),
            wire_attempts: 6,
        }
    }
}

impl MissionConfig {
    /// The defaults, with the round trip assumed before one is measured taken from the
    /// radio's budget: two of the largest frames (a request up, a packed item frame down) at
    /// `rate_bytes_per_s` plus [`MARGIN`](super::MARGIN)
    /// ([`unmeasured_timeout`](super::unmeasured_timeout), as the router's first poll), within
    /// `min_rto` and the default 1.5 s. An upload over a fast radio ends before any round trip is measured, so a loss at
    /// its end waited the whole 1.5 s: on SiK 64k that tripled an upload's time on 1 seed in
    /// 10 (the rig's `mission_efficiency`); this makes it ~0.3 s there, ~1.1 s on LoRa SF7.
    pub fn for_rate(rate_bytes_per_s: u32) -> Self {
        let d = Self::default();
        if rate_bytes_per_s == 0 {
            return d;
        }
        // The largest frame the radio leg carries: 255 payload bytes, signed.
        let first = super::unmeasured_timeout(MAX_FRAME_LEN as u64, rate_bytes_per_s);
        Self {
            initial_rtt: first.clamp(d.min_rto, d.initial_rtt),
            ..d
        }
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MissionStats {
    /// Transfers opened by the router.
    pub transfers: u64,
    /// Items requested over the radio (repairs; a loss-free transfer requests none).
    pub radio_requests: u64,
    /// Request frames sent over the radio (one per run of missing items).
    pub radio_request_frames: u64,
    /// Items received over the radio.
    pub radio_items: u64,
    /// Packed item frames (`MAVLORA_MISSION_ITEMS`) received.
    pub radio_packed_frames: u64,
    /// Packed item frames refused as unreadable.
    pub radio_bad_frames: u64,
    /// Frames for a transfer already finished or replaced, dropped.
    pub radio_stale_frames: u64,
    /// Items received that we already had.
    pub radio_duplicate_items: u64,
    /// Assembled plans whose CRC did not match the transfer id (all items requested again).
    pub plan_mismatches: u64,
    /// Items sent to the flight controller (its retries included).
    pub wire_items: u64,
    /// Wire uploads restarted because the flight controller rebooted.
    pub wire_restarts: u64,
    /// Uploads the flight controller accepted.
    pub completed: u64,
    /// Uploads that failed on either leg.
    pub failed: u64,
    /// Transfers the ground cancelled.
    pub cancelled: u64,
    /// Transfers refused with `MAV_MISSION_UNSUPPORTED`: a fence or rally plan for a
    /// MAVLink 1 flight controller, which cannot tell it from a mission.
    pub unsupported: u64,
    /// Acks from the flight controller that could not answer the upload in progress (before
    /// it asked for every item: an ack of an earlier upload or operation), not taken.
    pub wire_early_acks: u64,
    /// Requests and acks the flight controller addressed to us outside any upload of that
    /// type (late answers, the answer to our cancel), dropped.
    pub wire_stray: u64,
}

#[derive(Debug)]
enum Radio {
    Idle,
    Receiving {
        router: (u8, u8),
        id: u32,
        mission_type: MavMissionType,
        slots: Vec<Option<MISSION_ITEM_INT_DATA>>,
        /// One past the highest seq received: a later seq means the ones between were lost.
        horizon: u16,
        /// Repair requests in flight: seq → (sent at, sends).
        requested: BTreeMap<u16, (Instant, u32)>,
        /// Last item or poll received, or repair sent.
        heard: Instant,
        /// Repair rounds since the last progress.
        rounds: u32,
        /// The plan's CRC part the assembled items must match: the id's, or (an id whose plan
        /// part is 0: the router started streaming before the ground had sent every item)
        /// the one its poll names once it holds the whole plan.
        plan: Option<u32>,
    },
    /// All items in, the wire leg runs.
    Forwarding {
        router: (u8, u8),
        id: u32,
        mission_type: MavMissionType,
        count: u16,
    },
    /// Finished: a poll gets the same ack again.
    Done {
        router: (u8, u8),
        id: u32,
        mission_type: MavMissionType,
        result: MavMissionResult,
    },
}

#[derive(Debug)]
enum Wire {
    Idle,
    Sending {
        mission_type: MavMissionType,
        items: Vec<MISSION_ITEM_INT_DATA>,
        /// Last step sent: `None` for MISSION_COUNT, else the item seq.
        last: Option<u16>,
        /// Items the flight controller asked for (and got) since our latest count: its
        /// ACCEPTED answers this upload only once it has asked for every one.
        given: Vec<bool>,
        at: Instant,
        attempts: u32,
    },
}

/// Sans-IO mission relay of the bridge.
///
/// Feed it mission frames from the radio ([`handle_radio`](Self::handle_radio)) and those
/// the flight controller addresses to the bridge ([`handle_fc`](Self::handle_fc)); take what
/// to send with [`poll_radio`](Self::poll_radio) / [`poll_fc`](Self::poll_fc); wake it at
/// [`poll_timeout`](Self::poll_timeout) with [`handle_timeout`](Self::handle_timeout).
#[derive(Debug)]
pub struct MissionRelay {
    config: MissionConfig,
    rtt: RttEstimator,
    radio: Radio,
    wire: Wire,
    to_radio: VecDeque<MavMessage>,
    to_fc: VecDeque<MavMessage>,
    /// Items that arrived with no transfer open (its `MISSION_COUNT` was lost): kept for
    /// the next transfer, whose CRC check rejects them if they belong to another plan.
    orphans: BTreeMap<u16, MISSION_ITEM_INT_DATA>,
    /// Transfer ids seen lately (a frame of one that is not current is stale: never reopened).
    recent: VecDeque<u32>,
    /// A partial write from the radio in progress (its source, type, latest frame): its items
    /// are the autopilot's, not ours.
    partial: Option<((u8, u8), MavMissionType, Instant)>,
    /// The flight controller speaks MAVLink 1: `mission_type` does not reach it.
    fc_mavlink1: bool,
    stats: MissionStats,
}

/// A partial write with no item for this long is over (ArduPilot gives an upload up after
/// 8 s without an item).
const PARTIAL_WRITE_IDLE: Duration = Duration::from_secs(10);

/// Orphan items kept at most.
const MAX_ORPHANS: usize = 1024;

impl MissionRelay {
    /// An idle relay.
    pub fn new(config: MissionConfig) -> Self {
        Self {
            rtt: RttEstimator::new(config.initial_rtt, config.min_rto, config.max_rto),
            config,
            radio: Radio::Idle,
            wire: Wire::Idle,
            to_radio: VecDeque::new(),
            to_fc: VecDeque::new(),
            orphans: BTreeMap::new(),
            recent: VecDeque::new(),
            partial: None,
            fc_mavlink1: false,
            stats: MissionStats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> MissionStats {
        self.stats
    }

    /// The radio round-trip estimate.
    pub fn rtt(&self) -> &RttEstimator {
        &self.rtt
    }

    /// Whether the flight controller speaks MAVLink 1 (its heartbeat's version). MAVLink 1
    /// frames have no `mission_type`: a fence or rally upload would reach it as a mission, so
    /// such transfers are refused with `MAV_MISSION_UNSUPPORTED`.
    pub fn set_fc_mavlink1(&mut self, mavlink1: bool) {
        self.fc_mavlink1 = mavlink1;
    }

    /// A ground station's fence or rally operation was refused for a MAVLink 1 autopilot
    /// (see [`set_fc_mavlink1`](Self::set_fc_mavlink1)), outside a transfer: counted with the
    /// transfers refused.
    pub fn count_unsupported(&mut self) {
        self.stats.unsupported += 1;
    }

    /// Whether the flight controller's link carries plans of type `t`.
    fn carries(&self, t: MavMissionType) -> bool {
        !self.fc_mavlink1 || t == MavMissionType::MAV_MISSION_TYPE_MISSION
    }

    /// The router restarted (its uptime went back): it numbers transfers from its seed again
    /// and knows none of ours. A finished transfer is forgotten (the same id is a new upload
    /// now, never answered from memory), one still being received is dropped (nobody will
    /// finish it); an upload to the autopilot under way finishes (a half-written plan is
    /// worse than a plan nobody was told about).
    pub fn router_restarted(&mut self) {
        if matches!(self.radio, Radio::Done { .. } | Radio::Receiving { .. }) {
            info!("the router restarted: its earlier transfers are forgotten");
            self.radio = Radio::Idle;
        }
        self.recent.clear();
        self.orphans.clear();
    }

    /// Whether an item from `from` of type `t` belongs to a partial write in progress.
    fn partial_item(&mut self, now: Instant, from: (u8, u8), t: MavMissionType) -> bool {
        match &mut self.partial {
            Some((source, mission_type, at))
                if *source == from
                    && *mission_type == t
                    && now.saturating_duration_since(*at) < PARTIAL_WRITE_IDLE =>
            {
                *at = now;
                true
            }
            _ => false,
        }
    }

    /// A message from the radio sent by `from` (system, component), addressed to this
    /// vehicle. Returns whether the relay took it (else the caller forwards it to the flight
    /// controller).
    pub fn handle_radio(&mut self, now: Instant, from: (u8, u8), msg: &MavMessage) -> bool {
        match msg {
            MavMessage::MISSION_COUNT(c) => {
                self.radio_count(now, from, c);
                true
            }
            MavMessage::MISSION_ITEM_INT(item) => {
                if self.partial_item(now, from, item.mission_type) {
                    return false;
                }
                self.radio_item(now, item);
                true
            }
            MavMessage::MISSION_WRITE_PARTIAL_LIST(w) => {
                // The ground's partial write: the autopilot's business, and so are its items.
                self.partial = Some((from, w.mission_type, now));
                false
            }
            MavMessage::MAVLORA_MISSION_ITEMS(p) => {
                self.radio_packed(now, from, p);
                true
            }
            MavMessage::MISSION_ACK(a) => self.radio_cancel(a),
            _ => false,
        }
    }

    /// The router's status poll of transfer `id`, answered by state: every missing item
    /// requested, "busy" (`MISSION_REQUEST_INT{seq = count}`: all here, the autopilot is
    /// taking them) or the same ack again. Returns false if `id` is not the current transfer.
    fn answer_poll(&mut self, now: Instant, id: u32, named: Option<u32>) -> bool {
        match &mut self.radio {
            Radio::Receiving {
                id: current,
                heard,
                horizon,
                slots,
                plan,
                ..
            } if *current == id => {
                debug!(id, %now, "router polls the transfer");
                *heard = now;
                if plan_part(id) == 0 && named.is_some() {
                    *plan = named;
                }
                // The router polls once its whole stream has left and the radio keeps order:
                // whatever is missing now was lost (the items or our requests), none of it is
                // still on the way. Ask for all of it, however recently asked; the answer also
                // tells the router the round trip.
                *horizon = slots.len() as u16;
                self.repair_missing(now, true, true);
                true
            }
            Radio::Forwarding {
                id: current,
                router,
                count,
                mission_type,
            } if *current == id => {
                // All items are here; the autopilot is still taking them.
                let busy = request(*router, *count, *mission_type);
                self.to_radio.push_back(busy);
                true
            }
            Radio::Done {
                id: current,
                router,
                mission_type,
                result,
            } if *current == id => {
                let again = ack(*router, *result, *mission_type, id);
                self.to_radio.push_back(again);
                true
            }
            _ => false,
        }
    }

    fn radio_count(&mut self, now: Instant, from: (u8, u8), c: &MISSION_COUNT_DATA) {
        // A count always opens its transfer, even one already seen, never answered from
        // memory: a restarted router may number a new upload of the same plan as one that
        // finished here, and the autopilot may no longer hold it (a clear-all since). The
        // router's polls are item frames without items.
        self.recent.retain(|id| *id != c.opaque_id);
        if !self.open(now, from, c.count, c.mission_type, c.opaque_id) {
            return;
        }
        // Orphans below the horizon that are missing were lost: ask for them now.
        self.repair(now, false);
        self.check_complete(now);
    }

    /// The transfer currently open or finished.
    fn current_id(&self) -> Option<u32> {
        match &self.radio {
            Radio::Receiving { id, .. } | Radio::Forwarding { id, .. } | Radio::Done { id, .. } => {
                Some(*id)
            }
            Radio::Idle => None,
        }
    }

    /// Opens transfer `id` (replacing the one in progress), with the orphans that fit it;
    /// false if `id` is an earlier transfer's (a late item frame: only a count reopens it).
    fn open(
        &mut self,
        now: Instant,
        from: (u8, u8),
        count: u16,
        mission_type: MavMissionType,
        id: u32,
    ) -> bool {
        if id != 0 && self.recent.contains(&id) {
            self.stats.radio_stale_frames += 1;
            debug!(id, "frame of an earlier transfer dropped");
            return false;
        }
        info!(count, ?mission_type, id, "mission transfer from the router");
        if let Some(current) = self.current_id() {
            self.retire(current);
        }
        self.stats.transfers += 1;
        self.abort_wire();
        if !self.carries(mission_type) {
            // A MAVLink 1 autopilot would get the fence or rally points as mission items
            // (MAVLink 1 has no `mission_type`) and replace its mission with them.
            warn!(
                ?mission_type,
                "the flight controller speaks MAVLink 1: only missions, refused"
            );
            self.stats.unsupported += 1;
            self.stats.failed += 1;
            let result = MavMissionResult::MAV_MISSION_UNSUPPORTED;
            self.to_radio.push_back(ack(from, result, mission_type, id));
            self.radio = Radio::Done {
                router: from,
                id,
                mission_type,
                result,
            };
            return false;
        }
        let mut slots = vec![None; usize::from(count)];
        let mut horizon = 0;
        for (seq, item) in std::mem::take(&mut self.orphans) {
            if let Some(slot) = slots.get_mut(usize::from(seq))
                && item.mission_type == mission_type
            {
                *slot = Some(item);
                horizon = seq + 1;
            }
        }
        self.radio = Radio::Receiving {
            router: from,
            id,
            mission_type,
            slots,
            horizon,
            requested: BTreeMap::new(),
            heard: now,
            rounds: 0,
            plan: (plan_part(id) != 0).then_some(plan_part(id)),
        };
        true
    }

    /// Transfer `id` is over: a late frame of it is stale.
    fn retire(&mut self, id: u32) {
        if id != 0 && !self.recent.contains(&id) {
            self.recent.push_back(id);
            if self.recent.len() > 16 {
                self.recent.pop_front();
            }
        }
    }

    /// Items packed by the router: they open their transfer if its count was lost.
    fn radio_packed(&mut self, now: Instant, from: (u8, u8), p: &MAVLORA_MISSION_ITEMS_DATA) {
        self.stats.radio_packed_frames += 1;
        if p.items == 0 {
            // No item: the router's status poll (it opens the transfer if nothing else did).
            let named = pack::poll_plan(p);
            if !self.answer_poll(now, p.opaque_id, named)
                && (!self.open(now, from, p.count, p.mission_type, p.opaque_id)
                    || !self.answer_poll(now, p.opaque_id, named))
            {
                return;
            }
            // The poll may have named the plan the last thing missing: then the autopilot is
            // taking it, and the router hears so at once.
            let receiving = matches!(self.radio, Radio::Receiving { .. });
            self.check_complete(now);
            if receiving && matches!(self.radio, Radio::Forwarding { .. }) {
                self.answer_poll(now, p.opaque_id, None);
            }
            return;
        }
        let items = match pack::unpack(p) {
            Ok(items) => items,
            Err(e) => {
                self.stats.radio_bad_frames += 1;
                warn!(error = %e, "unreadable packed mission items dropped");
                return;
            }
        };
        match &self.radio {
            Radio::Receiving { id, .. } if *id == p.opaque_id => {}
            Radio::Forwarding { id, .. } | Radio::Done { id, .. } if *id == p.opaque_id => {
                // All here already: a repair that crossed the last item.
                self.stats.radio_duplicate_items += items.len() as u64;
                return;
            }
            _ => {
                if !self.open(now, from, p.count, p.mission_type, p.opaque_id) {
                    return;
                }
            }
        }
        let mut repair = false;
        let mut sampled = false;
        for item in &items {
            let (gap, answered) = self.take_item(now, item);
            if let Some((at, 1)) = answered
                && !sampled
            {
                // Karn's rule: only unambiguous round trips are samples; one per frame.
                self.rtt.sample(now.saturating_duration_since(at));
                sampled = true;
            }
            repair |= gap || answered.is_some();
        }
        if repair {
            self.repair(now, false);
        }
        self.check_complete(now);
    }

    fn radio_item(&mut self, now: Instant, item: &MISSION_ITEM_INT_DATA) {
        if !matches!(self.radio, Radio::Receiving { .. }) {
            if matches!(self.radio, Radio::Forwarding { .. }) || self.orphans.len() >= MAX_ORPHANS {
                self.stats.radio_duplicate_items += 1;
            } else {
                // Perhaps a new transfer whose count was lost: keep it for that count.
                self.orphans.insert(item.seq, item.clone());
            }
            return;
        }
        let (gap, answered) = self.take_item(now, item);
        if let Some((at, 1)) = answered {
            // Karn's rule: only unambiguous round trips are samples.
            self.rtt.sample(now.saturating_duration_since(at));
        }
        if gap || answered.is_some() {
            // The radio keeps order: what the stream skipped was lost. And an answered
            // request makes room for the next one: repairs flow at the round trip, a batch
            // in flight, rather than a batch per timeout.
            self.repair(now, false);
        }
        self.check_complete(now);
    }

    /// Stores one item of the transfer being received: whether it showed a gap, and the
    /// request it answered (sent at, sends).
    fn take_item(
        &mut self,
        now: Instant,
        item: &MISSION_ITEM_INT_DATA,
    ) -> (bool, Option<(Instant, u32)>) {
        let Radio::Receiving {
            slots,
            horizon,
            requested,
            heard,
            rounds,
            ..
        } = &mut self.radio
        else {
            return (false, None);
        };
        let seq = item.seq;
        let Some(slot) = slots.get_mut(usize::from(seq)) else {
            return (false, None);
        };
        *heard = now;
        if slot.is_some() {
            self.stats.radio_duplicate_items += 1;
            return (false, None);
        }
        *slot = Some(item.clone());
        *rounds = 0;
        self.stats.radio_items += 1;
        let answered = requested.remove(&seq);
        let gap = seq > *horizon;
        *horizon = (*horizon).max(seq + 1);
        (gap, answered)
    }

    /// Requests missing items not asked for within one RTO: below the horizon (known lost),
    /// or with `all` every missing one (our timeout: the tail may be lost too).
    fn repair(&mut self, now: Instant, all: bool) {
        self.repair_missing(now, all, false);
    }

    /// [`repair`](Self::repair), and with `again` also what was asked for less than one RTO
    /// ago (a poll showed it lost).
    // Indexing: the loop also builds `requested` entries keyed by the same seq.
    #[allow(clippy::needless_range_loop)]
    fn repair_missing(&mut self, now: Instant, all: bool, again: bool) {
        let rto = self.rtt.rto();
        let Radio::Receiving {
            router,
            mission_type,
            slots,
            horizon,
            requested,
            ..
        } = &mut self.radio
        else {
            return;
        };
        let limit = if all {
            slots.len()
        } else {
            usize::from(*horizon)
        };
        let mut sent = 0;
        let mut runs: Vec<(u16, u16)> = Vec::new();
        for seq in 0..limit {
            if sent >= self.config.repair_batch {
                break;
            }
            if slots[seq].is_some() {
                continue;
            }
            let seq = seq as u16;
            let entry = requested.entry(seq).or_insert((now, 0));
            // A request younger than one timeout may still be answered: asking again
            // would only put a second copy on the air.
            if entry.1 > 0 && !again && now.saturating_duration_since(entry.0) < rto {
                continue;
            }
            *entry = (now, entry.1 + 1);
            sent += 1;
            match runs.last_mut() {
                Some((_, end)) if *end + 1 == seq => *end = seq,
                _ => runs.push((seq, seq)),
            }
        }
        self.stats.radio_requests += sent as u64;
        self.stats.radio_request_frames += runs.len() as u64;
        for (start, end) in runs {
            self.to_radio
                .push_back(request_range(*router, start, end, *mission_type));
        }
    }

    fn check_complete(&mut self, now: Instant) {
        let Radio::Receiving {
            router,
            id,
            mission_type,
            slots,
            horizon,
            requested,
            plan,
            ..
        } = &mut self.radio
        else {
            return;
        };
        if slots.iter().any(Option::is_none) {
            return;
        }
        let expected = match (*id, *plan) {
            // A transfer without an id (not our router's): nothing to check against.
            (0, _) => None,
            (_, Some(plan)) => Some(plan),
            // Every item is here, the plan not named yet: the router's poll names it.
            (_, None) => return,
        };
        let items: Vec<_> = slots.iter().flatten().cloned().collect();
        if expected.is_some_and(|plan| plan_hash(*mission_type, &items) & 0x00FF_FFFF != plan) {
            warn!(
                id = *id,
                "assembled plan does not match the transfer id, asking again"
            );
            self.stats.plan_mismatches += 1;
            slots.iter_mut().for_each(|s| *s = None);
            *horizon = 0;
            requested.clear();
            self.repair(now, true);
            return;
        }
        let (router, id, mission_type) = (*router, *id, *mission_type);
        let count = items.len() as u16;
        info!(
            count,
            "mission received over the radio, uploading to the flight controller"
        );
        self.radio = Radio::Forwarding {
            router,
            id,
            mission_type,
            count,
        };
        if !self.carries(mission_type) {
            // The autopilot turned out to speak MAVLink 1 while the plan came in.
            self.stats.unsupported += 1;
            self.finish(MavMissionResult::MAV_MISSION_UNSUPPORTED);
            return;
        }
        self.to_fc.push_back(count_msg(count, mission_type));
        self.wire = Wire::Sending {
            mission_type,
            given: vec![false; items.len()],
            items,
            last: None,
            at: now,
            attempts: 1,
        };
    }

    /// The router's cancel (the ground cancelled): returns whether it was for us.
    fn radio_cancel(&mut self, a: &MISSION_ACK_DATA) -> bool {
        let current = match &self.radio {
            Radio::Receiving { id, .. } | Radio::Forwarding { id, .. } | Radio::Done { id, .. } => {
                *id
            }
            Radio::Idle => return a.opaque_id != 0,
        };
        if a.opaque_id == 0 {
            return false;
        }
        if a.opaque_id == current
            && a.mavtype != MavMissionResult::MAV_MISSION_ACCEPTED
            && !matches!(self.radio, Radio::Done { .. })
        {
            info!(id = current, "the ground cancelled the mission transfer");
            self.stats.cancelled += 1;
            self.abort_wire();
            self.retire(current);
            self.radio = Radio::Idle;
        }
        true
    }

    /// Stops a wire upload in progress, telling the autopilot (the protocol's cancel).
    fn abort_wire(&mut self) {
        if let Wire::Sending { mission_type, .. } = &self.wire {
            let cancel = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                mavtype: MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
                mission_type: *mission_type,
                ..Default::default()
            });
            self.to_fc.push_back(cancel);
        }
        self.wire = Wire::Idle;
    }

    /// The flight controller rebooted: an upload to it starts again from `MISSION_COUNT`
    /// (what it had received is gone).
    pub fn fc_rebooted(&mut self, now: Instant) {
        if let Wire::Sending {
            mission_type,
            items,
            last,
            given,
            at,
            attempts,
        } = &mut self.wire
        {
            info!("flight controller rebooted mid-upload, starting the upload again");
            self.stats.wire_restarts += 1;
            *last = None;
            given.iter_mut().for_each(|g| *g = false);
            *at = now;
            *attempts = 1;
            let count = count_msg(items.len() as u16, *mission_type);
            self.to_fc.push_back(count);
        }
    }

    /// A mission message the flight controller addressed to the bridge. Returns whether the
    /// relay took it: every request and ack addressed to us answers our own uploads, and one
    /// that answers none in progress (a late ack, the answer to our cancel) is nobody else's
    /// business (on the radio it would reach a ground station as the answer to its upload).
    // MISSION_REQUEST is deprecated but older autopilots and tools still send it.
    #[allow(deprecated)]
    pub fn handle_fc(&mut self, now: Instant, msg: &MavMessage) -> bool {
        let ours = matches!(
            msg,
            MavMessage::MISSION_ACK(_)
                | MavMessage::MISSION_REQUEST(_)
                | MavMessage::MISSION_REQUEST_INT(_)
        );
        if ours && !self.wire_step(now, msg) {
            self.stats.wire_stray += 1;
            debug!(
                msgid = msg.message_id(),
                "the autopilot's answer to no upload of ours, dropped"
            );
        }
        ours
    }

    /// One step of the wire upload; whether it belonged to it.
    #[allow(deprecated)]
    fn wire_step(&mut self, now: Instant, msg: &MavMessage) -> bool {
        let Wire::Sending {
            mission_type,
            items,
            last,
            given,
            at,
            attempts,
        } = &mut self.wire
        else {
            return false;
        };
        let seq = match msg {
            MavMessage::MISSION_REQUEST_INT(r) if r.mission_type == *mission_type => r.seq,
            MavMessage::MISSION_REQUEST(r) if r.mission_type == *mission_type => r.seq,
            MavMessage::MISSION_ACK(a) if a.mission_type == *mission_type => {
                // ACCEPTED answers this upload only once the autopilot asked for every item
                // (the last one last): before that it is an earlier upload's answer (an
                // autopilot that stores slowly acks plan A after our count for plan B went
                // out). An empty plan's ACCEPTED answers the count at once, and carries no
                // plan id (PX4 puts the stored plan's CRC in a non-empty upload's ack).
                let accepted = a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED;
                let complete = if items.is_empty() {
                    a.opaque_id == 0
                } else {
                    given.iter().all(|g| *g) && *last == Some(items.len() as u16 - 1)
                };
                if accepted && !complete {
                    self.stats.wire_early_acks += 1;
                    debug!("an ACCEPTED before the autopilot asked for every item: not ours");
                    return true;
                }
                let result = a.mavtype;
                self.wire = Wire::Idle;
                self.finish(result);
                return true;
            }
            _ => return false,
        };
        let Some(item) = items.get(usize::from(seq)) else {
            return true;
        };
        given[usize::from(seq)] = true;
        // Answer every request, repeats included: on the wire they cost nothing.
        self.to_fc
            .push_back(MavMessage::MISSION_ITEM_INT(item.clone()));
        self.stats.wire_items += 1;
        if *last != Some(seq) {
            *attempts = 1;
        }
        *last = Some(seq);
        *at = now;
        true
    }

    fn finish(&mut self, result: MavMissionResult) {
        let Radio::Forwarding {
            router,
            id,
            mission_type,
            count,
        } = self.radio
        else {
            return;
        };
        if result == MavMissionResult::MAV_MISSION_ACCEPTED {
            self.stats.completed += 1;
            info!(count, "flight controller accepted the mission");
        } else {
            self.stats.failed += 1;
            warn!(?result, "flight controller refused the mission");
        }
        self.to_radio
            .push_back(ack(router, result, mission_type, id));
        self.radio = Radio::Done {
            router,
            id,
            mission_type,
            result,
        };
    }

    /// When a timeout is due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let radio = match &self.radio {
            Radio::Receiving { heard, .. } => Some(*heard + self.rtt.rto()),
            _ => None,
        };
        let wire = match &self.wire {
            Wire::Sending { at, .. } => Some(*at + self.config.wire_timeout),
            Wire::Idle => None,
        };
        radio.into_iter().chain(wire).min()
    }

    /// Retries or gives up whatever timed out at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        if let Radio::Receiving {
            router,
            id,
            mission_type,
            heard,
            rounds,
            slots,
            ..
        } = &mut self.radio
            && now >= *heard + self.rtt.rto()
        {
            if slots.iter().all(Option::is_some) {
                // Only the plan's name is missing: the router polls until it gets an answer,
                // and nothing here is lost that a repair could bring.
                *heard = now;
            } else if *rounds >= self.config.radio_attempts {
                warn!(id = *id, "mission transfer over the radio abandoned");
                self.stats.failed += 1;
                let give_up = ack(
                    *router,
                    MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
                    *mission_type,
                    *id,
                );
                self.to_radio.push_back(give_up);
                let id = *id;
                self.retire(id);
                self.radio = Radio::Idle;
            } else {
                *rounds += 1;
                *heard = now;
                debug!(rto = ?self.rtt.rto(), %now, "no item for one timeout, repairing");
                // Repair first: the requests it repeats are one (un-backed-off) timeout old.
                self.repair(now, true);
                self.rtt.backoff();
            }
        }
        if let Wire::Sending {
            mission_type,
            items,
            last,
            given,
            at,
            attempts,
        } = &mut self.wire
            && now >= *at + self.config.wire_timeout
        {
            if *attempts >= self.config.wire_attempts {
                self.wire = Wire::Idle;
                self.finish(MavMissionResult::MAV_MISSION_ERROR);
                return;
            }
            *attempts += 1;
            *at = now;
            let again = match last {
                None => {
                    given.iter_mut().for_each(|g| *g = false);
                    Some(count_msg(items.len() as u16, *mission_type))
                }
                Some(seq) => items
                    .get(usize::from(*seq))
                    .cloned()
                    .map(MavMessage::MISSION_ITEM_INT),
            };
            self.to_fc.extend(again);
        }
    }

    /// Next message for the radio (targets filled in).
    pub fn poll_radio(&mut self) -> Option<MavMessage> {
        self.to_radio.pop_front()
    }

    /// Next message for the flight controller `fc` (system, component): targets rewritten to
    /// it, since the ground addressed its items to the vehicle, not to the bridge.
    pub fn poll_fc(&mut self, fc: (u8, u8)) -> Option<MavMessage> {
        let mut msg = self.to_fc.pop_front()?;
        match &mut msg {
            MavMessage::MISSION_COUNT(m) => (m.target_system, m.target_component) = fc,
            MavMessage::MISSION_ITEM_INT(m) => (m.target_system, m.target_component) = fc,
            MavMessage::MISSION_ACK(m) => (m.target_system, m.target_component) = fc,
            _ => {}
        }
        Some(msg)
    }
}

fn count_msg(count: u16, mission_type: MavMissionType) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count,
        mission_type,
        ..Default::default()
    })
}

/// Asks the router for items `start..=end` again (`MISSION_REQUEST_PARTIAL_LIST` on the radio
/// leg; sequence numbers in the `int16` fields as their bit patterns).
// `..Default::default()` although every field is set today: the dialect may grow.
#[allow(clippy::needless_update)]
pub(super) fn request_range(
    to: (u8, u8),
    start: u16,
    end: u16,
    mission_type: MavMissionType,
) -> MavMessage {
    MavMessage::MISSION_REQUEST_PARTIAL_LIST(MISSION_REQUEST_PARTIAL_LIST_DATA {
        start_index: start as i16,
        end_index: end as i16,
        target_system: to.0,
        target_component: to.1,
        mission_type,
        ..Default::default()
    })
}

// `..Default::default()` although every field is set today: the dialect may grow.
#[allow(clippy::needless_update)]
pub(super) fn request(to: (u8, u8), seq: u16, mission_type: MavMissionType) -> MavMessage {
    MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq,
        target_system: to.0,
        target_component: to.1,
        mission_type,
        ..Default::default()
    })
}

#[allow(clippy::needless_update)]
pub(super) fn ack(
    to: (u8, u8),
    result: MavMissionResult,
    mission_type: MavMissionType,
    opaque_id: u32,
) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: to.0,
        target_component: to.1,
        mavtype: result,
        mission_type,
        opaque_id,
        ..Default::default()
    })
}

#[cfg(test)]
#[path = "relay_tests.rs"]
mod tests;
