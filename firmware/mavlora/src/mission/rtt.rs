//! Round-trip time estimate and retransmission timeout, by RFC 6298 (TCP's rules: smoothed
//! RTT and variance, RTO = SRTT + max(G, 4·RTTVAR), doubled on each timeout, samples only
//! from requests answered on their first transmission — Karn's rule, applied by the caller).
//! G, the RFC's clock granularity, is here a floor on the margin ([`MARGIN`]): on a radio
//! with a steady round trip RTTVAR decays to nothing, and a reply queued behind one
//! telemetry frame would then count as lost.
//! Written here rather than taken from a crate: it is twenty lines and needs our `Duration`
//! handling, not a transport stack.

use crate::time::Duration;

/// Smallest margin above SRTT: about the airtime of one 41-byte compact telemetry frame at
/// 683 B/s (60 ms), with room.
pub const MARGIN: Duration = Duration::from_millis(100);

/// A timeout to start from before any round trip is measured: a frame of `frame_bytes` each
/// way at `rate_bytes_per_s` (the radio budget both ends pace to) plus [`MARGIN`].
pub fn unmeasured_timeout(frame_bytes: u64, rate_bytes_per_s: u32) -> Duration {
    Duration::from_micros(2 * frame_bytes * 1_000_000 / u64::from(rate_bytes_per_s.max(1))) + MARGIN
}

/// Sans-IO RTT estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct RttEstimator {
    srtt: Option<Duration>,
    rttvar: Duration,
    rto: Duration,
    min: Duration,
    max: Duration,
    samples: u64,
}

impl RttEstimator {
    /// An estimator whose timeout starts at `initial` and stays within `min..=max`.
    pub fn new(initial: Duration, min: Duration, max: Duration) -> Self {
        Self {
            srtt: None,
            rttvar: Duration::ZERO,
            rto: initial.clamp(min, max),
            min,
            max,
            samples: 0,
        }
    }

    /// Takes one measured round trip.
    pub fn sample(&mut self, rtt: Duration) {
        self.samples += 1;
        match self.srtt {
            None => {
                self.srtt = Some(rtt);
                self.rttvar = rtt / 2;
            }
            Some(srtt) => {
                let diff = srtt.abs_diff(rtt);
                self.rttvar = (self.rttvar * 3 + diff) / 4;
                self.srtt = Some((srtt * 7 + rtt) / 8);
            }
        }
        let srtt = self.srtt.unwrap_or(rtt);
        self.rto = (srtt + (self.rttvar * 4).max(MARGIN)).clamp(self.min, self.max);
    }

    /// A request timed out: back off (RFC 6298 5.5).
    pub fn backoff(&mut self) {
        self.rto = (self.rto * 2).min(self.max);
    }

    /// Current retransmission timeout.
    pub fn rto(&self) -> Duration {
        self.rto
    }

    /// Smoothed round-trip time, once measured.
    pub fn srtt(&self) -> Option<Duration> {
        self.srtt
    }

    /// Round trips measured.
    pub fn samples(&self) -> u64 {
        self.samples
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: fn(u64) -> Duration = Duration::from_millis;

    #[test]
    fn follows_the_measured_round_trip() {
        let mut r = RttEstimator::new(MS(1000), MS(100), MS(10_000));
        assert_eq!(r.rto(), MS(1000));
        r.sample(MS(400));
        // first sample: SRTT 400, RTTVAR 200, RTO 400 + 800
        assert_eq!(r.rto(), MS(1200));
        for _ in 0..50 {
            r.sample(MS(400));
        }
        // converges towards the RTT plus the minimum margin
        assert!(r.rto() < MS(520), "{:?}", r.rto());
        assert!(r.rto() >= MS(500));
        r.backoff();
        assert!(r.rto() >= MS(800));
    }

    #[test]
    fn stays_within_bounds() {
        let mut r = RttEstimator::new(MS(1000), MS(300), MS(2000));
        r.sample(MS(1));
        for _ in 0..20 {
            r.sample(MS(1));
        }
        assert_eq!(r.rto(), MS(300));
        for _ in 0..10 {
            r.backoff();
        }
        assert_eq!(r.rto(), MS(2000));
    }
}
