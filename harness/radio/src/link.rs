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
use super::faults::{FaultConfig, Faults, Reorder, Silence};
use super::loss::{self, GilbertElliott, LinkBudget, LossModel, REFERENCE_PACKET_BYTES};
use super::preset::{Access, Preset, ms};

/// Per-direction settings: what differs between uplink and downlink.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkConfig {
    /// Link budget (path, antennas, receiver noise) → independent loss.
    pub budget: LinkBudget,
    /// Bursty loss on top, if any: a chain stepped per millisecond of time.
    pub burst: Option<GilbertElliott>,
    /// Share of packets lost independently of their length and of each other
    /// (a fixed packet-loss rate, e.g. 0.1 for the C2 scenarios).
    pub packet_loss: f64,
    /// Probability that each delivered bit is flipped (corruption the radio's
    /// own CRC missed, or a transparent radio with none).
    pub bit_error_rate: f64,
    /// Share of delivered packets handed to the far port twice.
    pub duplicate: f64,
    /// Packets held back so later ones overtake them.
    pub reorder: Option<Reorder>,
    /// Scheduled silences: packets on air during one are lost.
    pub silences: Vec<Silence>,
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

/// A receiver's measurement: see [`Link::receiver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReceiverReading {
    /// Signal level of the packets arriving, dBm.
    pub rssi_dbm: f64,
    /// Noise floor, dBm.
    pub noise_dbm: f64,
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
    /// Air packets handed to the far serial port (duplicates included).
    pub packets_delivered: u64,
    /// Lost packets that fell in a scheduled silence (also in `packets_lost`).
    pub packets_silenced: u64,
    /// Received packets with at least one bit flipped.
    pub packets_corrupted: u64,
    /// Bits flipped in received packets.
    pub bits_flipped: u64,
    /// Received packets handed over a second time.
    pub packets_duplicated: u64,
    /// Bytes in those second copies (also in `bytes_delivered`).
    pub bytes_duplicated: u64,
    /// Received packets held back for later ones to overtake.
    pub packets_reordered: u64,
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
    faults: Faults,
    budget: LinkBudget,
    duty: DutyTracker,
    buffer: VecDeque<u8>,
    last_input: Instant,
    now: Instant,
    gap_until: Instant,
    on_air: Option<OnAir>,
    /// Received packets by delivery time, each with whether it is a second copy.
    in_flight: VecDeque<(Instant, Vec<u8>, bool)>,
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
        check_range("packet_loss", config.packet_loss, 0.0, 1.0, "0..=1")?;
        let faults = config.fault_config();
        faults.validate()?;
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
            loss: LossModel::new(
                config.budget.reference_per(preset),
                config.packet_loss,
                config.burst,
                config.seed,
            ),
            faults: Faults::new(faults, config.seed),
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

    /// Bytes the link holds: buffered, on air, and received but not yet handed
    /// over. With the counters, every offered byte is accounted for:
    /// `bytes_offered = bytes_dropped + bytes_lost + (bytes_delivered −
    /// bytes_duplicated) + queued_bytes()`.
    pub fn queued_bytes(&self) -> usize {
        let received: usize = self
            .in_flight
            .iter()
            .filter(|(_, _, second_copy)| !second_copy)
            .map(|(_, d, _)| d.len())
            .sum();
        self.buffer.len() + self.on_air.as_ref().map_or(0, |a| a.data.len()) + received
    }

    /// Schedules one more silence while the link runs: a test that starts the fault when
    /// the traffic is up, not at a time fixed before the programs started.
    pub fn add_silence(&mut self, silence: Silence) -> Result<(), ConfigError> {
        self.faults.add_silence(silence)
    }

    /// Whether `t` falls inside a scheduled silence, and until when.
    pub fn silence_at(&self, t: Instant) -> Option<Instant> {
        self.faults.silence_end(t)
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

    /// What this direction's receiver measures, as a radio reports it (SiK's `RADIO_STATUS`):
    /// the signal level of arriving packets and the receiver's noise floor.
    ///
    /// The model has no thermal floor of its own: the floor reported is the level a packet
    /// must clear, the sensitivity raised by the receiver's noise (`rx_noise_db`). A real
    /// radio's figure sits lower by the modulation's required SNR, a constant; the rise that
    /// deafens a receiver (the paper's blind drone) is the same dB for dB.
    pub fn receiver(&self) -> ReceiverReading {
        ReceiverReading {
            rssi_dbm: self.budget.received_dbm(&self.preset),
            noise_dbm: self.preset.sensitivity_dbm + self.budget.rx_noise_db,
        }
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
        self.in_flight.front().map(|(t, _, _)| *t)
    }

    /// The next delivery due by the model's time (`now` of the last call that moved it).
    pub(crate) fn pop_delivery(&mut self) -> Option<Vec<u8>> {
        if self.next_delivery()? > self.now {
            return None;
        }
        let (_, data, dup) = self.in_flight.pop_front()?;
        if dup {
            self.stats.bytes_duplicated += data.len() as u64;
        }
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
                let silenced = self.faults.silenced(t, t + airtime);
                // Drawn even when silenced, so a silence does not shift later draws.
                let lost = self.loss.lose(&mut self.rng, t, airtime, ratio) || silenced;
                self.stats.packets_silenced += silenced as u64;
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
                    let mut data = a.data;
                    let fate = self.faults.apply(&mut data);
                    self.stats.bits_flipped += fate.flipped;
                    self.stats.packets_corrupted += (fate.flipped > 0) as u64;
                    let at = (a.end + a.delay).max(self.last_delivery);
                    let at = match fate.held {
                        // Held back: it does not move `last_delivery`, so later packets overtake it.
                        Some(extra) => {
                            self.stats.packets_reordered += 1;
                            at + extra
                        }
                        None => {
                            self.last_delivery = at;
                            at
                        }
                    };
                    if fate.duplicated {
                        self.stats.packets_duplicated += 1;
                        self.schedule(at, data.clone(), false);
                        self.schedule(at, data, true);
                    } else {
                        self.schedule(at, data, false);
                    }
                }
                self.gap_until = a.end + self.gap;
            }
        }
        self.now = self.now.max(t);
    }
}

impl Link {
    /// Queues a received packet for delivery at `at`, after everything due no later.
    fn schedule(&mut self, at: Instant, data: Vec<u8>, second_copy: bool) {
        let i = self.in_flight.partition_point(|(t, _, _)| *t <= at);
        self.in_flight.insert(i, (at, data, second_copy));
    }
}

impl LinkConfig {
    pub(crate) fn fault_config(&self) -> FaultConfig {
        FaultConfig {
            bit_error_rate: self.bit_error_rate,
            duplicate: self.duplicate,
            reorder: self.reorder,
            silences: self.silences.clone(),
        }
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
            // 10 % of the time bad, 30 ms fades (per ms); before: 30-packet bursts.
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
        let seen: std::collections::BTreeSet<u8> =
            out.iter().flat_map(|(_, b)| b.clone()).collect();
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
}
