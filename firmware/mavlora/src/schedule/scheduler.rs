//! The link budget scheduler: what goes to the radio next, and when.

use std::collections::VecDeque;

use tracing::{debug, warn};

use super::bucket::TokenBucket;
use super::class::{Class, replaceable};
use super::fair::{FairQueue, Origin};
use crate::time::Instant;
use crate::wire::{MAX_FRAME_LEN, OwnedFrame};

/// Radio budget.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SchedulerConfig {
    /// Average bytes per second offered to the radio (e.g. 10 % duty cycle of a LoRa SF7
    /// channel: ~68 B/s).
    pub rate_bytes_per_s: u32,
    /// Bytes that may go out at once above the average; at least one largest frame
    /// ([`MAX_FRAME_LEN`]) so every frame can eventually go.
    pub burst_bytes: u32,
    /// Bytes that may wait in each class's queue (commands, transfers, telemetry; status
    /// text a quarter of it, parameters [`PARAM_QUEUE_BYTES`]); beyond it the class drops its
    /// own frames.
    pub max_queued_bytes: usize,
}

impl SchedulerConfig {
    /// A radio budget of `rate` bytes/s with bursts of `burst` bytes, queueing up to 4 s of
    /// traffic (at least 4 KiB): what both binaries use.
    pub fn for_radio(rate: u32, burst: u32) -> Self {
        Self {
            rate_bytes_per_s: rate,
            burst_bytes: burst,
            max_queued_bytes: (rate as usize * 4).max(4096),
        }
    }
}

/// Why a [`SchedulerConfig`] is unusable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ScheduleError {
    /// A burst below one largest frame would block such a frame forever.
    #[error("burst of {0} bytes is below one largest MAVLink frame ({MAX_FRAME_LEN} bytes)")]
    BurstTooSmall(u32),
    /// A zero rate would never send anything.
    #[error("rate must be above 0 bytes/s")]
    ZeroRate,
    /// The queue must hold at least one largest frame.
    #[error("queue limit of {0} bytes is below one largest MAVLink frame")]
    QueueTooSmall(usize),
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SchedulerStats {
    /// Frames handed to the radio.
    pub sent_frames: u64,
    /// Bytes handed to the radio, each frame with what the radio leg adds to it.
    pub sent_bytes: u64,
    /// Periodic frames replaced in the queue by a newer sample of the same message.
    pub replaced: u64,
    /// Periodic frames dropped because the telemetry queue was full.
    pub dropped_periodic: u64,
    /// Unnamed telemetry frames dropped because the telemetry queue was full (before any
    /// named one).
    pub dropped_unlisted: u64,
    /// Commands and acks dropped because their queue was full (of one origin's, first).
    pub dropped_command: u64,
    /// Transfer frames dropped because their queue was full (of one origin's, first).
    pub dropped_protocol: u64,
    /// Status texts dropped because their queue was full (the least severe first).
    pub dropped_status: u64,
    /// `PARAM_VALUE` frames handed to the radio.
    pub sent_param_frames: u64,
    /// `PARAM_VALUE` frames dropped because their own queue was full.
    pub dropped_param: u64,
}

/// Identity of a periodic stream: a newer frame with the same key replaces the queued one.
/// A part of a sequence ([`replaceable`] says no) gets a key of its own, `part`, so it is
/// never replaced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Key {
    system: u8,
    component: u8,
    message: u32,
    part: u64,
}

impl Key {
    fn of(frame: &OwnedFrame, part: u64) -> Self {
        Self {
            system: frame.system_id(),
            component: frame.component_id(),
            message: frame.message_id(),
            part,
        }
    }
}

/// Bytes of `PARAM_VALUE` frames that may wait: a whole ArduCopter parameter list (~1000
/// parameters of 33-37 bytes) fits, so a parameter load is paced rather than cut.
pub const PARAM_QUEUE_BYTES: usize = 64 * 1024;

/// The classes that share the budget, in the order they win a tie.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Lane {
    Periodic = 0,
    Protocol = 1,
    Status = 2,
    Param = 3,
}

const LANES: [Lane; 4] = [Lane::Periodic, Lane::Protocol, Lane::Status, Lane::Param];

