//! One SBUS input's link state: decodes its bytes and decides whether the
//! receiver behind it currently has a transmitter.
//!
//! Link loss is the failsafe flag or silence past the timeout; the frame-lost
//! flag alone is normal on a fading link and is not a loss.
//!
//! The silence timeout is the receiver's own: three missed frames at the period
//! measured on this input, plus its jitter and a margin (see
//! [`Link::silence_timeout`]). A receiver whose period is not measured yet gets
//! the configured timeout, which also bounds the measured one, so no receiver
//! is ever dropped later than with the fixed timeout.

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

/// Frames closer than this came in one delivery (a buffering adapter, a
/// repeating line), not one period apart: receivers send at most one frame
/// every 4 ms, and two frames back to back on the 100 kbaud wire are 3 ms apart.
pub const BURST_SPACING: Duration = Duration::from_micros(3_500);

/// Frames a receiver may miss before its silence is a link loss: two in a row
/// happen on healthy links (an adapter that clumps three frames delivers them
/// with the third), and handover within three frames plus one output period is
/// the requirement (issue 24).
pub const MISSED_FRAMES: u64 = 3;

/// Added to every measured timeout: drivers stamp bytes when they read them
/// (an interrupt, a host's read loop), so a frame on time can look up to this
/// late, beyond the jitter the intervals themselves show.
pub const SILENCE_MARGIN: Duration = Duration::from_millis(1);

/// Intervals the period is the median of: enough that a late frame or a
/// two-frame gap does not move it, few enough to follow a receiver switching
/// rate within a fraction of a second.
const PERIOD_SAMPLES: usize = 8;

/// Intervals needed before the period counts as measured: two, so a receiver
/// is timed as its own by the time it comes up (three frames by default). The
/// upper median of two is the larger, and an estimate can only be too long
/// then, which the configured timeout bounds; too short is what would drop a
/// healthy link.
const PERIOD_MIN_SAMPLES: u8 = 2;

/// Jitter is held at its peak and forgets it by 1/64 per interval (about half
/// a second at 7 ms): a receiver that was jittery a moment ago keeps the
/// tolerance it needed, a steady one earns a tighter one back slowly.
const JITTER_DECAY_SHIFT: u32 = 6;

/// Jitter allowed whatever was measured, as a fraction of the period: a
/// healthy 7 ms receiver's frames arrive 6-9 ms apart (issue 24), up to 2 ms
/// late, and the third frame of a two-frame gap (the rig's stutter fault) is as
/// late as any. A third of a period covers that, even after calm intervals
/// have let the measured jitter decay.
const JITTER_FLOOR_DIVISOR: u64 = 3;

/// The silence timeout of a receiver whose period is measured (see
/// [`Link::silence_timeout`]): `burst` frames in its newest delivery, `jitter`
/// the largest distance of its intervals from whole periods. Public so the rig
/// can tell when a stimulus it held was long enough to end a link.
pub fn measured_silence_timeout(
    period: Duration,
    burst: u8,
    jitter: Duration,
    configured: Duration,
) -> Duration {
    let us = |d: Duration| u32::try_from(d.as_micros()).unwrap_or(u32::MAX);
    Duration::from_micros(timeout_us(us(period), burst, us(jitter)).into()).min(configured)
}

/// [`measured_silence_timeout`] in microseconds, before the configured
/// ceiling. 32-bit arithmetic: the M0+ has no divider, and 64-bit division is
/// a library call several times as long.
fn timeout_us(period: u32, burst: u8, jitter: u32) -> u32 {
    timeout_us_within(period, burst, jitter, jitter_bounds(period))
}

/// The jitter a period allows, at least and at most (see [`timeout_us`]).
fn jitter_bounds(period: u32) -> (u32, u32) {
    // A third by multiplication where it is exact enough (never below a
    // third): division is a library call on the M0+.
    let floor = if period < 1 << 16 {
        (period * 21_846) >> 16
    } else {
        period / JITTER_FLOOR_DIVISOR as u32
    };
    (floor, period / 2)
}

/// [`timeout_us`] with the period's [`jitter_bounds`] already worked out (a
/// division by 3 is a library call on the M0+: once per median, not per frame).
fn timeout_us_within(period: u32, burst: u8, jitter: u32, (floor, ceiling): (u32, u32)) -> u32 {
    let held = u32::from(burst.saturating_sub(1));
    let jitter = jitter.clamp(floor, ceiling);
    // Plain multiplication (a checked one takes a 64-bit library call on the
    // M0+): a period longer than a second is no receiver's, and is capped.
    (MISSED_FRAMES as u32 + held) * period.min(1_000_000)
        + jitter.min(1_000_000)
        + SILENCE_MARGIN.as_micros() as u32
}

