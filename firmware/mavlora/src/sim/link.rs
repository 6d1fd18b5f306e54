//! One direction of a radio: frames in, frames out later, some lost.

use crate::time::Duration;
use std::collections::VecDeque;

use super::rng::SplitMix64;
use crate::time::Instant;

/// Radio model settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkConfig {
    /// One-way latency added to every frame.
    pub latency: Duration,
    /// Air rate in bytes per second (frames queue behind each other).
    pub bytes_per_s: u32,
    /// Probability that a frame is lost, independently per frame.
    pub loss: f64,
}

/// Counters of one direction.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames offered.
    pub frames: u64,
    /// Bytes offered.
    pub bytes: u64,
    /// Frames lost.
    pub lost: u64,
}

/// A simulated radio direction.
#[derive(Debug)]
pub struct Link {
    config: LinkConfig,
    rng: SplitMix64,
    busy_until: Instant,
    in_flight: VecDeque<(Instant, Vec<u8>)>,
    stats: LinkStats,
}

impl Link {
    /// A link with drops drawn from `seed`.
    pub fn new(config: LinkConfig, seed: u64) -> Self {
        Self {
            config,
            rng: SplitMix64::new(seed),
            busy_until: Instant::ZERO,
            in_flight: VecDeque::new(),
            stats: LinkStats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Sends one frame at `now`.
    pub fn send(&mut self, bytes: &[u8], now: Instant) {
        self.stats.frames += 1;
        self.stats.bytes += bytes.len() as u64;
        let airtime =
            Duration::from_secs_f64(bytes.len() as f64 / f64::from(self.config.bytes_per_s.max(1)));
        self.busy_until = self.busy_until.max(now) + airtime;
        if self.rng.next_f64() < self.config.loss {
            self.stats.lost += 1;
            return;
        }
        self.in_flight
            .push_back((self.busy_until + self.config.latency, bytes.to_vec()));
    }

    /// When the next frame arrives.
    pub fn next_arrival(&self) -> Option<Instant> {
        self.in_flight.front().map(|(t, _)| *t)
    }

    /// A frame that has arrived by `now`.
    pub fn receive(&mut self, now: Instant) -> Option<Vec<u8>> {
        if self.next_arrival()? <= now {
            self.in_flight.pop_front().map(|(_, b)| b)
        } else {
            None
        }
    }
}
