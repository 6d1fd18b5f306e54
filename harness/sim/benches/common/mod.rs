//! What the benchmarks share: a simulated PX4 flight to replay.

use mavlora::{Duration, Instant};

use harness_sim::{Px4Fc, StreamSpec};

/// 60 s of a PX4 on stream profile `profile` (`harness_sim::PX4_NORMAL`, `PX4_CONFIG`) at
/// full rate, as (time, frame bytes).
pub fn px4_capture(profile: &'static [StreamSpec]) -> Vec<(Instant, Vec<u8>)> {
    let mut fc = Px4Fc::new(profile, Instant::ZERO, 1);
    let mut out = Vec::new();
    let mut now = Instant::ZERO;
    while now < Instant::from_millis(60_000) {
        fc.handle_timeout(now);
        while let Some(f) = fc.poll_transmit() {
            out.push((now, f.into_inner()));
        }
        now = fc
            .poll_timeout()
            .unwrap()
            .max(now + Duration::from_micros(1));
    }
    out
}
