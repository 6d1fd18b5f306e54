//! One direction of a radio link as a sans-IO engine.
//!
//! Bytes the sender's serial side offers go into the radio's buffer (what
//! does not fit is dropped and counted); the preset's channel access decides
//! when a packet leaves and how many bytes it carries; the packet is on air
//! for its time on air, then lost or, after latency and jitter, handed to the
//! far side's serial port. Time is an argument: the driver calls
//! [`Link::handle_input`], [`Link::handle_timeout`] at [`Link::poll_timeout`],
//! and drains [`Link::poll_output`]. Internal events run at their own model
//! times even when the driver is late, so a late driver delays delivery to
//! the port, not the model's schedule.

use std::collections::VecDeque;
use timebase::{Duration, Instant};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::duty::{DutyCycle, DutyTracker};
use super::error::{ConfigError, check_range};
use super::loss::{self, GilbertElliott, LinkBudget, LossModel, REFERENCE_PACKET_BYTES};
use super::preset::{Access, Preset, ms};

/// Per-direction settings: what differs between uplink and downlink.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkConfig {
    /// Link budget (path, antennas, receiver noise) → independent loss.
    pub budget: LinkBudget,
    /// Bursty loss on top, if any.
    pub burst: Option<GilbertElliott>,
    /// Fixed delay from the end of a packet on air to its bytes at the far
    /// serial port (radio processing, serial out), ms.
    pub latency_ms: f64,
    /// Extra delay drawn uniformly in [0, jitter_ms] per packet; deliveries
    /// stay in order, as on a serial line.
    pub jitter_ms: f64,
    /// Duty-cycle rule tracked (and, if `enforce`, applied).
    pub duty: DutyCycle,
    /// Seed of this direction's random source (loss and jitter draws).
    pub seed: u64,
}

/// Which TDM slot a direction owns; B's windows start half a round after A's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// Windows at 0, round, 2·round, ...
    A,
    /// Windows half a round later.
    B,
}

/// Counters for the evidence. Packets are air packets: *offered* = formed
/// from the buffer and put on air, *sent* = finished their airtime, *lost* =
/// sent but not received, *delivered* = handed to the far serial port.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Bytes the sender's serial side offered.
    pub bytes_offered: u64,
    /// Bytes dropped because the radio's buffer was full.
    pub bytes_dropped: u64,
    /// Bytes in packets that finished their airtime.
    pub bytes_sent: u64,
    /// Bytes in lost packets.
    pub bytes_lost: u64,
    /// Bytes handed to the far serial port.
    pub bytes_delivered: u64,
    /// Air packets formed and put on air.
    pub packets_offered: u64,
    /// Air packets that finished their airtime.
    pub packets_sent: u64,
    /// Air packets lost.
    pub packets_lost: u64,
    /// Air packets handed to the far serial port.
    pub packets_delivered: u64,
    /// Total time on air.
    pub airtime: Duration,
}

/// One transmission, for a trace (see [`Link::set_trace`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AirPacket {
    /// Start on air.
    pub start: Instant,
    /// Time on air.
    pub airtime: Duration,
    /// Serial bytes carried.
    pub bytes: usize,
    /// Whether the receiver missed it.
    pub lost: bool,
}

/// What the engine does next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Event {
    /// The packet on air ends.
    TxEnd,
    /// A packet of this many bytes starts.
    TxStart(usize),
}

#[derive(Debug, Clone)]
enum Timing {
    Tdm {
        window: Duration,
        round: Duration,
        phase: Duration,
    },
    Burst {
        idle: Duration,
    },
}

#[derive(Debug, Clone)]
struct OnAir {
    end: Instant,
    data: Vec<u8>,
    lost: bool,
    delay: Duration,
}

/// One direction of a radio: sender's buffer, air, receiver's serial port.
#[derive(Debug, Clone)]
pub struct Link {
    preset: Preset,
    timing: Timing,
    gap: Duration,
    latency: Duration,
    jitter: Duration,
    reference_airtime: Duration,
    rng: ChaCha8Rng,
    loss: LossModel,
    budget: LinkBudget,
    duty: DutyTracker,
    buffer: VecDeque<u8>,
    last_input: Instant,
    now: Instant,
    gap_until: Instant,
    on_air: Option<OnAir>,
    in_flight: VecDeque<(Instant, Vec<u8>)>,
    last_delivery: Instant,
    last_start: Option<Instant>,
    stats: LinkStats,
    trace: Option<Vec<AirPacket>>,
}