/// A receiver's frame period, measured from the intervals between its frames.
#[derive(Debug, Clone)]
struct FramePeriod {
    /// The newest intervals, µs, in a ring.
    samples: [u32; PERIOD_SAMPLES],
    /// The same intervals in order (the first `len`): kept sorted as they come
    /// and go, so the median is a read, not a sort per frame.
    sorted: [u32; PERIOD_SAMPLES],
    len: u8,
    next: u8,
    /// Peak distance of an interval from a whole number of periods, µs.
    jitter_us: u32,
    /// The period, once measured: worked out once per frame, since the
    /// engine asks for deadlines many times per output period.
    period_us: Option<u32>,
    /// [`jitter_bounds`] of `period_us`.
    bounds: (u32, u32),
}

impl FramePeriod {
    const fn new() -> Self {
        FramePeriod {
            samples: [0; PERIOD_SAMPLES],
            sorted: [0; PERIOD_SAMPLES],
            len: 0,
            next: 0,
            jitter_us: 0,
            period_us: None,
            bounds: (0, 0),
        }
    }

    fn push(&mut self, interval: Duration) {
        let us = u32::try_from(interval.as_micros()).unwrap_or(u32::MAX);
        let next = usize::from(self.next) % PERIOD_SAMPLES;
        let mut len = usize::from(self.len).min(PERIOD_SAMPLES);
        // Plain loops over at most eight: a sort, or `copy_within`'s memmove,
        // costs several times as much on the M0+.
        if len == PERIOD_SAMPLES {
            // The oldest leaves the ordered copy.
            let old = self.samples[next];
            let mut i = 0;
            while i < len - 1 && self.sorted[i] != old {
                i += 1;
            }
            while i < len - 1 {
                self.sorted[i] = self.sorted[i + 1];
                i += 1;
            }
            len -= 1;
        }
        let mut i = len;
        while i > 0 && self.sorted[i - 1] > us {
            self.sorted[i] = self.sorted[i - 1];
            i -= 1;
        }
        self.sorted[i] = us;
        self.samples[next] = us;
        self.next = ((next + 1) % PERIOD_SAMPLES) as u8;
        self.len = (len + 1) as u8;
        let period = self.median();
        if period != self.period_us {
            self.period_us = period;
            self.bounds = period.map_or((0, 0), jitter_bounds);
        }
        if let Some(period) = self.period_us.filter(|p| *p > 0) {
            // A two-frame gap is two missed frames, not jitter: measure from
            // the nearest whole number of periods (by subtraction: intervals
            // are a few periods at most, and the M0+ has no divider).
            let mut whole = period;
            while us > whole.saturating_add(period / 2) && whole < u32::MAX - period {
                whole += period;
            }
            let deviation = us.abs_diff(whole);
            let decayed = self.jitter_us - (self.jitter_us >> JITTER_DECAY_SHIFT);
            self.jitter_us = decayed.max(deviation);
        }
    }

    /// The upper median of the intervals, once there are enough: one late
    /// frame or one gap cannot move it, bursts never reach it (see
    /// [`BURST_SPACING`]).
    fn median(&self) -> Option<u32> {
        let len = usize::from(self.len).min(PERIOD_SAMPLES);
        (self.len >= PERIOD_MIN_SAMPLES).then(|| self.sorted[len / 2])
    }
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
    last_frame_at: Option<Instant>,
    up_since: Option<Instant>,
    last_byte_at: Option<Instant>,
    /// The line's latest sign of life (a byte, a UART error, bytes lost to a
    /// full queue) plus the measured silence timeout: garbage after the last
    /// frame is a receiver still talking (a damaged stretch, a noisy line), not
    /// one that stopped. Kept as an instant so that the deadlines the engine
    /// asks for many times per output period cost an addition and a minimum.
    quiet_until: Option<Instant>,
    good_run: u8,
    /// Frames in the newest delivery (frames closer than [`BURST_SPACING`]).
    burst: u8,
    period: FramePeriod,
    /// The measured silence timeout before the configured ceiling, µs, worked
    /// out with each frame ([`timeout_us`]).
    timeout_us: Option<u32>,
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
            last_frame_at: None,
            up_since: None,
            last_byte_at: None,
            quiet_until: None,
            good_run: 0,
            burst: 0,
            period: FramePeriod::new(),
            timeout_us: None,
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

    /// The newest valid frame while the link is up, decoded. Up implies the newest frame
    /// was a good one: a failsafe frame takes the link out of `Up` at once.
    pub fn frame(&self) -> Option<SbusRepr> {
        if !self.is_up() {
            return None;
        }
        self.decoder
            .last_frame()
            .and_then(|f| SbusRepr::parse(&f).ok())
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

    /// The line showed at `now` that something is sending, though no byte of
    /// it is usable (a UART error, bytes lost to a full queue): the partial
    /// frame is dropped, and the silence timeout runs from here.
    pub fn handle_line_error(&mut self, now: Instant) {
        self.decoder.abort_frame();
        if self.is_powered() {
            self.heard(now);
        }
    }

    /// The line showed life at `now`.
    fn heard(&mut self, now: Instant) {
        self.quiet_until = self
            .timeout_us
            .map(|us| now + Duration::from_micros(us.into()));
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
            if self.decoder.push_byte(byte) {
                let failsafe = self
                    .decoder
                    .last_frame()
                    .is_some_and(|f| f.flags().failsafe);
                self.handle_frame(now, failsafe, acquire_frames);
            }
        }
        // After the frames: they may have measured the timeout anew.
        self.heard(now);
    }

