//! PX4's RC input as it treats an SBUS stream.
//!
//! - Frames: header 0x0F, footer 0x00 or an SBUS2 footer; channels unpacked
//!   bit by bit; raw → µs as `raw * 0.625 + 874`.
//! - RC loss: no frame for `COM_RC_LOSS_T` (0.5 s), or a frame with the
//!   failsafe flag.
//! - Flight mode: the mode channel selects one of six slots; PX4 acts only
//!   when the slot *changes*, which is why MultiRX holding auto-loiter across
//!   a handover keeps a mission flying.

use std::time::Duration;

use crate::clock::Mono;

/// PX4's default `COM_RC_LOSS_T`.
pub const RC_LOSS_TIMEOUT: Duration = Duration::from_millis(500);

/// One frame as the flight controller received it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FcFrame {
    /// When the rig read it.
    pub at: Mono,
    pub channels: [u16; 16],
    pub failsafe: bool,
    pub frame_lost: bool,
}

impl FcFrame {
    /// Channel `ch` (1-based, as pilots count) in µs.
    pub fn us(&self, ch: u8) -> f64 {
        raw_to_us(self.channels[usize::from(ch - 1)])
    }
}

/// PX4's SBUS scaling.
pub fn raw_to_us(raw: u16) -> f64 {
    f64::from(raw) * 0.625 + 874.0
}

/// Flight-mode slot (0..=5) of a mode-channel value, as PX4's six-position
/// mapping over 1000..2000 µs.
pub fn mode_slot(raw: u16) -> u8 {
    let us = raw_to_us(raw).clamp(1000.0, 2000.0);
    (((us - 1000.0) / (1000.0 / 6.0)) as u8).min(5)
}

/// Finds frames in the byte stream the flight controller reads.
#[derive(Debug, Default)]
pub struct SbusStream {
    buf: Vec<u8>,
    /// Bytes skipped looking for a frame.
    pub skipped: u64,
}

impl SbusStream {
    /// Feeds bytes read at `at`; returns the frames they completed.
    pub fn push(&mut self, at: Mono, bytes: &[u8]) -> Vec<FcFrame> {
        self.buf.extend_from_slice(bytes);
        let mut frames = Vec::new();
        loop {
            match self.buf.iter().position(|&b| b == 0x0F) {
                Some(start) => {
                    self.skipped += start as u64;
                    self.buf.drain(..start);
                }
                None => {
                    self.skipped += self.buf.len() as u64;
                    self.buf.clear();
                }
            }
            if self.buf.len() < 25 {
                return frames;
            }
            let footer_ok = matches!(self.buf[24], 0x00 | 0x04 | 0x14 | 0x24 | 0x34);
            if footer_ok && self.buf[23] & 0xF0 == 0 {
                frames.push(unpack(at, &self.buf[..25]));
                self.buf.drain(..25);
            } else {
                self.skipped += 1;
                self.buf.drain(..1);
            }
        }
    }
}

fn unpack(at: Mono, frame: &[u8]) -> FcFrame {
    let mut channels = [0u16; 16];
    for (ch, value) in channels.iter_mut().enumerate() {
        for bit in 0..11 {
            let pos = ch * 11 + bit;
            if frame[1 + pos / 8] & (1 << (pos % 8)) != 0 {
                *value |= 1 << bit;
            }
        }
    }
    FcFrame {
        at,
        channels,
        frame_lost: frame[23] & 0x04 != 0,
        failsafe: frame[23] & 0x08 != 0,
    }
}

/// What PX4 made of a stretch of frames.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RcReport {
    /// Times RC was declared lost.
    pub rc_losses: Vec<Mono>,
    /// Flight-mode slot changes: when, from, to.
    pub mode_changes: Vec<(Mono, u8, u8)>,
    /// Largest interval between frames.
    pub max_gap: Duration,
    pub frames: usize,
}

