//! A virtual-clock bench for the multiplexer: emulated receivers that honour
//! their power switch, boot, and lose their transmitter on cue, driving the
//! engine exactly as the firmware's loop does. Time jumps to the earliest
//! deadline, so tests never sleep and every run is deterministic.

#![allow(dead_code)]

use multirx_core::wire::{Flags, SbusFrame, SbusRepr};
use multirx_core::{Config, Duration, Event, Instant, Multiplexer, TimedEvent};

/// How a receiver reports that its transmitter is gone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Loss {
    /// Keeps sending frames, with the failsafe flag.
    Failsafe,
    /// Stops sending.
    Silent,
}

#[derive(Debug, Clone)]
pub struct SimReceiver {
    pub period: Duration,
    pub boot: Duration,
    pub loss: Loss,
    pub tx_on: bool,
    pub sticks: [u16; 16],
    powered_at: Option<Instant>,
    next_frame: Option<Instant>,
}

impl SimReceiver {
    pub fn new(period_ms: u64, boot_ms: u64, loss: Loss, stick: u16) -> Self {
        SimReceiver {
            period: Duration::from_millis(period_ms),
            boot: Duration::from_millis(boot_ms),
            loss,
            tx_on: false,
            sticks: [stick; 16],
            powered_at: None,
            next_frame: None,
        }
    }

    fn power(&mut self, now: Instant, on: bool) {
        if on && self.powered_at.is_none() {
            self.powered_at = Some(now);
            self.next_frame = Some(now + self.boot);
        } else if !on {
            self.powered_at = None;
            self.next_frame = None;
        }
    }

    /// The frame this receiver sends at `now`, if it sends one.
    fn frame(&self) -> Option<[u8; 25]> {
        if !self.tx_on && self.loss == Loss::Silent {
            return None;
        }
        let repr = SbusRepr {
            channels: self.sticks,
            flags: Flags {
                failsafe: !self.tx_on,
                ..Flags::default()
            },
            ..SbusRepr::default()
        };
        Some(repr.to_bytes())
    }
}

/// One output frame as the flight controller saw it.
#[derive(Debug, Clone, Copy)]
pub struct Output {
    pub at: Instant,
    pub frame: SbusRepr,
    /// Who the engine said was in control when it sent this frame.
    pub active: Option<u8>,
}

/// A scripted change: at `at`, receiver `rx`'s transmitter goes on or off.
#[derive(Debug, Clone, Copy)]
pub struct Cue {
    pub at: Instant,
    pub rx: u8,
    pub tx_on: bool,
}

pub struct Sim {
    pub mux: Multiplexer,
    pub receivers: Vec<SimReceiver>,
    pub now: Instant,
    pub outputs: Vec<Output>,
    pub events: Vec<TimedEvent>,
    /// Control changes where the receiver losing control still had its link up.
    pub idle_takeovers: u32,
}

impl Sim {
    pub fn new(config: Config, receivers: Vec<SimReceiver>) -> Self {
        config.validate().expect("test config is valid");
        assert_eq!(receivers.len(), usize::from(config.receivers));
        let mut sim = Sim {
            mux: Multiplexer::new(config, Instant::ZERO),
            receivers,
            now: Instant::ZERO,
            outputs: Vec::new(),
            events: Vec::new(),
            idle_takeovers: 0,
        };
        sim.drain();
        sim
    }

    /// Runs until `end`, applying `cues` (sorted by time) on the way.
    pub fn run(&mut self, end: Instant, cues: &[Cue]) {
        let mut cues = cues.iter().peekable();
        loop {
            let next_rx = self
                .receivers
                .iter()
                .enumerate()
                .filter_map(|(i, r)| r.next_frame.map(|t| (t, i)))
                .min();
            let next_cue = cues.peek().map(|c| c.at);
            let deadline = self.mux.poll_timeout().expect("the output never stops");
            let mut t = deadline;
            if let Some((rt, _)) = next_rx {
                t = t.min(rt);
            }
            if let Some(ct) = next_cue {
                t = t.min(ct);
            }
            if t > end {
                self.now = end;
                return;
            }
            self.now = t;
            while let Some(cue) = cues.next_if(|c| c.at <= t) {
                self.receivers[usize::from(cue.rx)].tx_on = cue.tx_on;
            }
            for i in 0..self.receivers.len() {
                let r = &mut self.receivers[i];
                if r.next_frame == Some(t) {
                    r.next_frame = Some(t + r.period);
                    if let Some(bytes) = r.frame() {
                        let before = self.mux.active();
                        self.mux.handle_receiver_bytes(t, i as u8, &bytes);
                        self.check_takeover(before);
                        self.drain();
                    }
                }
            }
            if self.mux.poll_timeout().is_some_and(|due| due <= t) {
                let before = self.mux.active();
                self.mux.handle_timeout(t);
                self.check_takeover(before);
                self.drain();
            }
        }
    }

    fn check_takeover(&mut self, before: Option<u8>) {
        if let Some(rx) = before
            && self.mux.active() != before
            && self.mux.link(rx).is_up()
        {
            self.idle_takeovers += 1;
        }
    }

    fn drain(&mut self) {
        while let Some(bytes) = self.mux.poll_transmit() {
            let frame = SbusRepr::parse(&SbusFrame::new_checked(&bytes[..]).unwrap()).unwrap();
            self.outputs.push(Output {
                at: self.now,
                frame,
                active: self.mux.active(),
            });
        }
        while let Some(event) = self.mux.poll_event() {
            if let Event::Power { rx, on } = event.event {
                self.receivers[usize::from(rx)].power(event.at, on);
            }
            self.events.push(event);
        }
    }

    /// First output at or after `from` whose pilot channel reads `value`.
    pub fn first_pilot_value(&self, from: Instant, value: u16) -> Option<Instant> {
        let ch = usize::from(self.mux.config().pilot_channel);
        self.outputs
            .iter()
            .find(|o| o.at >= from && o.frame.channels[ch] == value)
            .map(|o| o.at)
    }

    /// Largest interval between consecutive outputs.
    pub fn max_output_gap(&self) -> Duration {
        self.outputs
            .windows(2)
            .map(|w| w[1].at - w[0].at)
            .max()
            .unwrap_or(Duration::ZERO)
    }
}

pub fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}

pub fn cue(at_ms: u64, rx: u8, tx_on: bool) -> Cue {
    Cue {
        at: ms(at_ms),
        rx,
        tx_on,
    }
}
