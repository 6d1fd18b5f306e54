//! The multiplexer engine: N receiver inputs in, one SBUS stream out.
//!
//! Sans-IO, after quinn-proto: feed it bytes with [`Multiplexer::handle_receiver_bytes`]
//! and [`Multiplexer::handle_ifs_bytes`], call [`Multiplexer::handle_timeout`]
//! whenever `now` reaches [`Multiplexer::poll_timeout`], then drain
//! [`Multiplexer::poll_transmit`] (frames for the flight controller) and
//! [`Multiplexer::poll_event`] (power switching and status). It never reads a
//! clock and never blocks, so the firmware, the emulated device and tests
//! under a virtual clock all run the same decisions.
//!
//! Rules, from the paper and beyond it:
//! - The receiver in control keeps it while its link is up: a pilot whose
//!   transmitter comes on while another is in control gains nothing (scenario A).
//! - When it loses its link (failsafe flag, or silence past the timeout),
//!   **parallel** mode hands over at once to the receiver whose link has been
//!   up longest; **scan** mode powers it off and powers the others one at a
//!   time, listening a window each (the paper's design).
//! - One output frame every period whatever happens; with nobody in control,
//!   neutral sticks with the flight-mode channel at auto-loiter.

mod link;
mod output;

pub use link::{INTRA_FRAME_GAP, Link, LinkState, joins_slice};
pub use output::compose;

use heapless::Deque;

use crate::config::{Config, MAX_RECEIVERS, Mode};
use crate::event::{Event, TimedEvent};
use crate::time::Instant;
use crate::wire::{SbusFrame, SbusRepr};

/// Events buffered between polls; a slow reader loses the oldest.
const EVENT_CAPACITY: usize = 32;

/// Counters for status reports and tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MuxStats {
    /// Frames produced for the flight controller.
    pub frames_out: u32,
    /// Times control moved from one receiver to another or to nobody.
    pub control_changes: u32,
    /// Events dropped because nobody polled them in time.
    pub events_dropped: u32,
    /// Times bytes were lost between an input's UART and the engine, all inputs.
    pub rx_overflows: u32,
}

/// Scan mode while nobody is in control: which receiver we listen to, until when.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Scan {
    rx: u8,
    until: Instant,
}

/// The MultiRX engine; see the [module docs](self).
#[derive(Debug)]
pub struct Multiplexer {
    config: Config,
    links: [Link; MAX_RECEIVERS],
    ifs: Link,
    active: Option<u8>,
    scan: Option<Scan>,
    next_output: Instant,
    pending_output: Option<SbusRepr>,
    events: Deque<TimedEvent, EVENT_CAPACITY>,
    stats: MuxStats,
    /// Overflows per input: receivers, then the IFS.
    overflows: [u32; MAX_RECEIVERS + 1],
}

impl Multiplexer {
    /// Starts the engine at `now`. The configuration must have passed
    /// [`Config::validate`]; the first frame is due at once.
    pub fn new(config: Config, now: Instant) -> Self {
        let mut mux = Multiplexer {
            links: core::array::from_fn(|_| Link::new(false)),
            ifs: Link::new(!config.ifs_channels.is_empty()),
            active: None,
            scan: None,
            next_output: now,
            pending_output: None,
            events: Deque::new(),
            stats: MuxStats::default(),
            overflows: [0; MAX_RECEIVERS + 1],
            config,
        };
        match mux.config.mode {
            Mode::Parallel => {
                for rx in mux.config.receiver_indices() {
                    mux.set_power(now, rx, true);
                }
            }
            Mode::Scan => mux.start_scan(now, 0),
        }
        mux.push_event(now, Event::Active { rx: None });
        mux
    }

    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The receiver in control, if any.
    pub fn active(&self) -> Option<u8> {
        self.active
    }

    /// Whether receiver `rx`'s power switch is on.
    pub fn is_powered(&self, rx: u8) -> bool {
        self.links
            .get(usize::from(rx))
            .is_some_and(|l| l.is_powered())
    }

    /// Link state of receiver `rx`.
    pub fn link(&self, rx: u8) -> &Link {
        &self.links[usize::from(rx)]
    }

    pub fn stats(&self) -> MuxStats {
        self.stats
    }

    /// Bytes received from receiver `rx` at `now`. Indices beyond the
    /// configured receivers are ignored.
    pub fn handle_receiver_bytes(&mut self, now: Instant, rx: u8, bytes: &[u8]) {
        if rx >= self.config.receivers {
            return;
        }
        let link = &mut self.links[usize::from(rx)];
        let before = link.state();
        link.handle_bytes(now, bytes, self.config.acquire_frames);
        let after = link.state();
        if before != after {
            self.push_event(now, Event::Link { rx, state: after });
        }
        self.select(now);
    }

