//! Property tests: the decoder against arbitrary bytes, the engine against
//! random transmitter schedules.

mod sim;

use multirx_core::decoder::SbusDecoder;
use multirx_core::mux::{Link, joins_slice};
use multirx_core::wire::{Flags, Footer, SbusFrame, SbusRepr};
use multirx_core::{Config, Duration, Instant, Mode};
use proptest::prelude::*;
use sim::{Cue, Loss, Sim, SimReceiver, ms};

fn any_frame() -> impl Strategy<Value = SbusRepr> {
    (
        prop::array::uniform16(0u16..=2047),
        0u8..16,
        prop::sample::select(vec![
            Footer::Sbus,
            Footer::Sbus2(0),
            Footer::Sbus2(1),
            Footer::Sbus2(2),
            Footer::Sbus2(3),
        ]),
    )
        .prop_map(|(channels, flags, footer)| SbusRepr {
            channels,
            flags: Flags::from_byte(flags),
            footer,
        })
}

fn decode(chunks: &[&[u8]]) -> Vec<SbusRepr> {
    let mut decoder = SbusDecoder::new();
    let mut out = Vec::new();
    for chunk in chunks {
        decoder.push_slice(chunk, |f| out.push(f));
    }
    out
}

proptest! {
    #[test]
    fn decoder_only_yields_well_formed_frames(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        for frame in decode(&[&bytes]) {
            let wire = frame.to_bytes();
            prop_assert!(SbusFrame::new_checked(&wire[..]).is_ok());
        }
    }

    #[test]
    fn chunking_does_not_matter(frames in prop::collection::vec(any_frame(), 1..8), cut in 0usize..200) {
        let bytes: Vec<u8> = frames.iter().flat_map(|f| f.to_bytes()).collect();
        let cut = cut.min(bytes.len());
        prop_assert_eq!(decode(&[&bytes[..cut], &bytes[cut..]]), frames);
    }

    #[test]
    fn garbage_without_header_bytes_loses_nothing(
        items in prop::collection::vec(
            (any_frame(), prop::collection::vec(any::<u8>().prop_filter("no header", |b| *b != 0x0F), 0..40)),
            1..8,
        )
    ) {
        let mut bytes = Vec::new();
        for (frame, garbage) in &items {
            bytes.extend_from_slice(garbage);
            bytes.extend_from_slice(&frame.to_bytes());
        }
        let expected: Vec<SbusRepr> = items.iter().map(|(f, _)| *f).collect();
        prop_assert_eq!(decode(&[&bytes]), expected);
    }

    /// SBUS has no checksum, so garbage can fake a frame that swallows the
    /// start of a real one; the decoder must be back in step two frames later.
    #[test]
    fn resynchronises_within_two_frames_after_any_garbage(
        garbage in prop::collection::vec(any::<u8>(), 0..100),
        frames in prop::collection::vec(any_frame(), 3..8),
    ) {
        let mut bytes = garbage.clone();
        for f in &frames {
            bytes.extend_from_slice(&f.to_bytes());
        }
        let got = decode(&[&bytes]);
        let tail = &frames[2..];
        prop_assert!(got.len() >= tail.len());
        prop_assert_eq!(&got[got.len() - tail.len()..], tail);
    }

    /// The firmware feeds each loop pass's queued bytes as slices gathered by
    /// `joins_slice`: the link must keep and drop exactly the frames it keeps
    /// and drops fed byte by byte at each byte's own stamp, pauses inside
    /// frames included.
    #[test]
    fn slices_gathered_by_joins_slice_decode_as_bytes_do(
        chunks in prop::collection::vec(
            (any_frame(), 1usize..=25, prop::collection::vec(any::<u8>(), 0..6)),
            1..10,
        ),
        gaps in prop::collection::vec(
            prop::sample::select(vec![0u64, 120, 120, 120, 1_000, 2_999, 3_000, 3_001, 4_100, 9_000]),
            300,
        ),
        passes in prop::collection::vec(any::<bool>(), 300),
    ) {
        // Frames (some cut short) and garbage, each byte at its own stamp.
        let mut stream = Vec::new();
        let mut at = Instant::ZERO;
        for (frame, keep, garbage) in &chunks {
            for &byte in frame.to_bytes()[..*keep].iter().chain(garbage) {
                at += Duration::from_micros(gaps[stream.len() % gaps.len()]);
                stream.push((at, byte));
            }
        }
        let mut by_byte = Link::new(true);
        for &(at, byte) in &stream {
            by_byte.handle_bytes(at, &[byte], 1);
        }
        // A loop pass after random bytes; each pass gathers what it finds.
        // Stamps as the firmware's timer gives them: a 32-bit µs count, here
        // starting near its wrap.
        let raw = |at: Instant| (at.as_micros() as u32).wrapping_add(u32::MAX - 20_000);
        let mut sliced = Link::new(true);
        // Before the first slice: the timer's start, as the firmware does.
        let mut fed = raw(Instant::ZERO);
        let mut slice: Vec<u8> = Vec::new();
        let mut slice_at = Instant::ZERO;
        for (i, &(at, byte)) in stream.iter().enumerate() {
            if !slice.is_empty() && !joins_slice(fed, raw(at)) {
                sliced.handle_bytes(slice_at, &slice, 1);
                fed = raw(slice_at);
                slice.clear();
            }
            slice.push(byte);
            slice_at = at;
            if passes[i % passes.len()] || i + 1 == stream.len() {
                sliced.handle_bytes(slice_at, &slice, 1);
                fed = raw(slice_at);
                slice.clear();
            }
        }
        prop_assert_eq!(sliced.decoder().stats(), by_byte.decoder().stats());
        prop_assert_eq!(sliced.state(), by_byte.state());
        prop_assert_eq!(sliced.frame(), by_byte.frame());
    }
}