impl Link {
    /// A direction of `preset` with `config`, in TDM `slot` (ignored by
    /// non-TDM presets). Validates both.
    pub fn new(preset: &Preset, config: &LinkConfig, slot: Slot) -> Result<Link, ConfigError> {
        preset.validate()?;
        config.budget.validate()?;
        if let Some(b) = &config.burst {
            b.validate()?;
        }
        check_range(
            "latency_ms",
            config.latency_ms,
            0.0,
            600_000.0,
            "0..=600000 ms",
        )?;
        check_range(
            "jitter_ms",
            config.jitter_ms,
            0.0,
            600_000.0,
            "0..=600000 ms",
        )?;
        config
            .duty
            .validate(preset.time_on_air(preset.max_payload), preset.max_payload)?;
        let timing = match preset.access {
            Access::Tdm(t) => {
                let (window, silence) = (ms(t.window_ms), ms(t.silence_ms));
                Timing::Tdm {
                    window,
                    round: 2 * (window + silence),
                    phase: match slot {
                        Slot::A => Duration::ZERO,
                        Slot::B => window + silence,
                    },
                }
            }
            Access::Burst(b) => Timing::Burst {
                idle: ms(b.idle_ms),
            },
        };
        Ok(Link {
            timing,
            gap: ms(preset.gap_ms),
            latency: ms(config.latency_ms),
            jitter: ms(config.jitter_ms),
            reference_airtime: preset.time_on_air(REFERENCE_PACKET_BYTES),
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            loss: LossModel::new(config.budget.reference_per(preset), config.burst),
            budget: config.budget,
            duty: DutyTracker::new(config.duty),
            buffer: VecDeque::with_capacity(preset.buffer_bytes),
            last_input: Instant::ZERO,
            now: Instant::ZERO,
            gap_until: Instant::ZERO,
            on_air: None,
            in_flight: VecDeque::new(),
            last_delivery: Instant::ZERO,
            last_start: None,
            stats: LinkStats::default(),
            trace: None,
            preset: preset.clone(),
        })
    }

    /// The sender's serial side offers `bytes` at `now`.
    pub fn handle_input(&mut self, now: Instant, bytes: &[u8]) {
        self.advance(now);
        self.accept(now, bytes);
        self.advance(now);
    }

