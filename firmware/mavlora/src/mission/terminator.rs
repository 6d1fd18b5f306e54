//! The router's side of mission uploads: it terminates the ground station's transfer
//! locally and streams the plan over the radio.
//!
//! Ground leg (standard protocol, answered as the vehicle): a `MISSION_COUNT` from the ground
//! opens a transfer (always a new one: a second count, even with the same number, starts
//! from item 0); the router requests every item at once over the local link. With the plan
//! in, it keeps the ground waiting the standard way: it re-requests the last item every
//! [`TerminatorConfig::keepalive`] (below any ground station's timeout; PX4 itself re-requests
//! after 250 ms), which re-sends it and restarts the ground's timer. The ground is told
//! what the vehicle answered, never anything the router made up: ACCEPTED only for the
//! bridge's ack naming this transfer (its id carries the plan's CRC, which the bridge
//! checked). A `MISSION_ACK` with an error from the ground cancels the transfer.
//!
//! Radio leg: `MISSION_COUNT{opaque_id = transfer id}` and every item, one behind the other
//! (no round trip per item), packed several to a frame ([`super::pack`]) unless
//! [`TerminatorConfig::pack_bytes`] is `None`, each frame paced at its own length on the
//! radio; the bridge asks for the lost ones by range. A status poll goes right behind the
//! stream (and behind each batch of repairs): the radio keeps order, so when the poll arrives
//! every frame before it has arrived or is lost, and the bridge answers with what it misses,
//! "busy" or its ack (see [`super::relay`]). The poll is an item frame without items when
//! packing (the bridge knows it for a poll even if it never saw the transfer), else the count
//! again. While the bridge stays silent the poll is repeated at a timeout that follows the
//! round trip measured from polls to their answers (RFC 6298; Karn's rule: only a poll
//! answered while it was the only one out, by a request that did not cross our latest
//! frames, is a sample), doubling after [`POLLS_BEFORE_BACKOFF`] unanswered polls (up to
//! [`TerminatorConfig::poll_max`]); before any is measured the timeout is the time two of
//! the largest stream frames take at the paced rate plus [`super::MARGIN`], within
//! [`TerminatorConfig::poll_min`] and [`TerminatorConfig::poll_initial`]. A request for an
//! item sent again less than the shortest measured round trip ago crossed that copy and is
//! not answered twice.

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
    /// The last item is requested from the ground again this often while the vehicle has
    /// not answered: keeps ground stations with 0.5 s timeouts waiting.
    pub keepalive: Duration,
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
            keepalive: Duration::from_millis(250),
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
    /// Keep-alive re-requests of the last item sent to the ground.
    pub keepalives: u64,
    /// Acks from the radio for an older transfer, dropped.
    pub stale_acks: u64,
}

