use super::*;

const MS: Duration = Duration::from_millis(1);

fn at(d: Duration) -> Instant {
    Instant::ZERO + d
}

fn drain(link: &mut Link, until: Instant) -> Vec<(Instant, Vec<u8>)> {
    let mut out = Vec::new();
    while let Some(t) = link.poll_timeout() {
        if t > until {
            break;
        }
        link.handle_timeout(t);
        while let Some(b) = link.poll_output() {
            out.push((t, b));
        }
    }
    out
}

#[test]
fn lora_sends_a_partial_packet_after_the_idle_timeout() {
    let p = Preset::lora_sf7();
    let cfg = LinkConfig {
        latency_ms: 10.0,
        ..LinkConfig::default()
    };
    let mut link = Link::new(&p, &cfg, Slot::A).unwrap();
    link.handle_input(Instant::ZERO, &[7; 17]);
    // 17 data + 4 RadioHead = 21 bytes: 56.576 ms on air, after 5 ms idle, + 10 ms latency.
    assert_eq!(link.poll_timeout(), Some(at(5 * MS)));
    let out = drain(&mut link, Instant::from_secs(1));
    assert_eq!(out.len(), 1);
    assert_eq!(
        out[0].0,
        at(5 * MS + Duration::from_micros(56_576) + 10 * MS)
    );
    assert_eq!(out[0].1, vec![7; 17]);
    let s = link.stats();
    assert_eq!((s.packets_sent, s.bytes_delivered), (1, 17));
}

#[test]
fn overflow_drops_what_does_not_fit_the_buffer() {
    let p = Preset::lora_sf7();
    let mut link = Link::new(&p, &LinkConfig::default(), Slot::A).unwrap();
    link.handle_input(Instant::ZERO, &[1; 1000]);
    // A full buffer sends at once: 251 bytes leave, 256 stay buffered at most.
    let s = link.stats().clone();
    assert_eq!(s.bytes_offered, 1000);
    assert_eq!(s.bytes_dropped, 1000 - 256);
    assert_eq!(link.buffered(), 256 - 251);
    drain(&mut link, Instant::from_secs(5));
    assert_eq!(link.stats().bytes_delivered, 256);
}

#[test]
fn sik_waits_for_its_own_window() {
    let p = Preset::sik_64k();
    let mut b = Link::new(&p, &LinkConfig::default(), Slot::B).unwrap();
    // Slot B's first window opens at window + silence = 118.4 ms.
    b.handle_input(Instant::ZERO, &[3; 10]);
    assert_eq!(b.poll_timeout(), Some(Instant::from_micros(118_400)));
    // Later in B's window a packet leaves at once.
    let mut b2 = Link::new(&p, &LinkConfig::default(), Slot::B).unwrap();
    b2.set_trace(true);
    b2.handle_input(at(150 * MS), &[3; 10]);
    assert_eq!(b2.take_trace()[0].start, at(150 * MS));
    // 10 data + 2 trailer + 5 framing + 7 preamble/sync = 24 B = 3 ms on air.
    assert_eq!(b2.poll_timeout(), Some(at(153 * MS)));
}

#[test]
fn a_packet_must_end_inside_the_window() {
    let p = Preset::sik_64k();
    let mut a = Link::new(&p, &LinkConfig::default(), Slot::A).unwrap();
    a.set_trace(true);
    // 110 ms into a 114.24 ms window: 4.24 ms of room, 1 ms = 8 bytes at
    // 64 kbit/s, 14 bytes of framing → 19 data bytes fit (33 B = 4.125 ms).
    a.handle_input(at(110 * MS), &[9; 100]);
    drain(&mut a, Instant::from_secs(1));
    let trace = a.take_trace();
    assert_eq!(trace[0].start, at(110 * MS));
    assert_eq!(trace[0].bytes, 19);
    // The rest waits for the next A window at 236.8 ms.
    assert_eq!(trace[1].start, Instant::from_micros(236_800));
    assert_eq!(trace[1].bytes, 81);
}

