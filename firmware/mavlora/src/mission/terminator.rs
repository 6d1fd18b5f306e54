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
//! (no round trip per item); the bridge asks for the lost ones. When the stream has left
//! and the bridge said nothing for one timeout, the count goes again as a status poll (see
//! [`super::relay`]).

use crate::time::Duration;
use std::collections::VecDeque;

use tracing::{debug, info, warn};

use super::plan::{plan_hash, transfer_id};
use super::relay::{ack, request};
use crate::dialect::{
    MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MavMessage, MavMissionResult, MavMissionType,
};
use crate::time::Instant;

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
    /// First status poll this long after the stream left the radio without a word back.
    pub poll_initial: Duration,
    /// Polls back off up to this interval.
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
}

/// Bytes a stream frame may take on the radio (a signed `MISSION_ITEM_INT`: 37 + 12 + 13).
const STREAM_FRAME_BYTES: u64 = 62;

impl Default for TerminatorConfig {
    fn default() -> Self {
        Self {
            keepalive: Duration::from_millis(250),
            ground_timeout: Duration::from_millis(500),
            ground_attempts: 5,
            poll_initial: Duration::from_secs(2),
            poll_max: Duration::from_secs(8),
            silence_limit: Duration::from_secs(60),
            window: 4,
            pace_bytes_per_s: None,
        }
    }
}

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
        poll_every: Duration,
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
            stats: TerminatorStats::default(),
        }
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
        for item in &items {
            self.stream
                .push_back(MavMessage::MISSION_ITEM_INT(to_vehicle(item, vehicle)));
        }
        self.stats.items_streamed += items.len() as u64;
        self.state = State::Relaying {
            ground,
            vehicle,
            mission_type,
            items,
            id,
            keepalive_at: now + self.config.keepalive,
            quiet_since: now,
            poll_every: self.config.poll_initial,
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
            MavMessage::MISSION_ACK(a) if a.opaque_id != 0 => {
                self.bridge_ack(a.opaque_id, a.mavtype);
                true
            }
            _ => false,
        }
    }

    fn bridge_request(&mut self, now: Instant, seq: u16, t: MavMissionType) {
        let State::Relaying {
            vehicle,
            mission_type,
            items,
            quiet_since,
            poll_every,
            heard,
            ..
        } = &mut self.state
        else {
            return;
        };
        if t != *mission_type {
            return;
        }
        *heard = now;
        *quiet_since = now;
        *poll_every = self.config.poll_initial;
        // seq == count: "all items here, the autopilot is busy": alive, nothing to send.
        let waiting = self
            .stream
            .iter()
            .any(|m| matches!(m, MavMessage::MISSION_ITEM_INT(i) if i.seq == seq));
        if let Some(item) = items.get(usize::from(seq))
            && !waiting
        {
            // A repair goes before the rest of the stream (the bridge only looks for gaps
            // above what it has seen), and only once while it waits here.
            self.stats.items_repaired += 1;
            let at = usize::from(
                self.stream
                    .front()
                    .is_some_and(|m| matches!(m, MavMessage::MISSION_COUNT(_))),
            );
            self.stream
                .insert(at, MavMessage::MISSION_ITEM_INT(to_vehicle(item, *vehicle)));
        }
    }

    fn bridge_ack(&mut self, opaque_id: u32, result: MavMissionResult) {
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
        self.finish(*ground, *vehicle, *mission_type, items.len() as u16, result);
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

    /// Stream frames not yet on the radio.
    fn outstanding(&self) -> usize {
        self.stream.len() + self.in_queue
    }

    /// When something is due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let release = (!self.stream.is_empty() && self.in_queue < self.config.window)
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
                poll_every,
                ..
            } => {
                let poll = (outstanding == 0).then(|| *quiet_since + *poll_every);
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
                poll_every,
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
                if outstanding > 0 || now < *quiet_since + *poll_every {
                    return;
                }
                if now.saturating_duration_since(*heard) >= self.config.silence_limit {
                    warn!(id = *id, "the vehicle side stayed silent, upload failed");
                    let (g, v, t, n) = (*ground, *vehicle, *mission_type, items.len() as u16);
                    self.finish(g, v, t, n, MavMissionResult::MAV_MISSION_ERROR);
                    return;
                }
                self.stats.polls += 1;
                *quiet_since = now;
                *poll_every = (*poll_every * 2).min(self.config.poll_max);
                self.stream
                    .push_back(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                        count: items.len() as u16,
                        target_system: vehicle.0,
                        target_component: vehicle.1,
                        mission_type: *mission_type,
                        opaque_id: *id,
                        ..Default::default()
                    }));
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
        let msg = self.stream.pop_front()?;
        self.in_queue += 1;
        if let Some(rate) = self.config.pace_bytes_per_s.filter(|r| *r > 0) {
            let gap = Duration::from_micros(STREAM_FRAME_BYTES * 1_000_000 / u64::from(rate));
            self.next_release = self.next_release.max(now) + gap;
        }
        Some(msg)
    }
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