#[derive(Debug)]
enum State {
    Idle,
    Collecting {
        ground: (u8, u8),
        vehicle: (u8, u8),
        mission_type: MavMissionType,
        count: u16,
        items: Vec<MISSION_ITEM_INT_DATA>,
        asked_at: Instant,
        asks: u32,
    },
    Relaying {
        ground: (u8, u8),
        vehicle: (u8, u8),
        mission_type: MavMissionType,
        items: Vec<MISSION_ITEM_INT_DATA>,
        id: u32,
        keepalive_at: Instant,
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
    stats: TerminatorStats,
}

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
            stats: TerminatorStats::default(),
        }
    }

    /// The round trip to the bridge, as measured from polls.
    pub fn rtt(&self) -> &RttEstimator {
        &self.rtt
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
    pub fn from_ground(
        &mut self,
        now: Instant,
        from: (u8, u8),
        autopilot: u8,
        msg: &MavMessage,
    ) -> bool {
        match msg {
            MavMessage::MISSION_COUNT(c) => {
                let component = if c.target_component == 0 {
                    autopilot
                } else {
                    c.target_component
                };
                self.ground_count(now, from, (c.target_system, component), c);
                true
            }
            MavMessage::MISSION_ITEM_INT(item) => self.ground_item(now, from, item),
            MavMessage::MISSION_ACK(a) if a.mavtype != MavMissionResult::MAV_MISSION_ACCEPTED => {
                self.ground_cancel(from, a.mission_type)
            }
            _ => false,
        }
    }

    fn ground_count(
        &mut self,
        now: Instant,
        ground: (u8, u8),
        vehicle: (u8, u8),
        c: &MISSION_COUNT_DATA,
    ) {
        // An empty plan's count repeated while the vehicle has not answered: the same plan
        // (nothing can be mixed into it), keep the transfer rather than restart it each time.
        if let State::Relaying {
            ground: g,
            mission_type,
            items,
            ..
        } = &self.state
            && *g == ground
            && *mission_type == c.mission_type
            && items.is_empty()
            && c.count == 0
        {
            return;
        }
        if matches!(
            self.state,
            State::Collecting { .. } | State::Relaying { .. }
        ) {
            self.stats.restarts += 1;
            self.cancel_radio();
        }
        info!(count = c.count, mission_type = ?c.mission_type, "mission upload from the ground");
        self.stats.uploads += 1;
        self.state = State::Collecting {
            ground,
            vehicle,
            mission_type: c.mission_type,
            count: c.count,
            items: Vec::with_capacity(c.count.into()),
            asked_at: now,
            asks: 0,
        };
        self.advance(now);
    }

    fn ground_item(&mut self, now: Instant, from: (u8, u8), item: &MISSION_ITEM_INT_DATA) -> bool {
        match &mut self.state {
            State::Collecting {
                ground,
                vehicle,
                mission_type,
                items,
                ..
            } if *ground == from && item.mission_type == *mission_type => {
                let next = items.len() as u16;
                if item.seq == next {
                    items.push(item.clone());
                    self.advance(now);
                } else if item.seq + 1 == next {
                    // Our request for the next one was lost: ask again now.
                    let again = request(*ground, next, *mission_type);
                    self.to_ground.push_back((*vehicle, again));
                }
                true
            }
            State::Relaying {
                ground,
                mission_type,
                ..
            } if *ground == from && item.mission_type == *mission_type => true,
            State::Done {
                ground,
                vehicle,
                mission_type,
                count,
                result,
            } if *ground == from && item.mission_type == *mission_type => {
                if item.seq + 1 == *count {
                    // Our ack was lost: the ground repeats its last item.
                    let again = ack(*ground, *result, *mission_type, 0);
                    self.to_ground.push_back((*vehicle, again));
                }
                true
            }
            // An item nobody asked for from this ground: not the vehicle's business either.
            _ => true,
        }
    }

    fn ground_cancel(&mut self, from: (u8, u8), mission_type: MavMissionType) -> bool {
        let ours = match &self.state {
            State::Collecting {
                ground,
                mission_type: t,
                ..
            }
            | State::Relaying {
                ground,
                mission_type: t,
                ..
            } => *ground == from && *t == mission_type,
            _ => false,
        };
        if ours {
            info!("the ground cancelled its mission upload");
            self.stats.cancelled += 1;
            self.cancel_radio();
            self.state = State::Idle;
        }
        ours
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

    /// Asks the ground for the next item, or starts the radio leg with all of them.
    // `..Default::default()` on full literals: the dialect may grow.
    #[allow(clippy::needless_update)]
    fn advance(&mut self, now: Instant) {
        let State::Collecting {
            ground,
            vehicle,
            mission_type,
            count,
            items,
            asked_at,
            asks,
        } = &mut self.state
        else {
            return;
        };
        if items.len() < usize::from(*count) {
            *asked_at = now;
            *asks = 1;
            let next = request(*ground, items.len() as u16, *mission_type);
            self.to_ground.push_back((*vehicle, next));
            return;
        }
        let (ground, vehicle, mission_type) = (*ground, *vehicle, *mission_type);
        let items = std::mem::take(items);
        self.generation = self.generation.wrapping_add(1);
        let id = transfer_id(self.generation, plan_hash(mission_type, &items));
        self.recent.push_back(id);
        if self.recent.len() > 16 {
            self.recent.pop_front();
        }
        info!(
            count = items.len(),
            id, "plan from the ground complete, streaming it over the radio"
        );
        self.stream
            .push_back(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count: items.len() as u16,
                target_system: vehicle.0,
                target_component: vehicle.1,
                mission_type,
                opaque_id: id,
                ..Default::default()
            }));
        let count = items.len();
        let frames = item_frames(&self.config, id, vehicle, mission_type, &items, &items);
        self.stream.extend(frames);
        // A poll right behind the stream: a lost tail is asked for one round trip later.
        self.poll_pending = !items.is_empty();
        self.stats.items_streamed += items.len() as u64;
        self.state = State::Relaying {
            ground,
            vehicle,
            mission_type,
            items,
            id,
            keepalive_at: now + self.config.keepalive,
            quiet_since: now,
            polls_unanswered: 0,
            poll_sent: now,
            sent_at: vec![None; count],
            heard: now,
            streamed: false,
        };
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
            items,
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
        // Not what still waits to leave, nor what left less than the shortest round trip
        // ago (the request was sent before that copy could have arrived).
        let waiting = |seq: usize| self.stream.iter().any(|m| covers(m, seq));
        let crossed = |seq: usize| {
            sent_at[seq].is_some_and(|t| now.saturating_duration_since(t) < self.min_rtt)
        };
        let mut crossed_any = false;
        let mut runs: Vec<(usize, usize)> = Vec::new();
        let last = items.len().min(usize::from(end) + 1);
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
                items,
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
            ..
        } = &mut self.state
        {
            *quiet_since = now;
            if outstanding == 0 && !*streamed {
                *streamed = true;
                *heard = (*heard).max(now);
            }
        }
    }

    /// Stream frames (the poll included) not yet on the radio.
    fn outstanding(&self) -> usize {
        self.stream.len() + self.in_queue + usize::from(self.poll_pending)
    }

    /// The status poll of the transfer being relayed: an item frame without items when
    /// packing (the bridge knows it for a poll even if it never saw the count), else the
    /// count again.
    // `..Default::default()` on a full literal: the dialect may grow.
    #[allow(clippy::needless_update)]
    fn poll_message(&self) -> Option<MavMessage> {
        let State::Relaying {
            vehicle,
            mission_type,
            items,
            id,
            ..
        } = &self.state
        else {
            return None;
        };
        let count = items.len() as u16;
        Some(match self.config.pack_bytes {
            Some(_) if count > 0 => pack::poll(*id, count, *vehicle, *mission_type),
            _ => MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count,
                target_system: vehicle.0,
                target_component: vehicle.1,
                mission_type: *mission_type,
                opaque_id: *id,
                ..Default::default()
            }),
        })
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
        match &self.state {
            State::Collecting { asked_at, .. } => Some(*asked_at + self.config.ground_timeout),
            State::Relaying {
                keepalive_at,
                quiet_since,
                polls_unanswered,
                ..
            } => {
                let poll =
                    (outstanding == 0).then(|| *quiet_since + self.poll_after(*polls_unanswered));
                Some(poll.map_or(*keepalive_at, |p| p.min(*keepalive_at)))
            }
            _ => None,
        }
    }

    /// Keep-alives, polls and give-ups due at `now`.
    // `..Default::default()` on full literals: the dialect may grow.
    #[allow(clippy::needless_update)]
    pub fn handle_timeout(&mut self, now: Instant) {
        let outstanding = self.outstanding();
        let poll_after = match &self.state {
            State::Relaying {
                polls_unanswered, ..
            } => self.poll_after(*polls_unanswered),
            _ => Duration::ZERO,
        };
        match &mut self.state {
            State::Collecting {
                ground,
                vehicle,
                mission_type,
                items,
                asked_at,
                asks,
                ..
            } if now >= *asked_at + self.config.ground_timeout => {
                if *asks >= self.config.ground_attempts {
                    warn!("the ground stopped sending its items, upload dropped");
                    self.stats.failed += 1;
                    self.state = State::Idle;
                    return;
                }
                *asks += 1;
                *asked_at = now;
                let again = request(*ground, items.len() as u16, *mission_type);
                self.to_ground.push_back((*vehicle, again));
            }
            State::Relaying {
                ground,
                vehicle,
                mission_type,
                items,
                id,
                keepalive_at,
                quiet_since,
                heard,
                ..
            } => {
                if now >= *keepalive_at {
                    *keepalive_at = now + self.config.keepalive;
                    if let Some(last) = items.len().checked_sub(1) {
                        self.stats.keepalives += 1;
                        let again = request(*ground, last as u16, *mission_type);
                        self.to_ground.push_back((*vehicle, again));
                    }
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
                    ..
                } = &mut self.state
                {
                    self.stats.polls += 1;
                    *polls_unanswered += 1;
                    *poll_sent = now;
                }
                msg
            }
            None => return None,
        };
        self.in_queue += 1;
        if let State::Relaying { sent_at, .. } = &mut self.state {
            for (seq, at) in sent_at.iter_mut().enumerate() {
                if covers(&msg, seq) {
                    *at = Some(now);
                }
            }
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
    plan: &[MISSION_ITEM_INT_DATA],
    run: &[MISSION_ITEM_INT_DATA],
) -> Vec<MavMessage> {
    match config.pack_bytes {
        Some(cap) => pack::frames(id, plan.len() as u16, vehicle, mission_type, run, cap),
        None => run
            .iter()
            .map(|i| MavMessage::MISSION_ITEM_INT(to_vehicle(i, vehicle)))
            .collect(),
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