#[test]
fn tdm_window_arithmetic() {
    let (w, r, ph) = (10 * MS, 30 * MS, 15 * MS);
    let window = |t| tdm_window(at(t), w, r, ph);
    assert_eq!(window(Duration::ZERO), (at(15 * MS), at(25 * MS)));
    assert_eq!(window(20 * MS), (at(15 * MS), at(25 * MS)));
    assert_eq!(window(25 * MS), (at(45 * MS), at(55 * MS)));
    assert_eq!(window(50 * MS), (at(45 * MS), at(55 * MS)));
}

/// Sends `chunk(k)` every `period` for `n` chunks; returns what arrived, in order.
fn send_every(
    link: &mut Link,
    period: Duration,
    n: u32,
    chunk: impl Fn(u32) -> Vec<u8>,
) -> Vec<(Instant, Vec<u8>)> {
    let mut out = Vec::new();
    for k in 0..n {
        let t = at(period * k);
        out.extend(drain(link, t));
        link.handle_input(t, &chunk(k));
        // Balance holds at every step.
        let s = link.stats();
        assert_eq!(
            s.bytes_offered,
            s.bytes_dropped + s.bytes_lost + s.bytes_delivered - s.bytes_duplicated
                + link.queued_bytes() as u64
        );
    }
    out.extend(drain(link, at(period * n) + Duration::from_secs(10)));
    out
}

/// Regression: the Gilbert-Elliott chain stepped once per packet, so on an
/// uplink with one command a second a 30-packet burst was a 30 s outage.
/// Stepped per ms, 30 ms fades hit single commands, never runs of them.
#[test]
fn a_sparse_uplink_does_not_stretch_a_burst_over_seconds() {
    let cfg = LinkConfig {
        // 10 % of the time bad, 30 ms fades (the chain steps per ms, not per packet).
        burst: Some(GilbertElliott {
            p_good_to_bad: 0.1 / 0.9 / 30.0,
            p_bad_to_good: 1.0 / 30.0,
            loss_good: 0.0,
            loss_bad: 1.0,
        }),
        seed: 4,
        ..LinkConfig::default()
    };
    let mut link = Link::new(&Preset::sik_64k(), &cfg, Slot::B).unwrap();
    let out = send_every(&mut link, Duration::from_secs(1), 3000, |k| {
        k.to_le_bytes().repeat(5)
    });
    // A command split over two air packets is lost if either is; each arrives
    // within a TDM round (< 1 s) of being sent, so its second tells which it is.
    let mut got = vec![0usize; 3000];
    for (t, b) in &out {
        got[(t.as_micros() / 1_000_000) as usize] += b.len();
    }
    let (mut runs, mut longest, mut run) = (Vec::new(), 0, 0);
    for &n in &got {
        if n < 20 {
            run += 1;
            longest = longest.max(run);
        } else if run > 0 {
            runs.push(run);
            run = 0;
        }
    }
    let lost: usize = runs.iter().sum();
    let mean_run = lost as f64 / runs.len() as f64;
    // A 1 s gap forgets the state (p ≈ e^-33): runs are geometric in the
    // ~11 % per-packet loss, mean 1.12, P(run ≥ 5) ≈ 1.5e-4 per run.
    assert!((200..=450).contains(&lost), "{lost} of 3000 lost");
    assert!(
        mean_run < 1.3 && longest <= 4,
        "mean run {mean_run}, longest {longest}"
    );
}

/// The ms steps `[first, last)` a packet on air overlaps: where the burst chain judges it.
fn chain_steps(p: &AirPacket) -> (u64, u64) {
    let first = p.start.as_micros() / 1000;
    let last = (p.start + p.airtime)
        .as_micros()
        .div_ceil(1000)
        .max(first + 1);
    (first, last)
}

/// Gilbert model (loss_good 0, loss_bad 1): probability that no piece of a frame is
/// hit, i.e. the chain is good at every step the pieces overlap, given its state
/// (`from_bad`) at step `from`, before the first piece.
fn p_clean(ge: &GilbertElliott, from_bad: bool, from: u64, pieces: &[(u64, u64)]) -> f64 {
    let (mut p, mut bad, mut at) = (1.0, from_bad, from);
    for &(first, last) in pieces {
        let stay_good = (1.0 - ge.p_good_to_bad).powi((last - first - 1) as i32);
        p *= (1.0 - ge.p_bad_after(bad, first - at)) * stay_good;
        (bad, at) = (false, last - 1);
    }
    p
}