/// Replays frames through PX4's RC-loss and mode-switch logic.
#[derive(Debug, Clone, Copy)]
pub struct Px4RcInput {
    /// 1-based flight-mode channel (`RC_MAP_FLTMODE`).
    pub mode_channel: u8,
}

impl Px4RcInput {
    /// Judges `frames` (in arrival order) over `from..=until`: gaps before the
    /// first frame and after the last count too.
    pub fn replay(&self, frames: &[FcFrame], from: Mono, until: Mono) -> RcReport {
        let mut report = RcReport::default();
        let mut last = from;
        let mut lost = false;
        let mut slot: Option<u8> = None;
        for f in frames.iter().filter(|f| f.at >= from && f.at <= until) {
            report.frames += 1;
            let gap = f.at.since(last);
            report.max_gap = report.max_gap.max(gap);
            if !lost && (gap > RC_LOSS_TIMEOUT || f.failsafe) {
                lost = true;
                report.rc_losses.push(if f.failsafe {
                    f.at
                } else {
                    last + RC_LOSS_TIMEOUT
                });
            } else if lost && !f.failsafe {
                lost = false;
            }
            let s = mode_slot(f.channels[usize::from(self.mode_channel - 1)]);
            if let Some(prev) = slot
                && prev != s
            {
                report.mode_changes.push((f.at, prev, s));
            }
            slot = Some(s);
            last = f.at;
        }
        let tail = until.since(last);
        report.max_gap = report.max_gap.max(tail);
        if !lost && tail > RC_LOSS_TIMEOUT {
            report.rc_losses.push(last + RC_LOSS_TIMEOUT);
        }
        report
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use multirx_core::wire::SbusRepr;

    fn at(ms: u64) -> Mono {
        Mono::from_secs_f64(100.0 + ms as f64 / 1000.0)
    }

    #[test]
    fn unpacks_like_the_core_packs() {
        // Cross-check: the core's encoder against this independent decoder.
        let mut repr = SbusRepr::default();
        for (i, ch) in repr.channels.iter_mut().enumerate() {
            *ch = (i as u16 * 131 + 7) & 0x7FF;
        }
        repr.flags.failsafe = true;
        let mut stream = SbusStream::default();
        let frames = stream.push(at(0), &repr.to_bytes());
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].channels, repr.channels);
        assert!(frames[0].failsafe && !frames[0].frame_lost);
    }

    #[test]
    fn stream_skips_garbage_and_splits() {
        let bytes = SbusRepr::default().to_bytes();
        let mut stream = SbusStream::default();
        assert!(stream.push(at(0), &[0xFF, 0x0F, 0x01]).is_empty());
        assert!(stream.push(at(1), &bytes[..10]).is_empty());
        assert_eq!(stream.push(at(2), &bytes[10..]).len(), 1);
        assert!(stream.skipped >= 1);
    }

    #[test]
    fn scaling_matches_px4() {
        assert_eq!(raw_to_us(172), 981.5);
        assert_eq!(raw_to_us(1811), 2005.875);
        assert_eq!(mode_slot(172), 0);
        assert_eq!(mode_slot(1811), 5);
        assert_eq!(mode_slot(992), 2);
    }

    #[test]
    fn rc_loss_on_silence_and_failsafe_mode_change_on_slot_change() {
        let frame = |ms: u64, mode: u16, failsafe: bool| {
            let mut channels = [992u16; 16];
            channels[4] = mode;
            FcFrame {
                at: at(ms),
                channels,
                failsafe,
                frame_lost: false,
            }
        };
        let frames = vec![
            frame(0, 1811, false),
            frame(7, 1811, false),
            frame(600, 1811, false), // 593 ms gap: RC lost
            frame(607, 992, false),  // slot change
            frame(614, 992, true),   // failsafe: lost again
        ];
        let report = Px4RcInput { mode_channel: 5 }.replay(&frames, at(0), at(614));
        assert_eq!(report.rc_losses.len(), 2);
        assert_eq!(report.mode_changes, vec![(at(607), 5, 2)]);
        assert_eq!(report.max_gap, at(600).since(at(7)));
    }
}