/// Each lane's weight: its share of the budget while every lane has frames waiting (a lane
/// with nothing waiting leaves its share to the others).
/// - Telemetry 8/15, and 8/9 against a parameter stream alone: the profile's named
///   telemetry is what the operator budgeted the link for (compact: ~40-60 B/s, a fifth of
///   LoRa SF7's budget; ArduPilot's MAVLink 1 profile: most of it), so position keeps its
///   3 Hz, and a frame that arrives waits at most one frame of each other lane.
/// - Transfers 4/15: a mission or FTP download goes on at ~65 B/s on LoRa SF7 beside a
///   saturated link, and takes everything left beside an idle one.
/// - Status text 2/15: a 60-byte text every 2 s while everything else is busy; the least
///   severe are dropped first when they come faster.
/// - Parameters 1/15 (1/9 against telemetry alone, as the eighth they had before): a list of
///   1,000 values is paced, neither starved nor starving, and takes all the spare budget.
const WEIGHTS: [u64; 4] = [8, 4, 2, 1];

/// Virtual time a lane advances per byte sent is `UNIT / weight`: a multiple of every
/// weight, so the division is exact.
const UNIT: u64 = 840;

/// Budget that spare-capacity traffic (a parameter stream, unnamed telemetry) leaves in the
/// bucket: a named frame arriving next (a 3 Hz position is 36-53 bytes, signed MAVLink 2
/// included) finds it and leaves at once instead of waiting for a refill behind traffic that
/// only fills gaps. Reduced to what the burst allows above one largest frame.
pub const SPARE_RESERVE_BYTES: usize = 64;

/// Sans-IO scheduler between the filter and the radio.
///
/// Feed frames with [`push`](Self::push); whenever the radio can take bytes, call
/// [`poll_transmit`](Self::poll_transmit) until it returns `None`; wake up again at
/// [`poll_timeout`](Self::poll_timeout). Guarantees:
/// - over any window `w`, at most `rate * w + burst` bytes leave (token bucket);
/// - commands and acks ([`Class::Command`]) leave first, each origin's in arrival order;
/// - transfers, status text, parameters and named telemetry share what is left by weight
///   (start-time fair queueing over [`WEIGHTS`]): a class that has frames waiting gets at
///   least its share, a class with nothing waiting leaves its share to the others, and a
///   frame arriving in an idle class waits at most one frame of each busy class;
/// - within transfers and status text, origins ([`Origin`]) take turns by bytes, each in
///   its own order: a flooding origin waits behind its own frames;
/// - each class has its own bounded queue: a flood of one class drops only that class's
///   frames (the flooding origin's first; for status text, the least severe first), never a
///   command;
/// - unnamed telemetry ([`Class::Unlisted`]) only gets what every other class leaves;
///   spare-capacity traffic (it and parameters) never takes the last
///   [`SPARE_RESERVE_BYTES`] of the budget;
/// - a periodic frame replaces a queued frame of the same (sysid, compid, msgid) in place,
///   so the freshest sample leaves at the older one's turn instead of queueing behind it;
///   parts of a sequence (RTCM fragments, serial console bytes, log data, events) are never
///   replaced.
#[derive(Debug)]
pub struct LinkScheduler {
    config: SchedulerConfig,
    bucket: TokenBucket,
    /// Moves the bucket's rate by the radio's free buffer.
    pacer: super::TxbufPacer,
    /// What the radio holds unsent, kept under a limit ([`Self::with_radio_backlog`]).
    backlog: Option<super::RadioBacklog>,
    commands: FairQueue,
    transfers: FairQueue,
    status: FairQueue,
    params: VecDeque<OwnedFrame>,
    param_bytes: usize,
    /// Parts of sequences queued so far: each one's own key.
    parts: u64,
    /// Few distinct keys (one per periodic message per sender), so a linear scan for
    /// replacement beats maintaining an index.
    periodic: VecDeque<(Key, OwnedFrame)>,
    unlisted: VecDeque<(Key, OwnedFrame)>,
    /// Bytes waiting in the telemetry queues.
    telemetry_bytes: usize,
    /// Start tag of each lane's next frame, and of the frame a lane sent last: a lane that
    /// gets frames after a pause starts from there, not from its old tag.
    lane_start: [u64; 4],
    virtual_time: u64,
    /// Bytes each frame gains after it leaves the scheduler (a signature), charged with it.
    frame_extra: usize,
    stats: SchedulerStats,
}