/// A random flight: each receiver's transmitter toggles at random times.
fn schedule(n: u8) -> impl Strategy<Value = (Vec<Cue>, Vec<Loss>, u64)> {
    (
        prop::collection::vec((0u64..20_000, 0..n, any::<bool>()), 0..30),
        prop::collection::vec(
            prop::sample::select(vec![Loss::Failsafe, Loss::Silent]),
            usize::from(n),
        ),
        prop::sample::select(vec![7u64, 14]),
    )
        .prop_map(|(mut raw, losses, period)| {
            raw.sort();
            let cues = raw
                .into_iter()
                .map(|(at, rx, tx_on)| Cue {
                    at: ms(at),
                    rx,
                    tx_on,
                })
                .collect();
            (cues, losses, period)
        })
}

fn run(mode: Mode, n: u8, cues: &[Cue], losses: &[Loss], period: u64) -> Sim {
    let mut config = Config::new(mode, n);
    config.frame_period = multirx_core::Duration::from_millis(period);
    let receivers = losses
        .iter()
        .enumerate()
        .map(|(i, loss)| SimReceiver::new(period, 150, *loss, 200 + i as u16 * 150))
        .collect();
    let mut s = Sim::new(config, receivers);
    s.run(ms(25_000), cues);
    s
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn output_never_stops_and_pilot_channel_tells_the_truth(
        mode in prop::sample::select(vec![Mode::Parallel, Mode::Scan]),
        n in 1u8..=6,
        seed in schedule(6),
    ) {
        let (cues, losses, period) = seed;
        let cues: Vec<Cue> = cues.into_iter().filter(|c| c.rx < n).collect();
        let s = run(mode, n, &cues, &losses[..usize::from(n)], period);
        let config = s.mux.config();

        // Cadence: exactly one frame per period, whatever the inputs did.
        prop_assert_eq!(s.max_output_gap(), config.frame_period);
        prop_assert!(s.outputs.len() as u64 >= 25_000 / period);

        for o in &s.outputs {
            prop_assert!(!o.frame.flags.failsafe);
            let pilot = o.frame.channels[usize::from(config.pilot_channel)];
            match o.active {
                Some(rx) => {
                    prop_assert_eq!(pilot, config.pilot_values[usize::from(rx)]);
                    // Sticks are that pilot's.
                    prop_assert_eq!(o.frame.channels[0], s.receivers[usize::from(rx)].sticks[0]);
                }
                None => {
                    prop_assert_eq!(pilot, config.no_receiver_value);
                    prop_assert_eq!(
                        o.frame.channels[usize::from(config.flight_mode_channel)],
                        config.auto_loiter_value
                    );
                }
            }
        }
        prop_assert_eq!(s.idle_takeovers, 0);
    }

    /// Scenario A, strongly: a pilot whose transmitter never goes off keeps
    /// control from the moment it has it, whatever the others do.
    #[test]
    fn a_pilot_with_a_steady_link_is_never_displaced(
        mode in prop::sample::select(vec![Mode::Parallel, Mode::Scan]),
        seed in schedule(4),
    ) {
        let (cues, losses, period) = seed;
        let mut cues: Vec<Cue> = cues.into_iter().filter(|c| c.rx != 0).collect();
        cues.insert(0, Cue { at: ms(0), rx: 0, tx_on: true });
        let s = run(mode, 4, &cues, &losses[..4], period);
        let first = s.outputs.iter().position(|o| o.active == Some(0));
        prop_assert!(first.is_some(), "pilot 1 never got control");
        let first = first.unwrap_or_default();
        prop_assert!(s.outputs[first..].iter().all(|o| o.active == Some(0)));
    }
}