    /// Runs everything due by `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        self.advance(now);
    }

    /// When the engine next needs [`Link::handle_timeout`] or has output.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let event = self.next_event(Instant::ZERO).map(|(t, _)| t);
        min_opt(event, self.next_delivery())
    }

    /// Bytes of one packet that reached the far serial port by the time of the last
    /// [`Link::handle_input`] or [`Link::handle_timeout`].
    pub fn poll_output(&mut self) -> Option<Vec<u8>> {
        self.pop_delivery()
    }

    /// The preset this direction runs.
    pub fn preset(&self) -> &Preset {
        &self.preset
    }

    /// Counters so far.
    pub fn stats(&self) -> &LinkStats {
        &self.stats
    }

    /// Bytes waiting in the sender's buffer.
    pub fn buffered(&self) -> usize {
        self.buffer.len()
    }

    /// Free share of the sender's buffer, 0..=1 (what SiK reports as `txbuf`).
    pub fn buffer_free_share(&self) -> f64 {
        1.0 - self.buffer.len() as f64 / self.preset.buffer_bytes as f64
    }

    /// Airtime bookkeeping: share of the window at a time, peak share, total.
    pub fn duty(&self) -> &DutyTracker {
        &self.duty
    }

    /// Loss probability of a reference-length packet through the budget alone.
    pub fn reference_per(&self) -> f64 {
        self.budget.reference_per(&self.preset)
    }

    /// Changes the budget mid-run (an attenuation sweep); the burst model keeps its state.
    pub fn set_budget(&mut self, budget: LinkBudget) -> Result<(), ConfigError> {
        budget.validate()?;
        self.budget = budget;
        self.loss
            .set_reference_per(budget.reference_per(&self.preset));
        Ok(())
    }

    /// Starts (or stops and discards) a per-packet trace.
    pub fn set_trace(&mut self, on: bool) {
        self.trace = on.then(Vec::new);
    }

    /// Takes the packets traced so far.
    pub fn take_trace(&mut self) -> Vec<AirPacket> {
        self.trace.as_mut().map(std::mem::take).unwrap_or_default()
    }

    // ---- the engine, also driven by `Radio` ----

    pub(crate) fn accept(&mut self, now: Instant, bytes: &[u8]) {
        let now = now.max(self.now);
        self.now = now;
        if bytes.is_empty() {
            return;
        }
        let room = self.preset.buffer_bytes - self.buffer.len();
        let take = room.min(bytes.len());
        self.buffer.extend(&bytes[..take]);
        self.stats.bytes_offered += bytes.len() as u64;
        self.stats.bytes_dropped += (bytes.len() - take) as u64;
        self.last_input = now;
    }

    /// Runs this direction's events due by `now`, alone on its channel.
    fn advance(&mut self, now: Instant) {
        while let Some((t, event)) = self.next_event(Instant::ZERO) {
            if t > now {
                break;
            }
            self.fire(t, event);
        }
        self.now = self.now.max(now);
    }

    pub(crate) fn set_now(&mut self, now: Instant) {
        self.now = self.now.max(now);
    }

    /// End of the packet on air, if one is.
    pub(crate) fn on_air_until(&self) -> Option<Instant> {
        self.on_air.as_ref().map(|a| a.end)
    }

    pub(crate) fn last_start(&self) -> Option<Instant> {
        self.last_start
    }

    pub(crate) fn next_delivery(&self) -> Option<Instant> {
        self.in_flight.front().map(|(t, _)| *t)
    }

    /// The next delivery due by the model's time (`now` of the last call that moved it).
    pub(crate) fn pop_delivery(&mut self) -> Option<Vec<u8>> {
        if self.next_delivery()? > self.now {
            return None;
        }
        let (_, data) = self.in_flight.pop_front()?;
        self.stats.packets_delivered += 1;
        self.stats.bytes_delivered += data.len() as u64;
        Some(data)
    }

    /// The next internal event, with the channel busy until `busy` (the other
    /// direction of a half-duplex pair).
    pub(crate) fn next_event(&self, busy: Instant) -> Option<(Instant, Event)> {
        if let Some(a) = &self.on_air {
            return Some((a.end, Event::TxEnd));
        }
        self.next_start(busy).map(|(t, n)| (t, Event::TxStart(n)))
    }

    fn next_start(&self, busy: Instant) -> Option<(Instant, usize)> {
        if self.buffer.is_empty() {
            return None;
        }
        let queued = self.buffer.len();
        let cap = queued.min(self.preset.max_payload);
        let mut t = self.now.max(self.gap_until).max(busy);
        // Each round moves `t` strictly later; a handful is the norm.
        for _ in 0..1000 {
            let (start, n) = match self.timing {
                Timing::Burst { idle } => {
                    if queued < self.preset.max_payload {
                        t = t.max(self.last_input + idle);
                    }
                    (t, cap)
                }
                Timing::Tdm {
                    window,
                    round,
                    phase,
                } => {
                    let (ws, we) = tdm_window(t, window, round, phase);
                    let start = t.max(ws);
                    match self.fit(we - start, cap) {
                        0 => {
                            // Validated: a full packet fits an empty window.
                            let (next, _) = tdm_window(we, window, round, phase);
                            (next, self.fit(window, cap))
                        }
                        n => (start, n),
                    }
                }
            };
            let allowed = self
                .duty
                .earliest_start(start, self.preset.time_on_air(n))?;
            if allowed == start {
                return Some((start, n));
            }
            t = allowed;
        }
        None
    }

    /// Most bytes (≤ `cap`) whose packet fits in `room`.
    fn fit(&self, room: Duration, cap: usize) -> usize {
        if cap == 0 || self.preset.time_on_air(1) > room {
            return 0;
        }
        let (mut lo, mut hi) = (1, cap);
        while lo < hi {
            let mid = (lo + hi).div_ceil(2);
            if self.preset.time_on_air(mid) <= room {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        lo
    }

    pub(crate) fn fire(&mut self, t: Instant, event: Event) {
        match event {
            Event::TxStart(n) => {
                debug_assert!(self.on_air.is_none());
                let data: Vec<u8> = self.buffer.drain(..n).collect();
                let airtime = self.preset.time_on_air(n);
                let ratio = airtime.as_secs_f64() / self.reference_airtime.as_secs_f64();
                let lost = self.loss.lose(&mut self.rng, ratio);
                let delay = self.latency + loss::jitter(&mut self.rng, self.jitter);
                self.duty.record(t, airtime);
                self.stats.packets_offered += 1;
                self.stats.airtime += airtime;
                if let Some(trace) = &mut self.trace {
                    trace.push(AirPacket {
                        start: t,
                        airtime,
                        bytes: n,
                        lost,
                    });
                }
                self.on_air = Some(OnAir {
                    end: t + airtime,
                    data,
                    lost,
                    delay,
                });
                self.last_start = Some(t);
            }
            Event::TxEnd => {
                let Some(a) = self.on_air.take() else {
                    return;
                };
                self.stats.packets_sent += 1;
                self.stats.bytes_sent += a.data.len() as u64;
                if a.lost {
                    self.stats.packets_lost += 1;
                    self.stats.bytes_lost += a.data.len() as u64;
                } else {
                    let at = (a.end + a.delay).max(self.last_delivery);
                    self.last_delivery = at;
                    self.in_flight.push_back((at, a.data));
                }
                self.gap_until = a.end + self.gap;
            }
        }
        self.now = self.now.max(t);
    }
}

/// The own TDM window containing `t`, or the next one.
fn tdm_window(
    t: Instant,
    window: Duration,
    round: Duration,
    phase: Duration,
) -> (Instant, Instant) {
    let phase = Instant::ZERO + phase;
    if t < phase {
        return (phase, phase + window);
    }
    let rel = (t - phase).as_micros();
    let k = rel / round.as_micros();
    let start = phase + Duration::from_micros(k * round.as_micros());
    if t < start + window {
        (start, start + window)
    } else {
        (start + round, start + round + window)
    }
}

pub(crate) fn min_opt(a: Option<Instant>, b: Option<Instant>) -> Option<Instant> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

#[cfg(test)]
mod tests {
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
}
