//! One clock for the whole rig and its fixtures.
//!
//! Every timestamp the rig compares is a CLOCK_MONOTONIC reading: what Rust's
//! `std::time::Instant` and Python's `time.monotonic()` both read on Linux.
//! So a Python fixture can say "I wrote the failsafe frame at t" and the rig
//! can subtract that from when the flight-controller side saw the handover.

use std::fmt;
use std::time::Duration;

/// A CLOCK_MONOTONIC reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Mono(Duration);

impl Mono {
    pub fn now() -> Mono {
        let ts = rustix::time::clock_gettime(rustix::time::ClockId::Monotonic);
        Mono(Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32))
    }

    /// From a fixture's `time.monotonic()` seconds.
    pub fn from_secs_f64(secs: f64) -> Mono {
        Mono(Duration::from_secs_f64(secs.max(0.0)))
    }

    pub fn as_secs_f64(self) -> f64 {
        self.0.as_secs_f64()
    }

    /// Time from `earlier` to `self`, zero if `earlier` is later.
    pub fn since(self, earlier: Mono) -> Duration {
        self.0.saturating_sub(earlier.0)
    }

    /// Milliseconds from `earlier` to `self`, negative if `earlier` is later.
    pub fn ms_since(self, earlier: Mono) -> f64 {
        (self.0.as_secs_f64() - earlier.0.as_secs_f64()) * 1000.0
    }
}

impl std::ops::Add<Duration> for Mono {
    type Output = Mono;
    fn add(self, d: Duration) -> Mono {
        Mono(self.0 + d)
    }
}

impl std::ops::Sub<Duration> for Mono {
    type Output = Mono;
    /// Saturates at the clock's zero.
    fn sub(self, d: Duration) -> Mono {
        Mono(self.0.saturating_sub(d))
    }
}

impl fmt::Display for Mono {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.6}s", self.0.as_secs_f64())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agrees_with_std_instant_and_python() {
        let a = Mono::now();
        std::thread::sleep(Duration::from_millis(5));
        let b = Mono::now();
        assert!(b.since(a) >= Duration::from_millis(5));
        // Python's time.monotonic() in a child reads the same clock.
        let out = std::process::Command::new("python3")
            .args(["-c", "import time; print(time.monotonic())"])
            .output();
        if let Ok(out) = out {
            let t: f64 = String::from_utf8_lossy(&out.stdout).trim().parse().unwrap();
            let c = Mono::now();
            let py = Mono::from_secs_f64(t);
            assert!(py >= b && py <= c, "python {py} not within {b}..{c}");
        }
    }
}
