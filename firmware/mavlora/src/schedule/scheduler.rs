//! The link budget scheduler: what goes to the radio next, and when.

use std::collections::VecDeque;

use tracing::{debug, warn};

use super::bucket::TokenBucket;
use super::class::{Class, replaceable};
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
    /// Bytes that may wait in the queues; beyond it periodic samples are dropped first.
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
    /// Periodic frames dropped because the queue was full.
    pub dropped_periodic: u64,
    /// Priority frames dropped because the queue was full of priority frames only.
    pub dropped_priority: u64,
    /// Unnamed telemetry frames dropped because the queue was full.
    pub dropped_unlisted: u64,
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

/// Share of the budget guaranteed to a waiting parameter stream: one byte in
/// `PARAM_SHARE_DIVISOR` (an eighth: on LoRa SF7's 273 B/s, ~34 B/s, one `PARAM_VALUE` a
/// second, what is left once the profile's telemetry is served; more when it leaves more).
pub const PARAM_SHARE_DIVISOR: u64 = 8;

/// Budget that spare-capacity traffic (a parameter stream beyond its share, unnamed telemetry)
/// leaves in the bucket: a named frame arriving next (a 3 Hz position is 36-53 bytes, signed
/// MAVLink 2 included) finds it and leaves at once instead of waiting for a refill behind
/// traffic that only fills gaps. Reduced to what the burst allows above one largest frame.
pub const SPARE_RESERVE_BYTES: usize = 64;

/// Sans-IO scheduler between the filter and the radio.
///
/// Feed frames with [`push`](Self::push); whenever the radio can take bytes, call
/// [`poll_transmit`](Self::poll_transmit) until it returns `None`; wake up again at
/// [`poll_timeout`](Self::poll_timeout). Guarantees:
/// - over any window `w`, at most `rate * w + burst` bytes leave (token bucket);
/// - priority frames leave first, in arrival order, and are dropped only when no periodic
///   frame is left to drop;
/// - a waiting parameter stream ([`Class::Param`]) gets at least an eighth of the bytes sent
///   (ahead of named telemetry only when the spare budget did not give it that much) and
///   any spare budget, in arrival order, from its own bounded queue ([`PARAM_QUEUE_BYTES`]),
///   so it never pushes a priority frame out;
/// - named telemetry ([`Class::Periodic`]) goes before unnamed ([`Class::Unlisted`]), which
///   only gets what is left and is dropped first when the queue is full; spare-capacity
///   traffic never takes the last [`SPARE_RESERVE_BYTES`] of the budget;
/// - a periodic frame replaces a queued frame of the same (sysid, compid, msgid) in place,
///   so the freshest sample leaves at the older one's turn instead of queueing behind it;
///   parts of a sequence (RTCM fragments, serial console bytes, log data, events) are never
///   replaced.
#[derive(Debug)]
pub struct LinkScheduler {
    config: SchedulerConfig,
    bucket: TokenBucket,
    priority: VecDeque<OwnedFrame>,
    params: VecDeque<OwnedFrame>,
    param_bytes: usize,
    /// Bytes the parameter stream may send without leaving the spare reserve, times
    /// [`PARAM_SHARE_DIVISOR`] - 1: each byte of another class sent earns one, each
    /// parameter byte sent on this credit costs `PARAM_SHARE_DIVISOR - 1`. Capped so an idle
    /// stretch earns no burst.
    param_credit: u64,
    /// Parts of sequences queued so far: each one's own key.
    parts: u64,
    /// Few distinct keys (one per periodic message per sender), so a linear scan for
    /// replacement beats maintaining an index.
    periodic: VecDeque<(Key, OwnedFrame)>,
    unlisted: VecDeque<(Key, OwnedFrame)>,
    /// Bytes waiting in the priority and telemetry queues (parameters are counted apart).
    queued_bytes: usize,
    /// Bytes each frame gains after it leaves the scheduler (a signature), charged with it.
    frame_extra: usize,
    stats: SchedulerStats,
}

