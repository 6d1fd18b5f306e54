//! One SBUS input's link state: decodes its bytes and decides whether the
//! receiver behind it currently has a transmitter.
//!
//! Link loss is the failsafe flag or silence past the timeout; the frame-lost
//! flag alone is normal on a fading link and is not a loss.

use crate::decoder::SbusDecoder;

/// A partial frame older than this is dead: on the wire the bytes of a frame
/// are ~120 µs apart and frames are ≥ 4 ms apart, so a pause this long inside
/// a frame means bytes were lost. Resynchronising on it (as PX4 does) stops a
/// truncated frame from being glued to the start of the next one, which the
/// header/footer checks alone could occasionally accept.
pub const INTRA_FRAME_GAP: Duration = Duration::from_millis(3);
use crate::time::{Duration, Instant};
use crate::wire::SbusRepr;

/// Whether a byte stamped `at` may join the slice being gathered for
/// [`Link::handle_bytes`], when that slice is fed at its last byte's stamp.
/// `previous` is the stamp the input's previous slice was fed at; before its
/// first, any stamp not after the first byte's (the timer's start, say). The
/// first byte of a slice always starts it; gather the next only while this
/// holds, else feed the slice first. Stamps are a free-running 32-bit
/// microsecond count (the firmware's timer, see [`crate::counter::Counter32`]),
/// compared wrapping: cheaper per byte than [`Instant`]s, and right while they
/// are less than 2^31 µs apart.
///
/// The [`INTRA_FRAME_GAP`] check compares the times of two calls, not of two
/// bytes: a slice stretching [`INTRA_FRAME_GAP`] past the previous call would
/// drop a partial frame that byte-by-byte feeding keeps, and one spanning a
/// pause would hide it. Gathered this way, the decoder keeps and drops exactly
/// what byte-by-byte feeding does, at a fraction of the calls (the firmware
/// feeds what each receive queue holds in one call per loop pass).
pub fn joins_slice(previous: u32, at: u32) -> bool {
    at.wrapping_sub(previous) < INTRA_FRAME_GAP.as_micros() as u32
}

/// What MultiRX knows of an input's link, as reported in status lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LinkState {
    /// Not powered (scan mode powers one receiver at a time).
    Off,
    /// Powered, no frame within the silence timeout.
    Silent,
    /// Sending frames with the failsafe flag: its transmitter is gone.
    Failsafe,
    /// Valid frames, but fewer in a row than needed to trust it.
    Acquiring,
    /// Valid frames in a row: may be given control.
    Up,
}

impl LinkState {
    pub const fn name(self) -> &'static str {
        match self {
            LinkState::Off => "off",
            LinkState::Silent => "silent",
            LinkState::Failsafe => "failsafe",
            LinkState::Acquiring => "acquiring",
            LinkState::Up => "up",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        [
            LinkState::Off,
            LinkState::Silent,
            LinkState::Failsafe,
            LinkState::Acquiring,
            LinkState::Up,
        ]
        .into_iter()
        .find(|s| s.name() == name)
    }
}

/// An SBUS input and its link tracking.
#[derive(Debug, Clone)]
pub struct Link {
    decoder: SbusDecoder,
    state: LinkState,
    last_frame: Option<SbusRepr>,
    last_frame_at: Option<Instant>,
    up_since: Option<Instant>,
    last_byte_at: Option<Instant>,
    good_run: u8,
}

impl Link {
    pub const fn new(powered: bool) -> Self {
        Link {
            decoder: SbusDecoder::new(),
            state: if powered {
                LinkState::Silent
            } else {
                LinkState::Off
            },
            last_frame: None,
            last_frame_at: None,
            up_since: None,
            last_byte_at: None,
            good_run: 0,
        }
    }

    pub fn state(&self) -> LinkState {
        self.state
    }

    pub fn is_up(&self) -> bool {
        self.state == LinkState::Up
    }

    pub fn is_powered(&self) -> bool {
        self.state != LinkState::Off
    }

    /// When the link came up (for choosing among several live receivers).
    pub fn up_since(&self) -> Option<Instant> {
        self.up_since
    }

    /// The newest valid frame while the link is up.
    pub fn frame(&self) -> Option<&SbusRepr> {
        self.last_frame.as_ref().filter(|_| self.is_up())
    }

    pub fn decoder(&self) -> &SbusDecoder {
        &self.decoder
    }

    /// Powers the receiver on or off; off forgets everything it said.
    pub fn set_powered(&mut self, on: bool) {
        if on == self.is_powered() {
            return;
        }
        *self = Link::new(on);
    }

    /// Drops a partial frame: the UART saw a parity, framing or overrun error.
    pub fn abort_frame(&mut self) {
        self.decoder.abort_frame();
    }

    /// Feeds bytes read from the input at `now`.
    pub fn handle_bytes(&mut self, now: Instant, bytes: &[u8], acquire_frames: u8) {
        if !self.is_powered() {
            // An unpowered receiver cannot talk; bytes are line noise.
            return;
        }
        if self.decoder.pending() > 0
            && self
                .last_byte_at
                .is_some_and(|t| now - t >= INTRA_FRAME_GAP)
        {
            self.decoder.abort_frame();
        }
        self.last_byte_at = Some(now);
        for &byte in bytes {
            if let Some(frame) = self.decoder.push(byte) {
                self.handle_frame(now, frame, acquire_frames);
            }
        }
    }

