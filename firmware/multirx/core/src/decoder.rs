//! Byte-stream decoder: finds SBUS frames in whatever a UART delivers.
//!
//! SBUS has no checksum and its header byte 0x0F also occurs inside channel
//! data, so after garbage or a partial frame the decoder slides to the next
//! 0x0F and accepts a candidate only when header, reserved flag bits and footer
//! all check out. A receiver that is powered on mid-frame, a UART overrun or a
//! noisy line therefore costs at most the frames it actually damaged.

use crate::wire::{SbusFrame, SbusRepr};

const LEN: usize = SbusFrame::<&[u8]>::LEN;

/// Counters a decoder keeps, for status reports and tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DecoderStats {
    /// Well-formed frames returned.
    pub frames: u32,
    /// Bytes dropped while looking for a frame start.
    pub discarded_bytes: u32,
    /// Candidate frames rejected for bad framing.
    pub rejected_frames: u32,
}

/// Incremental SBUS decoder; see the [module docs](self).
///
/// Two buffers take turns: the frame in progress fills one while the other keeps the
/// last valid frame, readable as a view ([`SbusDecoder::last_frame`]) until the next one
/// completes. Nothing is copied or decoded per frame: on the Cortex-M0+ the copy alone
/// was a byte-wise `memcpy` of a fifth of a frame's cost, and the engine decodes channels
/// only for the frame it sends out.
#[derive(Debug, Clone)]
pub struct SbusDecoder {
    bufs: [[u8; LEN]; 2],
    /// The buffer being filled; the other holds the last valid frame once `has_last`.
    cur: usize,
    len: usize,
    has_last: bool,
    stats: DecoderStats,
}

impl Default for SbusDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl SbusDecoder {
    pub const fn new() -> Self {
        SbusDecoder {
            bufs: [[0; LEN]; 2],
            cur: 0,
            len: 0,
            has_last: false,
            stats: DecoderStats {
                frames: 0,
                discarded_bytes: 0,
                rejected_frames: 0,
            },
        }
    }

    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Bytes of a frame started but not finished.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Drops a partial frame, e.g. after a UART parity, framing or overrun error.
    pub fn abort_frame(&mut self) {
        self.stats.discarded_bytes += self.len as u32;
        self.len = 0;
    }

    /// Feeds one byte; true when it completes a valid frame, which is then
    /// [`SbusDecoder::last_frame`].
    pub fn push_byte(&mut self, byte: u8) -> bool {
        if self.len == 0 && byte != crate::wire::sbus::HEADER {
            self.stats.discarded_bytes += 1;
            return false;
        }
        let buf = &mut self.bufs[self.cur];
        buf[self.len] = byte;
        self.len += 1;
        if self.len < LEN {
            return false;
        }
        if SbusFrame::new_unchecked(&buf[..]).check_framing().is_ok() {
            self.len = 0;
            self.cur ^= 1;
            self.has_last = true;
            self.stats.frames += 1;
            true
        } else {
            self.stats.rejected_frames += 1;
            self.resync();
            false
        }
    }

    /// The last valid frame, if any: a view, checked (header, reserved flag bits, footer).
    pub fn last_frame(&self) -> Option<SbusFrame<&[u8]>> {
        self.has_last
            .then(|| SbusFrame::new_unchecked(&self.bufs[self.cur ^ 1][..]))
    }

    /// Feeds one byte; returns the frame decoded when this byte completes a valid one.
    pub fn push(&mut self, byte: u8) -> Option<SbusRepr> {
        if !self.push_byte(byte) {
            return None;
        }
        self.last_frame().and_then(|f| SbusRepr::parse(&f).ok())
    }

    /// Feeds many bytes, calling `on_frame` for each complete frame in order.
    pub fn push_slice(&mut self, bytes: &[u8], mut on_frame: impl FnMut(SbusRepr)) {
        for &byte in bytes {
            if let Some(frame) = self.push(byte) {
                on_frame(frame);
            }
        }
    }