    /// Receiver `rx`'s UART reported a parity, framing or overrun error: the
    /// frame in progress is dropped rather than risk accepting a damaged one.
    pub fn handle_receiver_error(&mut self, rx: u8) {
        if rx < self.config.receivers {
            self.links[usize::from(rx)].abort_frame();
        }
    }

    /// Bytes from receiver `rx` were lost before they reached the engine (the
    /// board's receive queue was full), between the bytes already handed in
    /// and the next: the frame in progress is dropped, as for a UART error,
    /// and the loss is counted ([`MuxStats::rx_overflows`]) and reported
    /// ([`Event::Overflow`]), so it is never silent.
    pub fn handle_receiver_overflow(&mut self, now: Instant, rx: u8) {
        if rx < self.config.receivers {
            self.links[usize::from(rx)].abort_frame();
            self.count_overflow(now, Some(rx));
        }
    }

    /// Bytes from the IFS input were lost; see [`Self::handle_receiver_overflow`].
    pub fn handle_ifs_overflow(&mut self, now: Instant) {
        self.ifs.abort_frame();
        self.count_overflow(now, None);
    }

    fn count_overflow(&mut self, now: Instant, rx: Option<u8>) {
        let slot = &mut self.overflows[rx.map_or(MAX_RECEIVERS, usize::from)];
        *slot = slot.wrapping_add(1);
        let total = *slot;
        self.stats.rx_overflows = self.stats.rx_overflows.wrapping_add(1);
        self.push_event(now, Event::Overflow { rx, total });
    }

    /// The IFS input's UART reported an error; see [`Self::handle_receiver_error`].
    pub fn handle_ifs_error(&mut self) {
        self.ifs.abort_frame();
    }

    /// Bytes from the independent fail-safe system at `now`.
    pub fn handle_ifs_bytes(&mut self, now: Instant, bytes: &[u8]) {
        let before = self.ifs.is_up();
        self.ifs.handle_bytes(now, bytes, 1);
        self.note_ifs(now, before);
    }

    /// Handles every deadline at or before `now`: link silence, scan windows,
    /// and the output frame.
    pub fn handle_timeout(&mut self, now: Instant) {
        let timeout = self.config.silence_timeout;
        for rx in self.config.receiver_indices() {
            let link = &mut self.links[usize::from(rx)];
            let before = link.state();
            link.handle_timeout(now, timeout);
            if link.state() != before {
                let state = link.state();
                self.push_event(now, Event::Link { rx, state });
            }
        }
        let ifs_before = self.ifs.is_up();
        self.ifs.handle_timeout(now, timeout);
        self.note_ifs(now, ifs_before);
        self.select(now);
        if now >= self.next_output {
            self.pending_output = Some(self.output_frame());
            self.stats.frames_out = self.stats.frames_out.wrapping_add(1);
            self.next_output += self.config.frame_period;
            if self.next_output <= now {
                // We were not called for more than a period: keep the cadence
                // from here rather than bursting frames to catch up.
                self.next_output = now + self.config.frame_period;
            }
        }
    }

