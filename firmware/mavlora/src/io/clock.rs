//! The one place that reads the clock: engine time is microseconds since process start.

use crate::time::Instant;

/// Wall clock for the engines.
#[derive(Debug, Clone, Copy)]
pub struct Clock {
    start: std::time::Instant,
}

impl Clock {
    /// A clock whose epoch is now.
    pub fn start() -> Self {
        Self {
            start: std::time::Instant::now(),
        }
    }

    /// Engine time now.
    pub fn now(&self) -> Instant {
        Instant::from_micros(self.start.elapsed().as_micros() as u64)
    }

    /// Real time until engine time `t` (zero if past).
    pub fn until(&self, t: Instant) -> std::time::Duration {
        t.saturating_duration_since(self.now()).into()
    }
}

/// MAVLink signing timestamp now (10 µs units since 2015-01-01 00:00 UTC): the epoch a
/// [`SigningConfig`](crate::signing::SigningConfig) needs for engine time zero.
pub fn signing_epoch_now() -> u64 {
    let unix_us = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64);
    unix_us.saturating_sub(1_420_070_400 * 1_000_000) / 10
}