/// Regression guard for a CI run over the rig's `sik-64k-bursty` (10 % bad, 250 ms
/// fades) where 4 mission-item requests 1.5 s apart were lost in a row. The
/// ground's sparse traffic, a 40-byte frame every 500 ± 50 ms for 15 s, goes through
/// the `Radio` the emulator runs, built from the rig file's own table, over 2,000
/// seeds. Every expectation is the model's, computed from where each frame was on
/// air (the trace) with `GilbertElliott::p_bad_after`, the chain starting good at 0:
/// - the loss share is the sum of the frames' marginal loss probabilities;
/// - after a lost frame the next one `d` frames on is lost with a probability between
///   the one from a good and the one from a bad state at the lost frame's end (by
///   the Markov property; weighted by a lower bound on still being bad): ≈ 0.2 at
///   0.5 s, ≈ the 10 % marginal at 1.5 s, where a chain stepped per packet or judged
///   at the wrong time would carry the fade over;
/// - 4 frames 1.5 s apart are all lost no more than 10× as often as if independent;
/// - no streak of lost frames is longer than one the chain rule bounds below 1e-3.
#[test]
fn a_bursty_sik_uplink_forgets_its_fades_between_sparse_frames() {
    use crate::{Direction, RadioSetup};
    use rand::{RngExt, SeedableRng};

    const SEEDS: u64 = 2000;
    const FRAMES: usize = 30;
    const FRAME_BYTES: usize = 40;
    let rig: toml::Table = toml::from_str(include_str!("../../../../rigs/emulated.toml")).unwrap();
    let setup: RadioSetup = rig["radios"]["sik-64k-bursty"].clone().try_into().unwrap();
    let ge = setup.uplink.burst.unwrap();
    assert!(
        (ge.loss_good, ge.loss_bad) == (0.0, 1.0) && setup.uplink.packet_loss == 0.0,
        "the expectations below are for the Gilbert model alone: {setup:?}"
    );
    let preset = setup.preset.resolve().unwrap();
    assert!(setup.uplink.budget.reference_per(&preset) < 1e-6);

    struct Frame {
        pieces: Vec<(u64, u64)>,
        lost: bool,
    }
    impl Frame {
        fn start(&self) -> u64 {
            self.pieces[0].0
        }
        fn end(&self) -> u64 {
            self.pieces.last().unwrap().1 - 1
        }
    }
    // Bounds on P(`next` lost | `prev` lost and all before): (low, high).
    let after_loss = |prev: &Frame, next: &Frame| {
        let hi = 1.0 - p_clean(&ge, true, prev.end(), &next.pieces);
        let lo = 1.0 - p_clean(&ge, false, prev.end(), &next.pieces);
        // Lost means bad at some step of `prev`; still bad at its end at least this often.
        let w = ge.p_bad_after(true, prev.end() - prev.start());
        (w * hi + (1.0 - w) * lo, hi)
    };

    let (mut lost, mut expected, mut var) = (0usize, 0.0, 0.0);
    // Per lag (1 frame = 0.5 s, 3 frames = 1.5 s): losses followed by a loss, bounds, variance.
    let mut lag = [
        (1usize, 0usize, 0usize, 0.0, 0.0, 0.0),
        (3, 0, 0, 0.0, 0.0, 0.0),
    ];
    let (mut fours, mut runs_with_four, mut fours_independent, mut fours_bound) =
        (0usize, 0usize, 0.0, 0.0);
    let (mut longest, mut streak_bound) = (0usize, vec![0.0; FRAMES + 1]);
    let mut windows_like_ci = 0usize;
    for seed in 0..SEEDS {
        let mut setup = setup.clone();
        setup.uplink.seed = seed;
        setup.downlink.seed = seed + SEEDS;
        let mut radio = setup.radio().unwrap();
        radio.link_mut(Direction::Uplink).set_trace(true);
        let mut got = [0usize; FRAMES];
        let mut run_until = |radio: &mut crate::Radio, until: Instant| {
            while let Some(t) = radio.poll_timeout().filter(|&t| t <= until) {
                radio.handle_timeout(t);
                while let Some(b) = radio.poll_output(Direction::Uplink) {
                    b.iter().for_each(|&k| got[k as usize] += 1);
                }
            }
        };
        let mut traffic = ChaCha8Rng::seed_from_u64(seed);
        traffic.set_stream(9);
        for k in 0..FRAMES {
            let jitter = Duration::from_micros((traffic.random::<f64>() * 100_000.0) as u64);
            let t = at(MS * (450 + 500 * k as u32) + jitter);
            run_until(&mut radio, t);
            radio.handle_input(t, Direction::Uplink, &[k as u8; FRAME_BYTES]);
        }
        run_until(&mut radio, Instant::from_secs(20));

        // Air packets to frames: a frame leaves before the next is written.
        let mut frames: Vec<Frame> = (0..FRAMES)
            .map(|_| Frame {
                pieces: Vec::new(),
                lost: false,
            })
            .collect();
        let mut sent = 0;
        for p in radio.link_mut(Direction::Uplink).take_trace() {
            let k = sent / FRAME_BYTES;
            assert!(sent % FRAME_BYTES + p.bytes <= FRAME_BYTES);
            frames[k].pieces.push(chain_steps(&p));
            frames[k].lost |= p.lost;
            sent += p.bytes;
        }
        assert_eq!(sent, FRAMES * FRAME_BYTES);
        for (f, &n) in frames.iter().zip(&got) {
            assert_eq!(
                f.lost,
                n < FRAME_BYTES,
                "the far port sees what the trace says"
            );
        }

        let p: Vec<f64> = frames
            .iter()
            .map(|f| 1.0 - p_clean(&ge, false, 0, &f.pieces))
            .collect();
        lost += frames.iter().filter(|f| f.lost).count();
        expected += p.iter().sum::<f64>();
        var += p.iter().map(|p| p * (1.0 - p)).sum::<f64>();
        for (d, prev_lost, both, lo_sum, hi_sum, v) in &mut lag {
            for j in 0..FRAMES - *d {
                if frames[j].lost {
                    let (lo, hi) = after_loss(&frames[j], &frames[j + *d]);
                    *prev_lost += 1;
                    *both += frames[j + *d].lost as usize;
                    (*lo_sum, *hi_sum, *v) = (*lo_sum + lo, *hi_sum + hi, *v + hi * (1.0 - lo));
                }
            }
        }
        let mut any_four = false;
        for j in 0..FRAMES - 9 {
            let w = [j, j + 3, j + 6, j + 9];
            fours_independent += w.iter().map(|&i| p[i]).product::<f64>();
            fours_bound += p[j]
                * w.windows(2)
                    .map(|s| after_loss(&frames[s[0]], &frames[s[1]]).1)
                    .product::<f64>();
            if w.iter().all(|&i| frames[i].lost) {
                fours += 1;
                any_four = true;
            }
        }
        runs_with_four += any_four as usize;
        // Streaks: P(frames i..i+L all lost) ≤ p_i · Π high bounds, by the chain rule.
        let mut run = 0;
        for f in &frames {
            run = if f.lost { run + 1 } else { 0 };
            longest = longest.max(run);
        }
        for i in 0..FRAMES {
            let mut bound = p[i];
            streak_bound[1] += bound;
            for l in 2..=FRAMES - i {
                bound *= after_loss(&frames[i + l - 2], &frames[i + l - 1]).1;
                streak_bound[l] += bound;
            }
        }
        // The CI run's look: 7 or more of 17 frames (8 s) lost.
        windows_like_ci += frames
            .windows(17)
            .any(|w| w.iter().filter(|f| f.lost).count() >= 7) as usize;
    }

    let n = SEEDS as usize * FRAMES;
    let share = lost as f64 / n as f64;
    eprintln!(
        "frames lost {lost} of {n} ({share:.4}), model {:.4}; bad share {:.4}",
        expected / n as f64,
        ge.bad_share()
    );
    // Neighbours 0.5 s apart are correlated (memory (1 − a − b)^~490 ≈ 0.11), so
    // the binomial variance is widened by 2 (1 + 2·Σρ ≈ 1.25 here).
    let sd = (2.0 * var).sqrt();
    assert!(
        (lost as f64 - expected).abs() < 5.0 * sd,
        "{lost} frames lost, model {expected:.0} ± {sd:.0}"
    );
    for &(d, prev_lost, both, lo, hi, v) in &lag {
        // Martingale differences (d interleaved sequences for lag d).
        let sd = (d as f64 * v).sqrt();
        eprintln!(
            "lost {} ms after a loss: {both} of {prev_lost} ({:.4}), model {:.4}..{:.4}",
            d * 500,
            both as f64 / prev_lost as f64,
            lo / prev_lost as f64,
            hi / prev_lost as f64
        );
        assert!(
            lo - 5.0 * sd < both as f64 && (both as f64) < hi + 5.0 * sd,
            "lag {d}: {both} of {prev_lost} losses followed by a loss, model {lo:.0}..{hi:.0} ± {sd:.0}"
        );
    }
    eprintln!(
        "4 in a row 1.5 s apart: {fours} windows in {runs_with_four} of {SEEDS} runs \
         ({:.2e} per 15 s run), independent {fours_independent:.2} windows, model ≤ {fours_bound:.2}",
        runs_with_four as f64 / SEEDS as f64
    );
    assert!(
        (fours as f64) < 10.0 * fours_independent,
        "{fours} windows of 4 frames 1.5 s apart all lost; independent loss gives {fours_independent:.2}"
    );
    let limit = (1..=FRAMES).find(|&l| streak_bound[l] < 1e-3).unwrap();
    eprintln!(
        "longest streak {longest} frames, P(≥ {limit}) ≤ {:.1e} by the model; \
         runs with ≥ 7 of 17 frames lost: {windows_like_ci} of {SEEDS}",
        streak_bound[limit]
    );
    assert!(longest < limit, "{longest} frames lost in a row");
}