    /// Restarts at the next header byte after the rejected candidate's first byte.
    fn resync(&mut self) {
        let buf = &mut self.bufs[self.cur];
        let next = buf[1..self.len]
            .iter()
            .position(|&b| b == crate::wire::sbus::HEADER)
            .map(|p| p + 1)
            .unwrap_or(self.len);
        buf.copy_within(next..self.len, 0);
        self.len -= next;
        self.stats.discarded_bytes += next as u32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Flags;

    fn frame(seed: u16) -> SbusRepr {
        let mut repr = SbusRepr::default();
        for (i, ch) in repr.channels.iter_mut().enumerate() {
            *ch = (seed.wrapping_mul(131).wrapping_add(i as u16 * 97)) & 0x7FF;
        }
        repr.flags = Flags::from_byte((seed % 16) as u8);
        repr
    }

    fn decode_all(bytes: &[u8]) -> (Vec<SbusRepr>, DecoderStats) {
        let mut decoder = SbusDecoder::new();
        let mut frames = Vec::new();
        decoder.push_slice(bytes, |f| frames.push(f));
        (frames, decoder.stats())
    }

    #[test]
    fn back_to_back_frames() {
        let mut bytes = [0u8; 75];
        for k in 0..3 {
            bytes[k * 25..(k + 1) * 25].copy_from_slice(&frame(k as u16).to_bytes());
        }
        let (frames, stats) = decode_all(&bytes);
        assert_eq!(frames.len(), 3);
        for (k, got) in frames.iter().enumerate() {
            assert_eq!(*got, frame(k as u16));
        }
        assert_eq!(stats.discarded_bytes, 0);
    }

    #[test]
    fn garbage_before_between_and_after_frames_is_skipped() {
        let garbage = [0x0F, 0x0F, 0x00, 0xFF, 0x0F, 0x12];
        let mut bytes = [0u8; 6 + 25 + 6 + 25 + 6];
        let mut at = 0;
        for chunk in [
            &garbage[..],
            &frame(1).to_bytes()[..],
            &garbage[..],
            &frame(2).to_bytes()[..],
            &garbage[..],
        ] {
            bytes[at..at + chunk.len()].copy_from_slice(chunk);
            at += chunk.len();
        }
        let (frames, _) = decode_all(&bytes);
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0], frame(1));
        assert_eq!(frames[1], frame(2));
    }

    #[test]
    fn truncated_frame_followed_by_full_frame() {
        let first = frame(5).to_bytes();
        let second = frame(6).to_bytes();
        let mut bytes = [0u8; 12 + 25];
        bytes[..12].copy_from_slice(&first[..12]);
        bytes[12..].copy_from_slice(&second);
        let (frames, _) = decode_all(&bytes);
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0], frame(6));
    }

    #[test]
    fn abort_frame_drops_partial() {
        let bytes = frame(3).to_bytes();
        let mut decoder = SbusDecoder::new();
        for &b in &bytes[..10] {
            assert!(decoder.push(b).is_none());
        }
        decoder.abort_frame();
        assert_eq!(decoder.pending(), 0);
        let mut got = None;
        decoder.push_slice(&bytes, |f| got = Some(f));
        assert_eq!(got, Some(frame(3)));
    }

    #[test]
    fn the_last_valid_frame_survives_partial_and_rejected_frames() {
        let good = frame(7).to_bytes();
        let mut bad = frame(8).to_bytes();
        bad[24] = 0x55; // no footer SBUS knows
        let mut decoder = SbusDecoder::new();
        assert!(decoder.last_frame().is_none());
        let completed: Vec<bool> = good.iter().map(|&b| decoder.push_byte(b)).collect();
        assert_eq!(completed.iter().filter(|&&c| c).count(), 1);
        assert!(completed[24]);
        let last = |d: &SbusDecoder| d.last_frame().map(|f| SbusRepr::parse(&f).unwrap());
        assert_eq!(last(&decoder), Some(frame(7)));
        for &b in &bad {
            assert!(!decoder.push_byte(b));
        }
        assert_eq!(
            last(&decoder),
            Some(frame(7)),
            "a rejected candidate replaced it"
        );
        let next = frame(9).to_bytes();
        for &b in &next[..24] {
            decoder.push_byte(b);
        }
        assert_eq!(
            last(&decoder),
            Some(frame(7)),
            "a partial frame replaced it"
        );
        assert!(decoder.push_byte(next[24]));
        assert_eq!(last(&decoder), Some(frame(9)));
    }
}
