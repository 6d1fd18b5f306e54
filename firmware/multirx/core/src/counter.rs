//! A free-running 32-bit microsecond counter (the SAMD21's TC4+TC5) extended
//! to the 64-bit [`Instant`] the engine takes. The main loop reads the counter
//! every pass ([`Counter32::now`]); RX interrupts stamp each byte with the raw
//! count, which may be a little before or after the loop's last reading, and
//! [`Counter32::at`] places it by the signed difference. Right as long as
//! readings are less than 2^31 µs (35 minutes) apart; the watchdog resets a
//! board whose loop stops for 250 ms.

use crate::time::Instant;

/// The counter's last reading and what it stood for.
#[derive(Debug, Clone, Copy, Default)]
pub struct Counter32 {
    last_raw: u32,
    micros: u64,
}

impl Counter32 {
    /// A counter that read `raw` at [`Instant::ZERO`].
    pub const fn starting_at(raw: u32) -> Self {
        Counter32 {
            last_raw: raw,
            micros: 0,
        }
    }

    /// The counter now reads `raw`: advances and returns now.
    pub fn now(&mut self, raw: u32) -> Instant {
        self.micros += u64::from(raw.wrapping_sub(self.last_raw));
        self.last_raw = raw;
        Instant::from_micros(self.micros)
    }

    /// Whether the counter read `raw` after the last [`Self::now`]: the same
    /// as `self.at(raw) > now`, without the 64-bit arithmetic.
    pub fn is_after_now(&self, raw: u32) -> bool {
        raw.wrapping_sub(self.last_raw) as i32 > 0
    }

    /// When the counter read `raw`, near the last [`Self::now`] (either side).
    pub fn at(&self, raw: u32) -> Instant {
        let delta = raw.wrapping_sub(self.last_raw) as i32;
        Instant::from_micros(self.micros.saturating_add_signed(i64::from(delta)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wraps_without_a_step() {
        let mut c = Counter32::starting_at(u32::MAX - 10);
        assert_eq!(c.now(u32::MAX).as_micros(), 10);
        assert_eq!(c.now(5).as_micros(), 16);
        assert_eq!(c.now(5 + 4_000_000_000).as_micros(), 4_000_000_016);
        // From 4e9 + 5 round past 2^32 to 2e9: 2^32 - 2e9 - 5 later.
        assert_eq!(c.now(2_000_000_000).as_micros(), 6_294_967_307);
    }

    #[test]
    fn byte_stamps_place_either_side_of_the_last_reading() {
        let mut c = Counter32::starting_at(0);
        c.now(1_000);
        assert_eq!(c.at(990).as_micros(), 990);
        assert_eq!(c.at(1_020).as_micros(), 1_020);
        assert!(!c.is_after_now(990) && !c.is_after_now(1_000) && c.is_after_now(1_001));
        // A stamp taken just before the counter wrapped, read just after.
        let mut c = Counter32::starting_at(u32::MAX - 100);
        c.now(50);
        assert_eq!(c.at(u32::MAX - 20).as_micros(), 80);
        // Never before the epoch.
        assert_eq!(Counter32::starting_at(100).at(50).as_micros(), 0);
    }
}
