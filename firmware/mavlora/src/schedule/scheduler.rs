//! The link budget scheduler: what goes to the radio next, and when.

use std::collections::VecDeque;

use tracing::{debug, warn};

use super::bucket::TokenBucket;
use super::class::Class;
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
    /// Bytes handed to the radio.
    pub sent_bytes: u64,
    /// Periodic frames replaced in the queue by a newer sample of the same message.
    pub replaced: u64,
    /// Periodic frames dropped because the queue was full.
    pub dropped_periodic: u64,
    /// Priority frames dropped because the queue was full of priority frames only.
    pub dropped_priority: u64,
}

/// Identity of a periodic stream: a newer frame with the same key replaces the queued one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Key {
    system: u8,
    component: u8,
    message: u32,
}

impl Key {
    fn of(frame: &OwnedFrame) -> Self {
        Self {
            system: frame.system_id(),
            component: frame.component_id(),
            message: frame.message_id(),
        }
    }
}

/// Sans-IO scheduler between the filter and the radio.
///
/// Feed frames with [`push`](Self::push); whenever the radio can take bytes, call
/// [`poll_transmit`](Self::poll_transmit) until it returns `None`; wake up again at
/// [`poll_timeout`](Self::poll_timeout). Guarantees:
/// - over any window `w`, at most `rate * w + burst` bytes leave (token bucket);
/// - priority frames leave first, in arrival order, and are dropped only when no periodic
///   frame is left to drop;
/// - a periodic frame replaces a queued frame of the same (sysid, compid, msgid) in place,
///   so the freshest sample leaves at the older one's turn instead of queueing behind it.
#[derive(Debug)]
pub struct LinkScheduler {
    config: SchedulerConfig,
    bucket: TokenBucket,
    priority: VecDeque<OwnedFrame>,
    /// Few distinct keys (one per periodic message per sender), so a linear scan for
    /// replacement beats maintaining an index.
    periodic: VecDeque<(Key, OwnedFrame)>,
    queued_bytes: usize,
    stats: SchedulerStats,
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
            periodic: VecDeque::new(),
            queued_bytes: 0,
            stats: SchedulerStats::default(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> SchedulerConfig {
        self.config
    }

    /// Counters so far.
    pub fn stats(&self) -> SchedulerStats {
        self.stats
    }

    /// Frames waiting, priority and periodic.
    pub fn queued_frames(&self) -> (usize, usize) {
        (self.priority.len(), self.periodic.len())
    }

    /// Bytes waiting.
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
            Class::Periodic => {
                let key = Key::of(&frame);
                if let Some(slot) = self.periodic.iter_mut().find(|(k, _)| *k == key) {
                    self.queued_bytes = self.queued_bytes - slot.1.as_bytes().len() + len;
                    slot.1 = frame;
                    self.stats.replaced += 1;
                } else {
                    self.periodic.push_back((key, frame));
                    self.queued_bytes += len;
                }
            }
        }
        self.enforce_queue_limit(now);
    }

    fn enforce_queue_limit(&mut self, now: Instant) {
        while self.queued_bytes > self.config.max_queued_bytes {
            if let Some((key, old)) = self.periodic.pop_front() {
                self.queued_bytes -= old.as_bytes().len();
                self.stats.dropped_periodic += 1;
                debug!(%now, msgid = key.message, "queue full, dropped periodic frame");
            } else if let Some(old) = self.priority.pop_front() {
                self.queued_bytes -= old.as_bytes().len();
                self.stats.dropped_priority += 1;
                warn!(%now, msgid = old.message_id(), "queue full of priority frames, dropped one");
            } else {
                break;
            }
        }
    }

    /// The next frame for the radio if the byte budget allows it at `now` and it fits in
    /// `room`, the bytes the radio can accept right now (its free buffer).
    pub fn poll_transmit(&mut self, now: Instant, room: usize) -> Option<OwnedFrame> {
        let len = self.head()?.as_bytes().len();
        if len > room || !self.bucket.try_take(len, now) {
            return None;
        }
        let frame = match self.priority.pop_front() {
            Some(frame) => frame,
            None => self.periodic.pop_front()?.1,
        };
        self.queued_bytes -= len;
        self.stats.sent_frames += 1;
        self.stats.sent_bytes += len as u64;
        Some(frame)
    }

    /// When the next queued frame fits the byte budget (a time already past if it does now),
    /// `None` if nothing is queued.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let len = self.head()?.as_bytes().len();
        self.bucket.ready_at(len)
    }

    fn head(&self) -> Option<&OwnedFrame> {
        self.priority
            .front()
            .or_else(|| self.periodic.front().map(|(_, f)| f))
    }
}

#[cfg(test)]
mod tests;
