//! Two SiK radios around one [`Radio`] model: what each host's serial port sees.
//!
//! The caller owns the [`Radio`] and runs it as before; this layer sits on both serial
//! sides. Host bytes go through [`SikPair::handle_host_input`] (command mode keeps them
//! from the air), the model's deliveries through [`SikPair::handle_air_output`] (radios
//! that do not hear each other get nothing), and each port is written from
//! [`SikPair::poll_host_output`]. `RT` commands travel as the firmware's command packets
//! do, outside the model's byte stream: one TDM round each way, delivered only when the
//! radios hear each other and the model's link is up both ways at the time they leave.
//! A side without a radio ([`None`]) is a plain wire, as the emulator has always been.

use timebase::{Duration, Instant};

use super::radio::{REMOTE_ANSWER_MAX, SikRadio};
use super::status::StatusInputs;
use crate::preset::ms;
use crate::{Access, Direction, Preset, Radio};

/// A side of the pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    /// The drone's radio: its sends are the downlink.
    Air,
    /// The ground's radio: its sends are the uplink.
    Ground,
}

impl End {
    fn index(self) -> usize {
        match self {
            End::Air => 0,
            End::Ground => 1,
        }
    }

    fn of(i: usize) -> End {
        if i == 0 { End::Air } else { End::Ground }
    }

    /// The direction this side transmits on.
    pub fn sends(self) -> Direction {
        match self {
            End::Air => Direction::Downlink,
            End::Ground => Direction::Uplink,
        }
    }
}

#[derive(Debug, Clone)]
enum Flight {
    Command { to: usize, line: String },
    Answer { to: usize, bytes: Vec<u8> },
}

/// SiK firmware on either or both sides of a [`Radio`].
#[derive(Debug, Clone)]
pub struct SikPair {
    base: Preset,
    sides: [Option<SikRadio>; 2],
    /// Host output of a side without a radio.
    wire: [Vec<u8>; 2],
    flights: Vec<(Instant, Flight)>,
    applied: [Preset; 2],
    dropped: [u64; 2],
}

impl SikPair {
    /// `air` and `ground` radios (or plain wires) on a radio model of preset `base`.
    pub fn new(base: &Preset, air: Option<SikRadio>, ground: Option<SikRadio>) -> SikPair {
        SikPair {
            base: base.clone(),
            sides: [air, ground],
            wire: [Vec::new(), Vec::new()],
            flights: Vec::new(),
            applied: [base.clone(), base.clone()],
            dropped: [0; 2],
        }
    }

    /// One side's radio, if it has one.
    pub fn radio(&self, end: End) -> Option<&SikRadio> {
        self.sides[end.index()].as_ref()
    }

    /// Bytes delivered towards `end` and dropped because the radios do not hear each
    /// other or `end` was in command mode.
    pub fn dropped(&self, end: End) -> u64 {
        self.dropped[end.index()]
    }

    /// Whether the two radios decode each other (a plain wire hears anything).
    pub fn paired(&self) -> bool {
        match &self.sides {
            [Some(a), Some(b)] => a.settings().hears(&b.settings()),
            _ => true,
        }
    }

    /// Host bytes from `end` at `now`; returns what the radio transmits (to feed the
    /// model with [`Radio::handle_input`] from `end.sends()`).
    pub fn handle_host_input(
        &mut self,
        now: Instant,
        end: End,
        bytes: &[u8],
        radio: &Radio,
    ) -> Vec<u8> {
        let i = end.index();
        let Some(side) = &mut self.sides[i] else {
            return bytes.to_vec();
        };
        let mut to_air = Vec::new();
        side.handle_host_input(now, bytes, &mut to_air);
        self.after(now, radio);
        to_air
    }

    /// Bytes the model delivered to `end`'s radio.
    pub fn handle_air_output(&mut self, end: End, bytes: &[u8]) {
        let i = end.index();
        if !self.paired() {
            self.dropped[i] += bytes.len() as u64;
            return;
        }
        match &mut self.sides[i] {
            Some(side) => {
                if side.in_command_mode() {
                    self.dropped[i] += bytes.len() as u64;
                }
                side.handle_air_data(bytes);
            }
            None => self.wire[i].extend_from_slice(bytes),
        }
    }

