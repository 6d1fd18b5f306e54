//! Cost of the core per input frame on this host.
//!
//! Machines are shared and noisy, so the figure that matters is the ratio to
//! a baseline measured in the same run: decoding the same bytes with the bare
//! [`SbusDecoder`]. The engine's overhead on top of decoding is what MultiRX
//! adds. Run with `cargo bench -p multirx-core`.

use std::hint::black_box;
use std::time::Instant as Clock;

use multirx_core::decoder::SbusDecoder;
use multirx_core::wire::SbusRepr;
use multirx_core::{Config, Duration, Instant, Mode, Multiplexer};

const FRAMES: usize = 200_000;

fn input() -> Vec<[u8; 25]> {
    (0..FRAMES)
        .map(|i| {
            let mut repr = SbusRepr::default();
            repr.channels[0] = (i % 2048) as u16;
            repr.to_bytes()
        })
        .collect()
}

/// Best of several runs of `f`, in ns per frame.
fn ns_per_frame(mut f: impl FnMut() -> u64) -> f64 {
    (0..7)
        .map(|_| {
            let start = Clock::now();
            black_box(f());
            start.elapsed().as_nanos() as f64 / FRAMES as f64
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let frames = input();
    let baseline = ns_per_frame(|| {
        let mut decoder = SbusDecoder::new();
        let mut n = 0u64;
        for f in &frames {
            decoder.push_slice(f, |r| n += u64::from(r.channels[0]));
        }
        n
    });
    let mut results = vec![("decode only (baseline)", baseline)];
    for (name, mode, n) in [
        ("mux parallel, 2 receivers", Mode::Parallel, 2u8),
        ("mux parallel, 6 receivers", Mode::Parallel, 6),
        ("mux scan, 2 receivers", Mode::Scan, 2),
    ] {
        let ns = ns_per_frame(|| {
            let config = Config::new(mode, n);
            let mut mux = Multiplexer::new(config, Instant::ZERO);
            let mut out = 0u64;
            let step = Duration::from_micros(7_000 / u64::from(n));
            let mut now = Instant::ZERO;
            for (i, f) in frames.iter().enumerate() {
                now += step;
                mux.handle_receiver_bytes(now, (i % usize::from(n)) as u8, f);
                if mux.poll_timeout().is_some_and(|due| now >= due) {
                    mux.handle_timeout(now);
                }
                if let Some(frame) = mux.poll_transmit() {
                    out += u64::from(frame[1]);
                }
                while mux.poll_event().is_some() {}
            }
            out
        });
        results.push((name, ns));
    }
    println!("multirx-core cost per input frame ({FRAMES} frames, best of 7):");
    for (name, ns) in &results {
        println!(
            "  {name:<28} {ns:>8.1} ns/frame  {:>5.2}x baseline",
            ns / baseline
        );
    }
}
