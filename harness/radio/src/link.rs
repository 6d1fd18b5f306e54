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

    /// The link budget in force.
    pub fn budget(&self) -> &LinkBudget {
        &self.budget
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
mod tests;