/// Which queue the next frame comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    Command,
    Lane(Lane),
    Unlisted,
}

impl LinkScheduler {
    /// An empty scheduler with a full burst allowance at `now`.
    pub fn new(config: SchedulerConfig, now: Instant) -> Result<Self, ScheduleError> {
        if config.rate_bytes_per_s == 0 {
            return Err(ScheduleError::ZeroRate);
        }
        if (config.burst_bytes as usize) < MAX_FRAME_LEN {
            return Err(ScheduleError::BurstTooSmall(config.burst_bytes));
        }
        if config.max_queued_bytes < MAX_FRAME_LEN {
            return Err(ScheduleError::QueueTooSmall(config.max_queued_bytes));
        }
        Ok(Self {
            config,
            bucket: TokenBucket::new(config.rate_bytes_per_s, config.burst_bytes, now),
            pacer: super::TxbufPacer::new(config.rate_bytes_per_s),
            backlog: None,
            commands: FairQueue::default(),
            transfers: FairQueue::default(),
            status: FairQueue::default(),
            params: VecDeque::new(),
            param_bytes: 0,
            parts: 0,
            periodic: VecDeque::new(),
            unlisted: VecDeque::new(),
            telemetry_bytes: 0,
            lane_start: [0; 4],
            virtual_time: 0,
            frame_extra: 0,
            stats: SchedulerStats::default(),
        })
    }

    /// Charges every frame `bytes` more than its length: what the radio leg adds after the
    /// scheduler (13 for a MAVLink 2 signature), so the budget counts the bytes on the air.
    /// Uncharged, a signed burst of short frames (an autopilot's parameters, ~37 bytes
    /// each) goes out 35 % over the rate and overflows a radio budgeted at 80 %.
    pub fn with_frame_extra(mut self, bytes: usize) -> Self {
        self.frame_extra = bytes;
        self
    }

    /// Hands the radio a frame only while it holds less than `limit` of unsent bytes (as
    /// time at the budget's rate, [`super::RadioBacklog`]): a backlog then waits here, where
    /// commands and a mode change overtake it, not in the radio's buffer. `None`: no limit
    /// but the burst.
    pub fn with_radio_backlog(
        mut self,
        limit: Option<crate::time::Duration>,
        now: Instant,
    ) -> Self {
        self.backlog = limit.map(|l| super::RadioBacklog::new(self.bucket.rate(), l, now));
        self
    }

    /// The local radio reported `txbuf_pct` % of its transmit buffer free: the budget's rate
    /// follows ([`super::TxbufPacer`]; the configured rate is the ceiling).
    pub fn handle_txbuf(&mut self, txbuf_pct: u8) {
        if let Some(rate) = self.pacer.handle_txbuf(txbuf_pct) {
            tracing::debug!(txbuf_pct, rate, "radio budget paced by the radio's buffer");
            self.bucket.set_rate(rate.max(1));
            if let Some(b) = &mut self.backlog {
                b.set_rate(rate.max(1));
            }
        }
    }

    /// The byte rate in force.
    pub fn rate(&self) -> u32 {
        self.bucket.rate()
    }

    /// The configuration.
    pub fn config(&self) -> SchedulerConfig {
        self.config
    }

    /// Counters so far.
    pub fn stats(&self) -> SchedulerStats {
        self.stats
    }

    /// Frames waiting: messages (commands, transfers, status text) and telemetry (named and
    /// unnamed); parameters not included.
    pub fn queued_frames(&self) -> (usize, usize) {
        (
            self.commands.len() + self.transfers.len() + self.status.len(),
            self.periodic.len() + self.unlisted.len(),
        )
    }

    /// `PARAM_VALUE` frames waiting.
    pub fn queued_params(&self) -> usize {
        self.params.len()
    }

    /// Bytes waiting in every queue but the parameters'.
    pub fn queued_bytes(&self) -> usize {
        self.commands.bytes() + self.transfers.bytes() + self.status.bytes() + self.telemetry_bytes
    }

    /// Bytes of status text that may wait: a quarter of the other queues' limit. A text is
    /// news for the pilot; a deep queue of them would only make every one of them late.
    fn status_limit(&self) -> usize {
        (self.config.max_queued_bytes / 4).max(MAX_FRAME_LEN)
    }

