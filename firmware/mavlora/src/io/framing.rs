//! Framing at the point where bytes enter, one reader per source: only whole frames cross
//! into the main loop, so one ground station's partial frame can never hold another's (or
//! its own next) frames.
//!
//! On a datagram transport a frame never spans datagrams: whatever partial frame is left at
//! a datagram's end is dropped there and counted ([`FrameReader::flush_partial`]). Were all
//! datagrams to share one stream reader, 10 bytes starting `FD FF` (a frame announcing 255
//! payload bytes) would hold the next command until later datagrams filled that frame.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::wire::FrameReader;

/// What a framer has seen, readable from any thread.
#[derive(Debug, Default)]
pub struct FramingCounters {
    /// Datagrams (or stream chunks) framed.
    pub chunks: AtomicU64,
    /// Whole frames passed on.
    pub frames: AtomicU64,
    /// Partial frames dropped at a datagram's end or after an idle gap.
    pub partials_dropped: AtomicU64,
    /// Bytes that were no part of any frame.
    pub garbage_bytes: AtomicU64,
}

impl FramingCounters {
    /// `(frames, partials_dropped, garbage_bytes)` now.
    pub fn snapshot(&self) -> (u64, u64, u64) {
        (
            self.frames.load(Ordering::Relaxed),
            self.partials_dropped.load(Ordering::Relaxed),
            self.garbage_bytes.load(Ordering::Relaxed),
        )
    }
}

/// Splits datagrams into whole frames.
#[derive(Debug, Default)]
pub struct DatagramFramer {
    reader: FrameReader,
}

impl DatagramFramer {
    /// Calls `each` with every whole frame of `datagram`, in order; a partial frame at its end
    /// is dropped and counted.
    pub fn frames(
        &mut self,
        datagram: &[u8],
        counters: &FramingCounters,
        mut each: impl FnMut(Vec<u8>),
    ) {
        self.reader.push(datagram);
        let mut frames = 0;
        loop {
            while let Some(rx) = self.reader.next_frame() {
                frames += 1;
                each(rx.frame.into_inner());
            }
            if !self.reader.flush_partial() {
                break;
            }
        }
        let s = self.reader.stats();
        counters.chunks.fetch_add(1, Ordering::Relaxed);
        counters.frames.fetch_add(frames, Ordering::Relaxed);
        counters
            .partials_dropped
            .store(s.partials_dropped, Ordering::Relaxed);
        counters
            .garbage_bytes
            .store(s.garbage_bytes, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::frame;
    use crate::wire::ids::{COMMAND_LONG, HEARTBEAT};

    fn framed(f: &mut DatagramFramer, c: &FramingCounters, d: &[u8]) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        f.frames(d, c, |b| out.push(b));
        out
    }

    #[test]
    fn a_partial_frame_at_a_datagrams_end_never_holds_the_next_datagram() {
        let (mut f, c) = (DatagramFramer::default(), FramingCounters::default());
        let cmd = frame(COMMAND_LONG, 255, 190, 0);
        // 10 bytes starting FD FF: a frame announcing 255 payload bytes, never completed.
        let stub = [0xFD, 0xFF, 0, 0, 0, 255, 190, 0x4C, 0, 0];
        assert!(framed(&mut f, &c, &stub).is_empty());
        assert_eq!(
            framed(&mut f, &c, cmd.as_bytes()),
            [cmd.as_bytes().to_vec()]
        );
        assert_eq!(c.snapshot(), (1, 1, 10));
    }

    #[test]
    fn whole_frames_before_and_after_a_partial_in_one_datagram_pass() {
        let (mut f, c) = (DatagramFramer::default(), FramingCounters::default());
        let hb = frame(HEARTBEAT, 255, 190, 0);
        let cmd = frame(COMMAND_LONG, 255, 190, 1);
        let datagram = [hb.as_bytes(), cmd.as_bytes(), &cmd.as_bytes()[..7]].concat();
        assert_eq!(
            framed(&mut f, &c, &datagram),
            [hb.as_bytes().to_vec(), cmd.as_bytes().to_vec()]
        );
        assert_eq!(c.snapshot(), (2, 1, 7));
    }
}