    fn handle_frame(&mut self, now: Instant, frame: SbusRepr, acquire_frames: u8) {
        self.last_frame_at = Some(now);
        if frame.flags.failsafe {
            self.good_run = 0;
            self.up_since = None;
            self.state = LinkState::Failsafe;
            return;
        }
        self.last_frame = Some(frame);
        self.good_run = self.good_run.saturating_add(1);
        if self.good_run >= acquire_frames {
            self.up_since.get_or_insert(now);
            self.state = LinkState::Up;
        } else {
            self.state = LinkState::Acquiring;
        }
    }

    /// When silence would end this link, if it has one to lose.
    pub fn silence_deadline(&self, timeout: Duration) -> Option<Instant> {
        match self.state {
            LinkState::Off | LinkState::Silent => None,
            _ => self.last_frame_at.map(|at| at + timeout),
        }
    }

    /// Applies the silence timeout.
    pub fn handle_timeout(&mut self, now: Instant, timeout: Duration) {
        if self.silence_deadline(timeout).is_some_and(|d| now >= d) {
            self.state = LinkState::Silent;
            self.good_run = 0;
            self.up_since = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Flags;

    const T: Duration = Duration::from_millis(60);

    fn bytes(failsafe: bool, frame_lost: bool) -> [u8; 25] {
        SbusRepr {
            flags: Flags {
                failsafe,
                frame_lost,
                ..Flags::default()
            },
            ..SbusRepr::default()
        }
        .to_bytes()
    }

    #[test]
    fn comes_up_after_acquire_frames() {
        let mut link = Link::new(true);
        link.handle_bytes(Instant::from_millis(0), &bytes(false, false), 3);
        assert_eq!(link.state(), LinkState::Acquiring);
        link.handle_bytes(Instant::from_millis(7), &bytes(false, false), 3);
        link.handle_bytes(Instant::from_millis(14), &bytes(false, false), 3);
        assert_eq!(link.state(), LinkState::Up);
        assert_eq!(link.up_since(), Some(Instant::from_millis(14)));
    }

    #[test]
    fn failsafe_flag_drops_at_once_frame_lost_does_not() {
        let mut link = Link::new(true);
        link.handle_bytes(Instant::ZERO, &bytes(false, false), 1);
        link.handle_bytes(Instant::from_millis(7), &bytes(false, true), 1);
        assert!(link.is_up(), "frame lost alone is not a link loss");
        link.handle_bytes(Instant::from_millis(14), &bytes(true, false), 1);
        assert_eq!(link.state(), LinkState::Failsafe);
        assert!(link.frame().is_none());
    }

    #[test]
    fn silence_drops_after_timeout() {
        let mut link = Link::new(true);
        link.handle_bytes(Instant::from_millis(10), &bytes(false, false), 1);
        assert_eq!(link.silence_deadline(T), Some(Instant::from_millis(70)));
        link.handle_timeout(Instant::from_millis(69), T);
        assert!(link.is_up());
        link.handle_timeout(Instant::from_millis(70), T);
        assert_eq!(link.state(), LinkState::Silent);
        assert_eq!(link.silence_deadline(T), None);
    }

    #[test]
    fn a_pause_inside_a_frame_drops_the_partial_frame() {
        // A frame cut short after 10 bytes, then a frame of zero sticks. Glued
        // together, the first 25 bytes pass every framing check (zeros make a
        // valid flags byte and footer) and would yield a frame that never was.
        let cut = SbusRepr {
            channels: [1500; 16],
            ..SbusRepr::default()
        }
        .to_bytes();
        let zeros = SbusRepr {
            channels: [0; 16],
            ..SbusRepr::default()
        };
        let mut glued = SbusDecoder::new();
        let mut got = Vec::new();
        glued.push_slice(&cut[..10], |f| got.push(f));
        glued.push_slice(&zeros.to_bytes(), |f| got.push(f));
        assert_eq!(got.len(), 1);
        assert_ne!(
            got[0], zeros,
            "the glued candidate is accepted without a gap check"
        );

        // With the 5 ms pause between them seen, only the real frame comes out.
        let mut link = Link::new(true);
        link.handle_bytes(Instant::ZERO, &cut[..10], 1);
        link.handle_bytes(Instant::from_millis(5), &zeros.to_bytes(), 1);
        assert!(link.is_up());
        assert_eq!(link.frame(), Some(&zeros));
    }

    #[test]
    fn abort_frame_recovers_after_a_uart_error() {
        let frame = bytes(false, false);
        let mut link = Link::new(true);
        link.handle_bytes(Instant::ZERO, &frame[..10], 1);
        link.abort_frame();
        link.handle_bytes(Instant::from_micros(100), &frame, 1);
        assert!(link.is_up());
    }

    #[test]
    fn unpowered_input_ignores_bytes() {
        let mut link = Link::new(false);
        link.handle_bytes(Instant::ZERO, &bytes(false, false), 1);
        assert_eq!(link.state(), LinkState::Off);
        link.set_powered(true);
        assert_eq!(link.state(), LinkState::Silent);
    }
}
