//! Counters the stream reader keeps: what the link-quality message reports.

use std::collections::BTreeMap;

/// One MAVLink stream: a sender's (system id, component id). Sequence numbers are per stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct StreamId {
    /// Sender's system id.
    pub system: u8,
    /// Sender's component id.
    pub component: u8,
}

/// Counters for one stream.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StreamCounters {
    /// Frames accepted (checked or forwarded unchecked).
    pub received: u64,
    /// Frames missing, from sequence gaps (pymavlink's rule: `(seq - expected) mod 256`, so a
    /// duplicate or reordered frame counts as 255 lost, as in MAVProxy's link statistics),
    /// except a restart (see [`StreamCounters::restarts`]).
    pub lost: u64,
    /// Times the stream's numbering started again: a gap landing at sequence 0, or the first
    /// gap after its sender said it restarted ([`ReaderStats::expect_restart`]). A restarted
    /// bridge or autopilot numbers from 0 again (and its first frame may be lost): that is
    /// not up to 255 frames lost. A real burst of loss that happens to end at 0 goes
    /// uncounted: 1 burst in 256.
    pub restarts: u64,
    /// Frames whose header named this stream but whose checksum failed. Counted only once the
    /// stream has been seen in a good frame, so garbage cannot create streams (nor can a
    /// frame of an unknown id, whose checksum cannot be checked).
    pub bad_crc: u64,
    last_sequence: Option<u8>,
    /// The sender said it restarted: the next gap is its new numbering.
    restart_expected: bool,
}

/// Streams a [`ReaderStats`] keeps counters for at most; frames of more senders count in the
/// totals only. A MAVLink network has a handful of components; this bounds what a sender
/// that makes up ids costs.
pub const MAX_STREAMS: usize = 1024;

/// Counters for everything a [`FrameReader`](super::FrameReader) has read.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ReaderStats {
    /// Frames accepted with a verified checksum.
    pub frames_checked: u64,
    /// Frames of unknown message ids accepted without a checksum check.
    pub frames_unchecked: u64,
    /// Candidate frames of known ids whose checksum failed, all streams.
    pub bad_crc: u64,
    /// Frames missing from sequence gaps, all streams.
    pub lost: u64,
    /// Stream restarts, all streams (see [`StreamCounters::restarts`]).
    pub restarts: u64,
    /// Bytes discarded while resynchronising (not part of any accepted frame).
    pub garbage_bytes: u64,
    /// Partial frames given up by [`FrameReader::flush_partial`](super::FrameReader::flush_partial)
    /// (their bytes are in `garbage_bytes`).
    pub partials_dropped: u64,
    streams: BTreeMap<StreamId, StreamCounters>,
}

impl ReaderStats {
    /// Counters of one stream, if it has sent a good frame.
    pub fn stream(&self, id: StreamId) -> Option<&StreamCounters> {
        self.streams.get(&id)
    }

    /// All streams seen, in (system, component) order.
    pub fn streams(&self) -> impl Iterator<Item = (StreamId, &StreamCounters)> {
        self.streams.iter().map(|(id, c)| (*id, c))
    }

    /// Frames accepted, checked or not.
    pub fn frames(&self) -> u64 {
        self.frames_checked + self.frames_unchecked
    }

    pub(crate) fn record_frame(&mut self, id: StreamId, sequence: u8, checked: bool) {
        if checked {
            self.frames_checked += 1;
        } else {
            self.frames_unchecked += 1;
        }
        // Only a checked frame opens a stream, and only up to `MAX_STREAMS`: a frame of an
        // unknown id passes unchecked, so noise on a serial line (an 0xFD, then any id) opened
        // a stream per random (system, component), up to 65,536 of ~60 bytes: the bridge's
        // flight-controller port flooded with garbage grew it past 8 MB of RSS.
        let opens = checked && self.streams.len() < MAX_STREAMS;
        if !opens && !self.streams.contains_key(&id) {
            return;
        }
        let stream = self.streams.entry(id).or_default();
        stream.received += 1;
        if let Some(last) = stream.last_sequence {
            let gap = u64::from(sequence.wrapping_sub(last.wrapping_add(1)));
            if gap > 0 {
                tracing::debug!(
                    ?id,
                    last,
                    sequence,
                    expected = stream.restart_expected,
                    "sequence gap"
                );
            }
            if gap > 0 && (sequence == 0 || stream.restart_expected) {
                stream.restarts += 1;
                self.restarts += 1;
            } else {
                stream.lost += gap;
                self.lost += gap;
            }
        }
        stream.restart_expected = false;
        stream.last_sequence = Some(sequence);
    }