    /// Queues a frame for the radio from the frame's own sender.
    pub fn push(&mut self, frame: OwnedFrame, class: Class, now: Instant) {
        let origin = Origin::of(&frame);
        self.push_from(frame, class, origin, now);
    }

    /// Queues a frame for the radio from `origin` (commands, transfers and status text take
    /// turns between origins). Time is not needed to queue; it is taken for log context.
    pub fn push_from(&mut self, frame: OwnedFrame, class: Class, origin: Origin, now: Instant) {
        if let Some(lane) = lane_of(class)
            && self.lane_is_empty(lane)
        {
            // a lane back from a pause starts now: its unused share is not saved up
            let l = lane as usize;
            self.lane_start[l] = self.lane_start[l].max(self.virtual_time);
        }
        match class {
            Class::Command => {
                self.commands.push(origin, frame);
                let limit = self.config.max_queued_bytes;
                let n = &mut self.stats.dropped_command;
                shed(&mut self.commands, limit, oldest, n, now, "commands");
            }
            Class::Protocol => {
                self.transfers.push(origin, frame);
                let limit = self.config.max_queued_bytes;
                let n = &mut self.stats.dropped_protocol;
                shed(&mut self.transfers, limit, oldest, n, now, "transfers");
            }
            Class::Status => {
                self.status.push(origin, frame);
                let limit = self.status_limit();
                let n = &mut self.stats.dropped_status;
                shed(
                    &mut self.status,
                    limit,
                    least_severe,
                    n,
                    now,
                    "status texts",
                );
            }
            Class::Param => {
                let len = frame.as_bytes().len();
                if self.param_bytes + len > PARAM_QUEUE_BYTES {
                    // The ground station re-requests what it misses (PARAM_REQUEST_READ).
                    self.stats.dropped_param += 1;
                    // A log line at the 1st, 2nd, 4th, 8th... drop: a flood of them fills
                    // no disk; the status line has the count.
                    let n = self.stats.dropped_param;
                    if n.is_power_of_two() {
                        warn!(%now, dropped = n, "parameter queue full, dropped a PARAM_VALUE (logged at the 1st, 2nd, 4th... drop)");
                    }
                    return;
                }
                self.param_bytes += len;
                self.params.push_back(frame);
            }
            Class::Periodic | Class::Unlisted => self.push_telemetry(frame, class, now),
        }
    }

    fn push_telemetry(&mut self, frame: OwnedFrame, class: Class, now: Instant) {
        let len = frame.as_bytes().len();
        let part = if replaceable(frame.message_id()) {
            0
        } else {
            self.parts += 1;
            self.parts
        };
        let key = Key::of(&frame, part);
        let queue = if class == Class::Periodic {
            &mut self.periodic
        } else {
            &mut self.unlisted
        };
        if let Some(slot) = queue.iter_mut().find(|(k, _)| *k == key) {
            self.telemetry_bytes = self.telemetry_bytes - slot.1.as_bytes().len() + len;
            slot.1 = frame;
            self.stats.replaced += 1;
        } else {
            queue.push_back((key, frame));
            self.telemetry_bytes += len;
        }
        while self.telemetry_bytes > self.config.max_queued_bytes {
            if let Some((key, old)) = self.unlisted.pop_front() {
                self.telemetry_bytes -= old.as_bytes().len();
                self.stats.dropped_unlisted += 1;
                debug!(%now, msgid = key.message, "queue full, dropped unlisted frame");
            } else if let Some((key, old)) = self.periodic.pop_front() {
                self.telemetry_bytes -= old.as_bytes().len();
                self.stats.dropped_periodic += 1;
                debug!(%now, msgid = key.message, "queue full, dropped periodic frame");
            } else {
                break;
            }
        }
    }

    /// Where a frame of `message` from (`system`, `component`) waits, if one does: with the
    /// commands ([`Class::Command`]) or the telemetry ([`Class::Periodic`], also for
    /// [`Class::Unlisted`]).
    pub fn waiting(&self, system: u8, component: u8, message: u32) -> Option<Class> {
        self.waiting_frame(system, component, message)
            .map(|(class, _)| class)
    }