    fn handle_frame(&mut self, now: Instant, failsafe: bool, acquire_frames: u8) {
        match self.last_frame_at.map(|at| now - at) {
            Some(interval) if interval < BURST_SPACING => {
                self.burst = self.burst.saturating_add(1);
            }
            Some(interval) => {
                self.burst = 1;
                self.period.push(interval);
            }
            // The first frame, or the first after a silence: no interval.
            None => self.burst = 1,
        }
        self.timeout_us = self
            .period
            .period_us
            .map(|p| timeout_us_within(p, self.burst, self.period.jitter_us, self.period.bounds));
        self.last_frame_at = Some(now);
        if failsafe {
            self.good_run = 0;
            self.up_since = None;
            self.state = LinkState::Failsafe;
            return;
        }
        self.good_run = self.good_run.saturating_add(1);
        if self.good_run >= acquire_frames {
            self.up_since.get_or_insert(now);
            self.state = LinkState::Up;
        } else {
            self.state = LinkState::Acquiring;
        }
    }

    /// The receiver's frame period as measured on this input, once measured.
    pub fn frame_period(&self) -> Option<Duration> {
        self.period
            .period_us
            .map(|p| Duration::from_micros(p.into()))
    }

    /// How long this link may stay silent after its last frame: [`MISSED_FRAMES`]
    /// periods, plus the periods a line that delivered several frames at once
    /// may hold back before its next delivery, plus the jitter seen (at least
    /// a third of a period, at most half: beyond that an interval is nearer
    /// another whole number of periods) and [`SILENCE_MARGIN`]: 24.3-25.5 ms
    /// for a 7 ms receiver, 47.7-50 ms for a 14 ms one. `configured` until the period is
    /// measured, and never more than it.
    pub fn silence_timeout(&self, configured: Duration) -> Duration {
        self.timeout_us.map_or(configured, |us| {
            Duration::from_micros(us.into()).min(configured)
        })
    }

    /// When silence would end this link, if it has one to lose; `configured`
    /// as in [`Self::silence_timeout`]. Silence is a quiet line: while bytes
    /// or errors keep coming after the last frame (a burst of garbage, a
    /// damaged stretch), the timeout runs from the latest of them, but never
    /// past `configured` after the last frame, so a receiver sending only
    /// garbage loses the link as it always did.
    pub fn silence_deadline(&self, configured: Duration) -> Option<Instant> {
        match self.state {
            LinkState::Off | LinkState::Silent => None,
            // Life is heard at the last frame's bytes at the latest, so
            // `quiet_until` is never before the last frame plus the timeout.
            _ => self.last_frame_at.map(|at| {
                let ceiling = at + configured;
                self.quiet_until.map_or(ceiling, |quiet| quiet.min(ceiling))
            }),
        }
    }

    /// Applies the silence timeout.
    pub fn handle_timeout(&mut self, now: Instant, configured: Duration) {
        if self.silence_deadline(configured).is_some_and(|d| now >= d) {
            self.state = LinkState::Silent;
            self.good_run = 0;
            self.up_since = None;
            // The interval across a silence is not a period: the next frame
            // starts a new one. The period measured so far is kept, so a
            // receiver coming back is timed as its own at once.
            self.last_frame_at = None;
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
        assert_eq!(link.frame(), Some(zeros));
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
    fn period_ignores_late_frames_bursts_and_silences() {
        let ms = Instant::from_millis;
        let frame = bytes(false, false);
        let mut link = Link::new(true);
        for n in 0..6 {
            link.handle_bytes(ms(7 * n), &frame, 1);
        }
        let period = Some(Duration::from_millis(7));
        assert_eq!(link.frame_period(), period);
        // One late frame, then three frames in one delivery: neither moves it.
        link.handle_bytes(ms(35 + 12), &frame, 1);
        link.handle_bytes(ms(35 + 14), &[frame, frame, frame].concat(), 1);
        assert_eq!(link.frame_period(), period);
        // The delivery held two frames back, so the next may be two periods
        // later than the frame period alone says.
        let burst = link.silence_timeout(T);
        link.handle_bytes(ms(35 + 21), &frame, 1);
        assert!(link.silence_timeout(T) + Duration::from_millis(14) <= burst);
        // Silent, then back: the interval across the silence is not a period.
        link.handle_timeout(ms(500), T);
        assert_eq!(link.state(), LinkState::Silent);
        link.handle_bytes(ms(600), &frame, 1);
        link.handle_bytes(ms(607), &frame, 1);
        assert_eq!(link.frame_period(), period);
        assert!(link.silence_timeout(T) < Duration::from_millis(30));
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