    /// The far end says it restarted (its `LINK_QUALITY` uptime went back, in a frame of
    /// stream `said_by`, already counted): the next gap of each other stream seen so far is
    /// its new numbering, not loss.
    pub fn expect_restart(&mut self, said_by: StreamId) {
        for (id, stream) in self.streams.iter_mut() {
            stream.restart_expected = *id != said_by;
        }
    }

    pub(crate) fn record_bad_crc(&mut self, id: StreamId) {
        self.bad_crc += 1;
        if let Some(stream) = self.streams.get_mut(&id) {
            stream.bad_crc += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: StreamId = StreamId {
        system: 1,
        component: 1,
    };

    #[test]
    fn gaps_count_lost_frames_across_wraparound() {
        let mut stats = ReaderStats::default();
        for seq in [250, 251, 254, 255, 0, 3] {
            stats.record_frame(S, seq, true);
        }
        // missing: 252, 253, 1, 2
        assert_eq!(stats.stream(S).unwrap().lost, 4);
        assert_eq!(stats.lost, 4);
        assert_eq!(stats.stream(S).unwrap().received, 6);
    }

    #[test]
    fn a_sender_that_starts_again_at_zero_restarted_and_lost_nothing() {
        let mut stats = ReaderStats::default();
        for seq in [7, 8, 9, 0, 1, 3] {
            stats.record_frame(S, seq, true);
        }
        // 9 → 0: a restart, not 246 lost; 1 → 3: one lost
        assert_eq!(stats.stream(S).unwrap().restarts, 1);
        assert_eq!(stats.lost, 1);
        // 255 → 0 is the plain wrap of a running stream
        stats.record_frame(S, 255, true);
        stats.record_frame(S, 0, true);
        assert_eq!((stats.restarts, stats.lost), (1, 252));
        // Told of a restart, its first frame lost too: 0 → 2 is the new numbering; only that
        // one gap, after it gaps are loss again.
        stats.expect_restart(StreamId {
            system: 1,
            component: 191,
        });
        stats.record_frame(S, 2, true);
        stats.record_frame(S, 4, true);
        assert_eq!((stats.restarts, stats.lost), (2, 253));
    }

    #[test]
    fn streams_are_independent() {
        let other = StreamId {
            system: 1,
            component: 190,
        };
        let mut stats = ReaderStats::default();
        stats.record_frame(S, 0, true);
        stats.record_frame(other, 100, false);
        stats.record_frame(S, 1, true);
        stats.record_frame(other, 101, true);
        assert_eq!(stats.lost, 0);
        assert_eq!(stats.frames_checked, 3);
        assert_eq!(stats.frames_unchecked, 1);
    }

    /// Regression: garbage on the flight controller's port, read as frames of unknown ids from
    /// random senders, opened a stream each (MBs of counters).
    #[test]
    fn made_up_senders_open_no_stream_beyond_the_bound() {
        let mut stats = ReaderStats::default();
        for n in 0..=u16::MAX {
            let [system, component] = n.to_le_bytes();
            stats.record_frame(StreamId { system, component }, 0, false);
        }
        assert_eq!(stats.streams().count(), 0);
        assert_eq!(stats.frames_unchecked, 65_536);
        for n in 0..=u16::MAX {
            let [system, component] = n.to_le_bytes();
            stats.record_frame(StreamId { system, component }, 0, true);
        }
        assert_eq!(stats.streams().count(), MAX_STREAMS);
        assert_eq!(stats.frames(), 2 * 65_536);
        // A stream seen checked counts its unchecked frames too.
        let first = stats.streams().next().unwrap().0;
        stats.record_frame(first, 1, false);
        assert_eq!(stats.stream(first).unwrap().received, 2);
    }

    #[test]
    fn bad_crc_of_unseen_stream_counts_only_in_total() {
        let mut stats = ReaderStats::default();
        stats.record_bad_crc(S);
        assert_eq!(stats.bad_crc, 1);
        assert!(stats.stream(S).is_none());
        stats.record_frame(S, 0, true);
        stats.record_bad_crc(S);
        assert_eq!(stats.stream(S).unwrap().bad_crc, 1);
        assert_eq!(stats.bad_crc, 2);
    }
}