    /// [`waiting`](Self::waiting), with the frame [`replace_waiting`](Self::replace_waiting)
    /// would replace.
    pub fn waiting_frame(
        &self,
        system: u8,
        component: u8,
        message: u32,
    ) -> Option<(Class, &OwnedFrame)> {
        let same = |f: &OwnedFrame| {
            (f.system_id(), f.component_id(), f.message_id()) == (system, component, message)
        };
        if let Some(f) = self.commands.newest(same) {
            return Some((Class::Command, f));
        }
        [&self.periodic, &self.unlisted]
            .into_iter()
            .find_map(|q| q.iter().rev().map(|(_, f)| f).find(|f| same(f)))
            .map(|f| (Class::Periodic, f))
    }

    /// Puts `frame` in the place of the newest waiting frame of its sender and message id,
    /// with the commands or the telemetry, a part of a sequence included (the caller made
    /// `frame` carry what that one did: merged compact frames); gives `frame` back if none
    /// waits.
    pub fn replace_waiting(&mut self, frame: OwnedFrame) -> Result<(), OwnedFrame> {
        let (system, component, message) =
            (frame.system_id(), frame.component_id(), frame.message_id());
        let same = move |f: &OwnedFrame| {
            (f.system_id(), f.component_id(), f.message_id()) == (system, component, message)
        };
        let frame = match self.commands.replace_newest(same, frame) {
            Ok(()) => {
                self.stats.replaced += 1;
                return Ok(());
            }
            Err(frame) => frame,
        };
        let slot = match self.periodic.iter().rposition(|(_, f)| same(f)) {
            Some(i) => &mut self.periodic[i],
            None => match self.unlisted.iter().rposition(|(_, f)| same(f)) {
                Some(i) => &mut self.unlisted[i],
                None => return Err(frame),
            },
        };
        self.telemetry_bytes =
            self.telemetry_bytes - slot.1.as_bytes().len() + frame.as_bytes().len();
        slot.1 = frame;
        self.stats.replaced += 1;
        Ok(())
    }

    /// Takes out every waiting telemetry frame of `message` from (`system`, `component`),
    /// oldest first: the caller sends what they carried another way (an urgent compact frame
    /// with the commands, folded into it).
    pub fn take_telemetry(&mut self, system: u8, component: u8, message: u32) -> Vec<OwnedFrame> {
        let mut taken = Vec::new();
        for queue in [&mut self.periodic, &mut self.unlisted] {
            let mut kept = VecDeque::with_capacity(queue.len());
            for (k, f) in queue.drain(..) {
                if (k.system, k.component, k.message) == (system, component, message) {
                    self.telemetry_bytes -= f.as_bytes().len();
                    taken.push(f);
                } else {
                    kept.push_back((k, f));
                }
            }
            *queue = kept;
        }
        taken
    }

    fn lane_is_empty(&self, lane: Lane) -> bool {
        match lane {
            Lane::Periodic => self.periodic.is_empty(),
            Lane::Protocol => self.transfers.is_empty(),
            Lane::Status => self.status.is_empty(),
            Lane::Param => self.params.is_empty(),
        }
    }

    /// The next frame for the radio if the byte budget allows it at `now` and it fits in
    /// `room`, the bytes the radio can accept right now (its free buffer).
    pub fn poll_transmit(&mut self, now: Instant, room: usize) -> Option<OwnedFrame> {
        let (source, len) = self.next_source()?;
        let cost = len + self.frame_extra;
        if self.backlog.as_mut().is_some_and(|b| !b.admits(now)) {
            return None;
        }
        if cost > room
            || !self
                .bucket
                .try_take_keeping(cost, self.reserve_for(source), now)
        {
            return None;
        }
        let frame = match source {
            Source::Command => self.commands.pop(cost)?,
            Source::Lane(lane) => {
                let frame = match lane {
                    Lane::Periodic => {
                        let (_, f) = self.periodic.pop_front()?;
                        self.telemetry_bytes -= len;
                        f
                    }
                    Lane::Protocol => self.transfers.pop(cost)?,
                    Lane::Status => self.status.pop(cost)?,
                    Lane::Param => {
                        let f = self.params.pop_front()?;
                        self.param_bytes -= len;
                        self.stats.sent_param_frames += 1;
                        f
                    }
                };
                let l = lane as usize;
                self.virtual_time = self.lane_start[l];
                self.lane_start[l] += cost as u64 * (UNIT / WEIGHTS[l]);
                frame
            }
            Source::Unlisted => {
                let (_, f) = self.unlisted.pop_front()?;
                self.telemetry_bytes -= len;
                f
            }
        };
        if let Some(b) = &mut self.backlog {
            b.add(cost);
        }
        self.stats.sent_frames += 1;
        self.stats.sent_bytes += cost as u64;
        Some(frame)
    }

