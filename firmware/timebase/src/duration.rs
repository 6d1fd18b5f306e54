//! Spans of time.

use core::fmt;
use core::iter::Sum;
use core::ops::{Add, AddAssign, Div, Mul, Sub, SubAssign};

/// A span of time in microseconds.
///
/// Subtraction saturates at zero; use [`checked_sub`](Self::checked_sub) where "does not fit"
/// is an answer.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Duration {
    micros: u64,
}

impl Duration {
    /// No time.
    pub const ZERO: Duration = Duration { micros: 0 };
    /// The longest span (about 584 000 years).
    pub const MAX: Duration = Duration { micros: u64::MAX };

    /// `micros` microseconds.
    pub const fn from_micros(micros: u64) -> Self {
        Duration { micros }
    }

    /// `millis` milliseconds.
    pub const fn from_millis(millis: u64) -> Self {
        Duration {
            micros: millis.saturating_mul(1_000),
        }
    }

    /// `secs` seconds.
    pub const fn from_secs(secs: u64) -> Self {
        Duration {
            micros: secs.saturating_mul(1_000_000),
        }
    }

    /// `secs` seconds, truncated to whole microseconds after `core::time::Duration`'s
    /// conversion to nanoseconds (so decimal settings such as 0.1184 s come out exact, and
    /// a period of 1/6 s is what engines got before by adding a `core` duration to an
    /// instant); negative and NaN give zero, too large saturates.
    pub fn from_secs_f64(secs: f64) -> Self {
        match core::time::Duration::try_from_secs_f64(secs) {
            Ok(d) => Duration::from(d),
            Err(_) if secs > 0.0 => Duration::MAX,
            Err(_) => Duration::ZERO,
        }
    }

    /// Whole microseconds.
    pub const fn as_micros(self) -> u64 {
        self.micros
    }

    /// Whole milliseconds, rounded down.
    pub const fn as_millis(self) -> u64 {
        self.micros / 1_000
    }

    /// Whole seconds, rounded down.
    pub const fn as_secs(self) -> u64 {
        self.micros / 1_000_000
    }

    /// Seconds.
    pub fn as_secs_f64(self) -> f64 {
        self.micros as f64 / 1e6
    }

    /// Whether this is no time at all.
    pub const fn is_zero(self) -> bool {
        self.micros == 0
    }

    /// `self - rhs`, or `None` if `rhs` is longer.
    pub const fn checked_sub(self, rhs: Duration) -> Option<Duration> {
        match self.micros.checked_sub(rhs.micros) {
            Some(micros) => Some(Duration { micros }),
            None => None,
        }
    }

    /// The difference, whichever is longer.
    pub const fn abs_diff(self, other: Duration) -> Duration {
        Duration {
            micros: self.micros.abs_diff(other.micros),
        }
    }
}

impl fmt::Display for Duration {
    /// Milliseconds with microseconds: `7.250ms`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:03}ms", self.micros / 1_000, self.micros % 1_000)
    }
}

impl fmt::Debug for Duration {
    /// As `core::time::Duration` prints (`7.25ms`), so logs read the same as before.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&core::time::Duration::from(*self), f)
    }
}

impl From<core::time::Duration> for Duration {
    /// Truncated to whole microseconds, saturating at [`Duration::MAX`].
    fn from(d: core::time::Duration) -> Duration {
        // Seconds and sub-second part apart: no 128-bit maths.
        let micros = d
            .as_secs()
            .saturating_mul(1_000_000)
            .saturating_add(u64::from(d.subsec_micros()));
        Duration { micros }
    }
}

impl From<Duration> for core::time::Duration {
    fn from(d: Duration) -> core::time::Duration {
        core::time::Duration::from_micros(d.micros)
    }
}

impl Add for Duration {
    type Output = Duration;
    fn add(self, rhs: Duration) -> Duration {
        Duration::from_micros(self.micros.saturating_add(rhs.micros))
    }
}

impl AddAssign for Duration {
    fn add_assign(&mut self, rhs: Duration) {
        *self = *self + rhs;
    }
}

impl Sub for Duration {
    type Output = Duration;
    /// Saturates at zero.
    fn sub(self, rhs: Duration) -> Duration {
        Duration::from_micros(self.micros.saturating_sub(rhs.micros))
    }
}

impl SubAssign for Duration {
    fn sub_assign(&mut self, rhs: Duration) {
        *self = *self - rhs;
    }
}

impl Mul<u32> for Duration {
    type Output = Duration;
    fn mul(self, rhs: u32) -> Duration {
        Duration::from_micros(self.micros.saturating_mul(u64::from(rhs)))
    }
}

impl Mul<Duration> for u32 {
    type Output = Duration;
    fn mul(self, rhs: Duration) -> Duration {
        rhs * self
    }
}

impl Div<u32> for Duration {
    type Output = Duration;
    /// Rounded down. Panics on zero, like integer division.
    fn div(self, rhs: u32) -> Duration {
        Duration::from_micros(self.micros / u64::from(rhs))
    }
}

impl Sum for Duration {
    fn sum<I: Iterator<Item = Duration>>(iter: I) -> Duration {
        iter.fold(Duration::ZERO, Add::add)
    }
}

impl<'a> Sum<&'a Duration> for Duration {
    fn sum<I: Iterator<Item = &'a Duration>>(iter: I) -> Duration {
        iter.copied().sum()
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::format;
    use std::string::ToString;

    use super::*;

    #[test]
    fn arithmetic_saturates_instead_of_panicking() {
        let d = Duration::from_millis(2);
        assert_eq!(d - Duration::from_millis(3), Duration::ZERO);
        assert_eq!(d.checked_sub(Duration::from_millis(3)), None);
        assert_eq!(Duration::MAX + d, Duration::MAX);
        assert_eq!(Duration::from_secs(u64::MAX), Duration::MAX);
        assert_eq!(d * 3 / 2, Duration::from_millis(3));
        assert_eq!(2 * d, Duration::from_millis(4));
    }

    #[test]
    fn floats_are_exact_for_decimals_and_truncate_the_rest() {
        // 0.1184 * 1e6 is 118399.99999999999 in f64; via nanoseconds it stays exact.
        assert_eq!(
            Duration::from_secs_f64(0.1184),
            Duration::from_micros(118_400)
        );
        assert_eq!(
            Duration::from_secs_f64(1.0 / 6.0),
            Duration::from_micros(166_666)
        );
        assert_eq!(Duration::from_secs_f64(-1.0), Duration::ZERO);
        assert_eq!(Duration::from_secs_f64(f64::NAN), Duration::ZERO);
        assert_eq!(Duration::from_secs_f64(1e300), Duration::MAX);
    }

    #[test]
    fn converts_to_and_from_core_duration() {
        let core = core::time::Duration::from_nanos(1_500_999);
        assert_eq!(Duration::from(core), Duration::from_micros(1_500));
        assert_eq!(
            core::time::Duration::from(Duration::from_micros(1_500)),
            core::time::Duration::from_micros(1_500)
        );
        assert_eq!(Duration::from(core::time::Duration::MAX), Duration::MAX);
    }

    #[test]
    fn display_and_debug_are_readable() {
        assert_eq!(Duration::from_micros(7_250).to_string(), "7.250ms");
        assert_eq!(format!("{:?}", Duration::from_micros(7_250)), "7.25ms");
        assert_eq!(format!("{:?}", Duration::from_secs(5)), "5s");
    }
}