/// Which queue the next frame comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    Priority,
    ParamShare,
    Periodic,
    ParamLeftover,
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
            priority: VecDeque::new(),
            params: VecDeque::new(),
            param_bytes: 0,
            param_credit: 0,
            parts: 0,
            periodic: VecDeque::new(),
            unlisted: VecDeque::new(),
            queued_bytes: 0,
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

    /// The configuration.
    pub fn config(&self) -> SchedulerConfig {
        self.config
    }

    /// Counters so far.
    pub fn stats(&self) -> SchedulerStats {
        self.stats
    }

    /// Frames waiting: priority and periodic (named and unnamed; parameters not included).
    pub fn queued_frames(&self) -> (usize, usize) {
        (
            self.priority.len(),
            self.periodic.len() + self.unlisted.len(),
        )
    }

    /// `PARAM_VALUE` frames waiting.
    pub fn queued_params(&self) -> usize {
        self.params.len()
    }

    /// Bytes waiting in the priority and telemetry queues.
    pub fn queued_bytes(&self) -> usize {
        self.queued_bytes
    }

    /// Queues a frame for the radio. Time is not needed to queue; it is taken for symmetry
    /// with the other calls and for log context.
    pub fn push(&mut self, frame: OwnedFrame, class: Class, now: Instant) {
        let len = frame.as_bytes().len();
        match class {
            Class::Priority => {
                self.priority.push_back(frame);
                self.queued_bytes += len;
            }
            Class::Param => {
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
            Class::Periodic | Class::Unlisted => {
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
                    self.queued_bytes = self.queued_bytes - slot.1.as_bytes().len() + len;
                    slot.1 = frame;
                    self.stats.replaced += 1;
                } else {
                    queue.push_back((key, frame));
                    self.queued_bytes += len;
                }
            }
        }
        self.enforce_queue_limit(now);
    }

    fn enforce_queue_limit(&mut self, now: Instant) {
        while self.queued_bytes > self.config.max_queued_bytes {
            if let Some((key, old)) = self.unlisted.pop_front() {
                self.queued_bytes -= old.as_bytes().len();
                self.stats.dropped_unlisted += 1;
                debug!(%now, msgid = key.message, "queue full, dropped unlisted frame");
            } else if let Some((key, old)) = self.periodic.pop_front() {
                self.queued_bytes -= old.as_bytes().len();
                self.stats.dropped_periodic += 1;
                debug!(%now, msgid = key.message, "queue full, dropped periodic frame");
            } else if let Some(old) = self.priority.pop_front() {
                self.queued_bytes -= old.as_bytes().len();
                self.stats.dropped_priority += 1;
                let n = self.stats.dropped_priority;
                if n.is_power_of_two() {
                    warn!(%now, msgid = old.message_id(), dropped = n, "queue full of priority frames, dropped one (logged at the 1st, 2nd, 4th... drop)");
                }
            } else {
                break;
            }
        }
    }

    /// The next frame for the radio if the byte budget allows it at `now` and it fits in
    /// `room`, the bytes the radio can accept right now (its free buffer).
    pub fn poll_transmit(&mut self, now: Instant, room: usize) -> Option<OwnedFrame> {
        let (source, len) = self.next_source()?;
        let cost = len + self.frame_extra;
        if cost > room
            || !self
                .bucket
                .try_take_keeping(cost, self.reserve_for(source), now)
        {
            return None;
        }
        let frame = match source {
            Source::Priority => self.priority.pop_front()?,
            Source::ParamShare | Source::ParamLeftover => self.params.pop_front()?,
            Source::Periodic => self.periodic.pop_front()?.1,
            Source::Unlisted => self.unlisted.pop_front()?.1,
        };
        match source {
            Source::ParamShare => {
                self.param_bytes -= len;
                self.param_credit -= cost as u64 * (PARAM_SHARE_DIVISOR - 1);
                self.stats.sent_param_frames += 1;
            }
            Source::ParamLeftover => {
                // spare budget counts towards the share: the share only overtakes named
                // telemetry when the spare budget did not give it as much
                self.param_bytes -= len;
                self.param_credit = self
                    .param_credit
                    .saturating_sub(cost as u64 * (PARAM_SHARE_DIVISOR - 1));
                self.stats.sent_param_frames += 1;
            }
            _ => {
                self.queued_bytes -= len;
                if !self.params.is_empty() {
                    let cap = (MAX_FRAME_LEN as u64) * (PARAM_SHARE_DIVISOR - 1);
                    self.param_credit = (self.param_credit + cost as u64).min(cap);
                }
            }
        }
        self.stats.sent_frames += 1;
        self.stats.sent_bytes += cost as u64;
        Some(frame)
    }

    /// When the next queued frame fits the byte budget (a time already past if it does now),
    /// `None` if nothing is queued.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let (source, len) = self.next_source()?;
        self.bucket
            .ready_at(len + self.frame_extra + self.reserve_for(source))
    }

    fn reserve_for(&self, source: Source) -> usize {
        match source {
            Source::ParamLeftover | Source::Unlisted => SPARE_RESERVE_BYTES
                .min((self.config.burst_bytes as usize).saturating_sub(MAX_FRAME_LEN)),
            _ => 0,
        }
    }

    /// The queue the next frame comes from and its length; depends on queue state only (not
    /// on time), so [`poll_timeout`](Self::poll_timeout) names the frame
    /// [`poll_transmit`](Self::poll_transmit) will send.
    fn next_source(&self) -> Option<(Source, usize)> {
        let len = |f: &OwnedFrame| f.as_bytes().len();
        if let Some(f) = self.priority.front() {
            return Some((Source::Priority, len(f)));
        }
        let share_due = |f: &OwnedFrame| {
            self.param_credit >= (len(f) + self.frame_extra) as u64 * (PARAM_SHARE_DIVISOR - 1)
        };
        if let Some(f) = self.params.front()
            && share_due(f)
        {
            return Some((Source::ParamShare, len(f)));
        }
        if let Some((_, f)) = self.periodic.front() {
            return Some((Source::Periodic, len(f)));
        }
        if let Some(f) = self.params.front() {
            return Some((Source::ParamLeftover, len(f)));
        }
        self.unlisted
            .front()
            .map(|(_, f)| (Source::Unlisted, len(f)))
    }
}

#[cfg(test)]
mod tests;