    /// When the next queued frame fits the byte budget (a time already past if it does now),
    /// `None` if nothing is queued.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let (source, len) = self.next_source()?;
        let budget = self
            .bucket
            .ready_at(len + self.frame_extra + self.reserve_for(source))?;
        match &self.backlog {
            Some(b) => Some(budget.max(b.ready_at()?)),
            None => Some(budget),
        }
    }

    fn reserve_for(&self, source: Source) -> usize {
        match source {
            Source::Lane(Lane::Param) | Source::Unlisted => SPARE_RESERVE_BYTES
                .min((self.config.burst_bytes as usize).saturating_sub(MAX_FRAME_LEN)),
            _ => 0,
        }
    }

    /// The queue the next frame comes from and its length; depends on queue state only (not
    /// on time), so [`poll_timeout`](Self::poll_timeout) names the frame
    /// [`poll_transmit`](Self::poll_transmit) will send.
    fn next_source(&self) -> Option<(Source, usize)> {
        let len = |f: &OwnedFrame| f.as_bytes().len();
        if let Some(f) = self.commands.front() {
            return Some((Source::Command, len(f)));
        }
        let lane = LANES
            .iter()
            .filter(|&&l| !self.lane_is_empty(l))
            .min_by_key(|&&l| self.lane_start[l as usize]);
        if let Some(&lane) = lane {
            let head = match lane {
                Lane::Periodic => self.periodic.front().map(|(_, f)| f),
                Lane::Protocol => self.transfers.front(),
                Lane::Status => self.status.front(),
                Lane::Param => self.params.front(),
            }?;
            return Some((Source::Lane(lane), len(head)));
        }
        self.unlisted
            .front()
            .map(|(_, f)| (Source::Unlisted, len(f)))
    }
}

/// The lane a class shares the budget in; `None` for commands (first) and unnamed telemetry
/// (last).
fn lane_of(class: Class) -> Option<Lane> {
    match class {
        Class::Periodic => Some(Lane::Periodic),
        Class::Protocol => Some(Lane::Protocol),
        Class::Status => Some(Lane::Status),
        Class::Param => Some(Lane::Param),
        Class::Command | Class::Unlisted => None,
    }
}

/// Drops frames of the origin with most waiting (the one `choose` picks among its frames)
/// until `queue` holds at most `limit` bytes, counting them in `dropped`. A log line at the
/// 1st, 2nd, 4th... drop: a flood fills no disk; the status line has the count.
fn shed(
    queue: &mut FairQueue,
    limit: usize,
    choose: fn(&VecDeque<OwnedFrame>) -> usize,
    dropped: &mut u64,
    now: Instant,
    what: &str,
) {
    while queue.bytes() > limit {
        let Some(old) = queue.drop_from_largest(choose) else {
            break;
        };
        *dropped += 1;
        if dropped.is_power_of_two() {
            warn!(%now, msgid = old.message_id(), dropped = *dropped, "queue of {what} full, dropped a frame of the origin with most waiting (logged at the 1st, 2nd, 4th... drop)");
        }
    }
}

/// A flooding origin's frame to drop first: its oldest.
fn oldest(_: &VecDeque<OwnedFrame>) -> usize {
    0
}

/// The status text to drop first: the least severe (MAV_SEVERITY: 0 emergency ... 7 debug),
/// the oldest of those. A severity MAVLink 2 trimmed away is 0, emergency: kept longest.
fn least_severe(texts: &VecDeque<OwnedFrame>) -> usize {
    let severity = |f: &OwnedFrame| f.payload().first().copied().unwrap_or(0);
    let worst = texts.iter().map(severity).max().unwrap_or(0);
    texts.iter().position(|f| severity(f) == worst).unwrap_or(0)
}

#[cfg(test)]
mod tests;