    /// Runs guard timers, command packets and reports due by `now`.
    pub fn handle_timeout(&mut self, now: Instant, radio: &Radio) {
        for side in self.sides.iter_mut().flatten() {
            side.handle_timeout(now);
        }
        self.after(now, radio);
    }

    /// When [`SikPair::handle_timeout`] is next needed.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let timers = self
            .sides
            .iter()
            .flatten()
            .filter_map(SikRadio::poll_timeout);
        timers.chain(self.flights.iter().map(|(t, _)| *t)).min()
    }

    /// Bytes for `end`'s host port, if any.
    pub fn poll_host_output(&mut self, end: End) -> Option<Vec<u8>> {
        let i = end.index();
        let out = match &mut self.sides[i] {
            Some(side) => side.take_host_output(),
            None => std::mem::take(&mut self.wire[i]),
        };
        (!out.is_empty()).then_some(out)
    }

    /// The presets the two directions should run with, `[downlink, uplink]`, when the
    /// radios' settings changed them since the last call (the caller rebuilds its model).
    pub fn take_presets(&mut self) -> Option<[Preset; 2]> {
        let mut changed = false;
        for (i, side) in self.sides.iter_mut().enumerate() {
            let Some(side) = side else { continue };
            if side.take_changed() {
                let preset = side.settings().preset(&self.base);
                if preset != self.applied[i] {
                    self.applied[i] = preset;
                    changed = true;
                }
            }
        }
        changed.then(|| self.applied.clone())
    }

    /// Remote commands out, command packets in, reports due.
    fn after(&mut self, now: Instant, radio: &Radio) {
        let one_way = one_way(radio);
        for i in 0..2 {
            while let Some(line) = self.sides[i]
                .as_mut()
                .and_then(SikRadio::poll_remote_command)
            {
                if self.reachable(now, radio) {
                    self.flights
                        .push((now + one_way, Flight::Command { to: 1 - i, line }));
                }
            }
        }
        self.flights.sort_by_key(|(t, _)| *t);
        while self.flights.first().is_some_and(|(t, _)| *t <= now) {
            let (t, flight) = self.flights.remove(0);
            match flight {
                Flight::Command { to, line } => {
                    let reachable = self.reachable(t, radio);
                    let Some(far) = &mut self.sides[to] else {
                        continue;
                    };
                    let answer = far.execute_remote(&line, t);
                    // The far radio may have rebooted into settings that no longer pair.
                    if !answer.is_empty() && reachable && self.paired() {
                        debug_assert!(answer.len() <= REMOTE_ANSWER_MAX);
                        let back = Flight::Answer {
                            to: 1 - to,
                            bytes: answer,
                        };
                        let i = self.flights.partition_point(|(at, _)| *at <= t + one_way);
                        self.flights.insert(i, (t + one_way, back));
                    }
                }
                Flight::Answer { to, bytes } => {
                    if let Some(side) = &mut self.sides[to] {
                        side.handle_remote_answer(&bytes);
                    }
                }
            }
        }
        for i in 0..2 {
            let end = End::of(i);
            let Some(side) = &mut self.sides[i] else {
                continue;
            };
            if side.report_due() {
                let out = radio.link(end.sends());
                let inbound = radio.link(end.sends().reverse());
                side.send_report(&StatusInputs {
                    local: inbound.receiver(),
                    remote: out.receiver(),
                    tx_free_share: out.buffer_free_share(),
                });
            }
        }
    }

    /// Whether a command packet gets through now: two radios that hear each other, a
    /// link not silenced and not past its edge either way.
    fn reachable(&self, now: Instant, radio: &Radio) -> bool {
        let both = self.sides.iter().all(Option::is_some);
        both && self.paired()
            && [Direction::Uplink, Direction::Downlink]
                .into_iter()
                .all(|d| {
                    let link = radio.link(d);
                    link.silence_at(now).is_none() && link.reference_per() < 0.5
                })
    }
}

/// A command packet's trip: a full TDM round (the sender waits for its window), or one
/// packet's airtime on a channel taken on demand.
fn one_way(radio: &Radio) -> Duration {
    let preset = radio.link(Direction::Uplink).preset();
    match preset.access {
        Access::Tdm(t) => ms(2.0 * (t.window_ms + t.silence_ms)),
        Access::Burst(_) => preset.time_on_air(REMOTE_ANSWER_MAX.min(preset.max_payload)),
    }
}