    /// The next time [`handle_timeout`](Self::handle_timeout) must be called. Always `Some`
    /// (the output never stops); an `Option` like every engine's, so drivers read alike.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let timeout = self.config.silence_timeout;
        let links = self.links[..usize::from(self.config.receivers)]
            .iter()
            .chain(core::iter::once(&self.ifs))
            .filter_map(|l| l.silence_deadline(timeout));
        let scan = self.scan.map(|s| s.until);
        Some(
            links
                .chain(scan)
                .fold(self.next_output, |earliest, t| earliest.min(t)),
        )
    }

    /// The frame due for the flight controller, once per period.
    pub fn poll_transmit(&mut self) -> Option<[u8; SbusFrame::<&[u8]>::LEN]> {
        self.pending_output.take().map(|repr| repr.to_bytes())
    }

    /// The oldest unread event.
    pub fn poll_event(&mut self) -> Option<TimedEvent> {
        self.events.pop_front()
    }

    /// The frame that would go out now.
    pub fn output_frame(&self) -> SbusRepr {
        let active = self
            .active
            .and_then(|rx| self.links[usize::from(rx)].frame().map(|f| (rx, f)));
        let ifs = if self.config.ifs_channels.is_empty() {
            None
        } else {
            self.ifs.frame()
        };
        compose(&self.config, active, ifs)
    }

    /// Decides who is in control; the one place control changes.
    fn select(&mut self, now: Instant) {
        if let Some(rx) = self.active {
            if self.links[usize::from(rx)].is_up() {
                return;
            }
            self.set_active(now, None);
            if self.config.mode == Mode::Scan {
                self.set_power(now, rx, false);
                self.start_scan(now, self.next_receiver(rx));
            }
        }
        match self.config.mode {
            Mode::Parallel => {
                let best = self
                    .config
                    .receiver_indices()
                    .filter_map(|rx| self.links[usize::from(rx)].up_since().map(|t| (t, rx)))
                    .filter(|&(_, rx)| self.links[usize::from(rx)].is_up())
                    .min();
                if let Some((_, rx)) = best {
                    self.set_active(now, Some(rx));
                }
            }
            Mode::Scan => {
                let Some(scan) = self.scan else { return };
                if self.links[usize::from(scan.rx)].is_up() {
                    self.scan = None;
                    self.set_active(now, Some(scan.rx));
                } else if now >= scan.until {
                    self.set_power(now, scan.rx, false);
                    self.start_scan(now, self.next_receiver(scan.rx));
                }
            }
        }
    }

    fn start_scan(&mut self, now: Instant, rx: u8) {
        self.set_power(now, rx, true);
        self.scan = Some(Scan {
            rx,
            until: now + self.config.scan_window,
        });
    }

    fn next_receiver(&self, rx: u8) -> u8 {
        (rx + 1) % self.config.receivers
    }

    fn set_active(&mut self, now: Instant, rx: Option<u8>) {
        if self.active != rx {
            self.active = rx;
            self.stats.control_changes = self.stats.control_changes.wrapping_add(1);
            self.push_event(now, Event::Active { rx });
        }
    }

    fn set_power(&mut self, now: Instant, rx: u8, on: bool) {
        let link = &mut self.links[usize::from(rx)];
        if link.is_powered() != on {
            link.set_powered(on);
            let state = link.state();
            self.push_event(now, Event::Power { rx, on });
            self.push_event(now, Event::Link { rx, state });
        }
    }

    fn note_ifs(&mut self, now: Instant, was_up: bool) {
        let up = self.ifs.is_up() && !self.config.ifs_channels.is_empty();
        if up != was_up {
            self.push_event(now, Event::Ifs { overriding: up });
        }
    }

    fn push_event(&mut self, at: Instant, event: Event) {
        let timed = TimedEvent { at, event };
        if self.events.is_full() {
            self.events.pop_front();
            self.stats.events_dropped = self.stats.events_dropped.wrapping_add(1);
        }
        // Cannot fail: we just made room.
        let _ = self.events.push_back(timed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Mode;
    use crate::time::Instant;

    #[test]
    fn a_receive_queue_overflow_drops_the_frame_and_is_counted_and_reported() {
        // One frame brings a link up, so any frame accepted shows.
        let config = Config {
            acquire_frames: 1,
            ..Config::new(Mode::Parallel, 2)
        };
        let mut mux = Multiplexer::new(config, Instant::ZERO);
        let a = SbusRepr {
            channels: [500; 16],
            ..SbusRepr::default()
        }
        .to_bytes();
        let b = SbusRepr {
            channels: [1500; 16],
            ..SbusRepr::default()
        }
        .to_bytes();
        let t = Instant::from_millis(1);
        // The board lost the end of `a` and the start of `b`: what is left
        // looks like one frame, with no quiet gap to give it away.
        mux.handle_receiver_bytes(t, 1, &a[..10]);
        mux.handle_receiver_overflow(t, 1);
        mux.handle_receiver_bytes(t, 1, &b[10..]);
        assert_eq!(
            mux.link(1).frame(),
            None,
            "a frame spliced across lost bytes was accepted"
        );
        // The next whole frame, after the receiver's quiet gap, is taken.
        mux.handle_receiver_bytes(t + crate::time::Duration::from_millis(5), 1, &b);
        assert_eq!(mux.link(1).frame().map(|f| f.channels[0]), Some(1500));

        mux.handle_receiver_overflow(t, 1);
        mux.handle_ifs_overflow(t);
        // A receiver beyond the config is not counted.
        mux.handle_receiver_overflow(t, 5);
        assert_eq!(mux.stats().rx_overflows, 3);
        let overflows: heapless::Vec<(Option<u8>, u32), 8> =
            core::iter::from_fn(|| mux.poll_event())
                .filter_map(|e| match e.event {
                    Event::Overflow { rx, total } => Some((rx, total)),
                    _ => None,
                })
                .collect();
        assert_eq!(overflows, [(Some(1), 1), (Some(1), 2), (None, 1)]);
    }
}