#[test]
fn nothing_on_air_in_a_silence_arrives_and_the_link_comes_back_after_it() {
    let cfg = LinkConfig {
        silences: vec![Silence {
            at_s: 2.0,
            for_s: 3.0,
            every_s: None,
        }],
        ..LinkConfig::default()
    };
    let mut link = Link::new(&Preset::sik_64k(), &cfg, Slot::A).unwrap();
    link.set_trace(true);
    let out = send_every(&mut link, 100 * MS, 100, |k| vec![k as u8; 20]);
    let (silence, end) = (at(2000 * MS), at(5000 * MS));
    for p in link.take_trace() {
        let overlaps = p.start < end && p.start + p.airtime > silence;
        assert_eq!(p.lost, overlaps, "packet at {:?}", p.start);
    }
    assert_eq!(link.silence_at(at(3000 * MS)), Some(end));
    assert_eq!(link.silence_at(end), None);
    let s = link.stats();
    assert!(s.packets_silenced > 0 && s.packets_silenced == s.packets_lost);
    // Chunks sent from the silence's end on all arrive.
    let seen: std::collections::BTreeSet<u8> = out.iter().flat_map(|(_, b)| b.clone()).collect();
    assert!((50..100).all(|k| seen.contains(&k)));
    assert!(!seen.contains(&30));
}

