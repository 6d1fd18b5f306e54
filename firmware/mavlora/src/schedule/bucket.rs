//! Token bucket in integer micro-bytes, so refills over any split of time add up exactly.

use crate::time::Instant;

const MICRO: u64 = 1_000_000;

/// Allows `rate` bytes per second on average with bursts of at most `capacity` bytes: over
/// any window `w`, at most `rate * w + capacity` bytes are taken.
#[derive(Debug, Clone)]
pub struct TokenBucket {
    rate: u64,
    capacity_micro: u64,
    tokens_micro: u64,
    last: Instant,
}

impl TokenBucket {
    /// A full bucket at `now`.
    pub fn new(rate_bytes_per_s: u32, capacity_bytes: u32, now: Instant) -> Self {
        let capacity_micro = u64::from(capacity_bytes) * MICRO;
        Self {
            rate: rate_bytes_per_s.into(),
            capacity_micro,
            tokens_micro: capacity_micro,
            last: now,
        }
    }

    /// Changes the rate from the last refill on (the tokens gathered until then stay).
    pub fn set_rate(&mut self, rate_bytes_per_s: u32) {
        self.rate = rate_bytes_per_s.into();
    }

    /// Bytes per second.
    pub fn rate(&self) -> u32 {
        self.rate as u32
    }

    fn refill(&mut self, now: Instant) {
        let elapsed = now.as_micros().saturating_sub(self.last.as_micros());
        self.tokens_micro = self
            .tokens_micro
            .saturating_add(elapsed.saturating_mul(self.rate))
            .min(self.capacity_micro);
        self.last = self.last.max(now);
    }

    /// Takes `bytes` if the bucket holds them at `now`.
    pub fn try_take(&mut self, bytes: usize, now: Instant) -> bool {
        self.refill(now);
        let need = (bytes as u64).saturating_mul(MICRO);
        if self.tokens_micro >= need {
            self.tokens_micro -= need;
            true
        } else {
            false
        }
    }

    /// Takes `bytes` only if `reserve` more bytes would still be left at `now`: traffic that
    /// may only use spare budget leaves a frame's worth for what matters more.
    pub fn try_take_keeping(&mut self, bytes: usize, reserve: usize, now: Instant) -> bool {
        self.refill(now);
        let need = (bytes as u64 + reserve as u64).saturating_mul(MICRO);
        if self.tokens_micro >= need {
            self.tokens_micro -= (bytes as u64).saturating_mul(MICRO);
            true
        } else {
            false
        }
    }

    /// Earliest time at which `bytes` can be taken, `None` if never (more than the capacity,
    /// or zero rate). Does not refill: the answer is the same whenever it is asked, and a
    /// time already past (the last refill) means "now".
    pub fn ready_at(&self, bytes: usize) -> Option<Instant> {
        let need = (bytes as u64).saturating_mul(MICRO);
        if need > self.capacity_micro {
            return None;
        }
        if self.tokens_micro >= need {
            return Some(self.last);
        }
        if self.rate == 0 {
            return None;
        }
        let missing = need - self.tokens_micro;
        Some(Instant::from_micros(
            self.last.as_micros() + missing.div_ceil(self.rate),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn burst_then_rate() {
        let mut b = TokenBucket::new(100, 50, Instant::ZERO);
        assert!(b.try_take(50, Instant::ZERO));
        assert!(!b.try_take(1, Instant::ZERO));
        assert_eq!(b.ready_at(10), Some(Instant::from_millis(100)));
        assert!(!b.try_take(10, Instant::from_millis(99)));
        assert!(b.try_take(10, Instant::from_millis(100)));
        // a long pause refills only up to the capacity
        assert!(b.try_take(50, Instant::from_millis(10_000)));
        assert!(!b.try_take(1, Instant::from_millis(10_000)));
    }

    #[test]
    fn taking_spare_budget_keeps_the_reserve() {
        let mut b = TokenBucket::new(100, 60, Instant::ZERO);
        assert!(!b.try_take_keeping(30, 40, Instant::ZERO));
        assert!(b.try_take_keeping(20, 40, Instant::ZERO));
        // the reserve is still there for a frame that may use it
        assert!(b.try_take(40, Instant::ZERO));
    }

    #[test]
    fn more_than_capacity_is_never_ready() {
        let b = TokenBucket::new(100, 50, Instant::ZERO);
        assert_eq!(b.ready_at(51), None);
    }
}