#[test]
fn a_silence_added_while_running_takes_and_a_bad_one_is_refused() {
    let mut link = Link::new(&Preset::sik_64k(), &LinkConfig::default(), Slot::A).unwrap();
    let before = send_every(&mut link, 100 * MS, 20, |k| vec![k as u8; 20]);
    assert!(!before.is_empty());
    let bad = Silence {
        at_s: 3.0,
        for_s: -1.0,
        every_s: None,
    };
    assert!(link.add_silence(bad).is_err());
    let silence = Silence {
        at_s: 3.0,
        for_s: 2.0,
        every_s: None,
    };
    link.add_silence(silence).unwrap();
    assert_eq!(link.silence_at(at(4000 * MS)), Some(at(5000 * MS)));
    assert_eq!(link.silence_at(at(2500 * MS)), None);
}

#[test]
fn duplicates_and_reordering_reach_the_far_port_as_counted() {
    let cfg = LinkConfig {
        duplicate: 0.2,
        reorder: Some(Reorder {
            share: 0.2,
            delay_ms: 700.0,
        }),
        seed: 8,
        ..LinkConfig::default()
    };
    let mut link = Link::new(&Preset::sik_64k(), &cfg, Slot::A).unwrap();
    // One 2-byte sequence number per air packet (sent every 300 ms, > a TDM round).
    let out = send_every(&mut link, 300 * MS, 500, |k| {
        (k as u16).to_le_bytes().to_vec()
    });
    let seqs: Vec<u16> = out
        .iter()
        .map(|(_, b)| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    let s = link.stats().clone();
    // Nothing lost: every number arrives, the extras are exactly the duplicates.
    let unique: std::collections::BTreeSet<u16> = seqs.iter().copied().collect();
    assert_eq!(unique.len(), 500);
    assert_eq!(seqs.len() as u64, 500 + s.packets_duplicated);
    assert!((60..=140).contains(&s.packets_duplicated), "{s:?}");
    assert!((60..=140).contains(&s.packets_reordered), "{s:?}");
    let overtaken = seqs.windows(2).filter(|w| w[1] < w[0]).count();
    assert!(overtaken >= 60, "{overtaken} out of order");
    // Without the knobs, the same traffic arrives once each, in order.
    let mut plain = Link::new(&Preset::sik_64k(), &LinkConfig::default(), Slot::A).unwrap();
    let out = send_every(&mut plain, 300 * MS, 500, |k| {
        (k as u16).to_le_bytes().to_vec()
    });
    let seqs: Vec<u16> = out
        .iter()
        .map(|(_, b)| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    assert_eq!(seqs, (0..500).collect::<Vec<u16>>());
}

#[test]
fn bit_errors_are_counted_as_the_far_port_sees_them() {
    let cfg = LinkConfig {
        bit_error_rate: 1e-3,
        seed: 2,
        ..LinkConfig::default()
    };
    let mut link = Link::new(&Preset::sik_64k(), &cfg, Slot::A).unwrap();
    let sent: Vec<u8> = (0..200u32).flat_map(|k| [k as u8; 50]).collect();
    let out = send_every(&mut link, 300 * MS, 200, |k| vec![k as u8; 50]);
    let got: Vec<u8> = out.into_iter().flat_map(|(_, b)| b).collect();
    assert_eq!(got.len(), sent.len());
    let flipped: u64 = sent
        .iter()
        .zip(&got)
        .map(|(a, b)| (a ^ b).count_ones() as u64)
        .sum();
    let s = link.stats();
    assert_eq!(flipped, s.bits_flipped);
    // 80,000 bits at 1e-3: 80 expected.
    assert!((45..=120).contains(&flipped), "{flipped}");
    assert!(s.packets_corrupted > 0 && s.packets_corrupted <= flipped);
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]
    /// Whatever the faults and the traffic, every offered byte is dropped, lost,
    /// delivered or still held, at every step (checked inside `send_every`).
    #[test]
    fn every_offered_byte_is_accounted_for(
        seed in 0u64..1000,
        dup in 0.0f64..1.0,
        reorder in 0.0f64..1.0,
        ber in 0.0f64..0.01,
        silence_at in 0.0f64..5.0,
        chunk in 1usize..400,
        lora in proptest::bool::ANY,
    ) {
        let cfg = LinkConfig {
            burst: Some(GilbertElliott::with_mean(0.2, 40.0).unwrap()),
            packet_loss: 0.05,
            duplicate: dup,
            reorder: Some(Reorder { share: reorder, delay_ms: 90.0 }),
            bit_error_rate: ber,
            silences: vec![Silence { at_s: silence_at, for_s: 0.7, every_s: Some(2.0) }],
            seed,
            ..LinkConfig::default()
        };
        let preset = if lora { Preset::lora_sf7() } else { Preset::sik_64k() };
        let mut link = Link::new(&preset, &cfg, Slot::A).unwrap();
        send_every(&mut link, 37 * MS, 200, |k| vec![k as u8; chunk]);
        proptest::prop_assert_eq!(link.queued_bytes(), 0);
    }
}
