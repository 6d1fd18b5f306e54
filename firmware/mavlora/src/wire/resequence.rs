//! Renumbering frames on a link. MAVLink receivers count loss from sequence gaps per sender;
//! a bridge that filters, thins or replaces frames creates gaps that are not loss. Renumbering
//! each sender's frames as they leave on the radio makes the far side's loss counters (and
//! so `LINK_QUALITY`) count radio loss only.

use std::collections::HashMap;

use super::frame::OwnedFrame;
use super::version::crc_extra_of;

/// Per-sender sequence counters for one outgoing link.
#[derive(Debug, Default, Clone)]
pub struct Resequencer {
    next: HashMap<(u8, u8), u8>,
}

impl Resequencer {
    /// A resequencer with no history.
    pub fn new() -> Self {
        Self::default()
    }

    /// Gives `frame` the next sequence number of its sender and fixes its checksum, unknown
    /// message ids included (their CRC_EXTRA is recovered from their checksum: one frame of
    /// the sender left with its own number would read as a gap of up to 255 frames). Signed
    /// frames (the signature covers the sequence) keep theirs; returns whether the frame was
    /// renumbered.
    pub fn apply(&mut self, frame: &mut OwnedFrame) -> bool {
        if frame.is_signed() {
            return false;
        }
        let Some(extra) = crc_extra_of(frame) else {
            return false;
        };
        let seq = self
            .next
            .entry((frame.system_id(), frame.component_id()))
            .or_insert(0);
        frame.set_sequence(*seq);
        frame.fill_checksum(extra);
        *seq = seq.wrapping_add(1);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::frame;
    use crate::wire::FrameReader;
    use crate::wire::ids::{GLOBAL_POSITION_INT, HEARTBEAT};

    #[test]
    fn thinned_stream_reads_as_gap_free() {
        let mut r = Resequencer::new();
        let mut reader = FrameReader::new();
        // every third frame of sender 1/1 survives a filter; sender 2/1 is interleaved
        for seq in (0..60u8).step_by(3) {
            let mut a = frame(GLOBAL_POSITION_INT, 1, 1, seq);
            let mut b = frame(HEARTBEAT, 2, 1, seq.wrapping_mul(7));
            assert!(r.apply(&mut a) && r.apply(&mut b));
            reader.push(a.as_bytes());
            reader.push(b.as_bytes());
        }
        while reader.next_frame().is_some() {}
        assert_eq!(reader.stats().frames_checked, 40);
        assert_eq!(reader.stats().lost, 0);
    }

    /// Regression: ArduPilot's own messages (ids outside our dialect) kept the autopilot's
    /// sequence numbers among renumbered frames of the same sender; the router's
    /// `LINK_QUALITY` read ~97 % loss on a loss-free link.
    #[test]
    fn unknown_ids_are_renumbered_with_their_sender() {
        use crate::testutil::raw_frame;
        use mavlink::MavlinkVersion;
        let mut r = Resequencer::new();
        let mut reader = FrameReader::new();
        for seq in (0..200u8).step_by(5) {
            let mut known = frame(GLOBAL_POSITION_INT, 1, 1, seq);
            // SIMSTATE (164, CRC_EXTRA 154): the FC's numbers run ahead of what passed
            let mut unknown =
                raw_frame(MavlinkVersion::V2, 1, 1, seq.wrapping_add(2), 164, &[7; 44]);
            unknown.fill_checksum(154);
            assert!(r.apply(&mut known) && r.apply(&mut unknown));
            assert!(
                unknown.crc_matches(154),
                "checksum rebuilt with its own CRC_EXTRA"
            );
            reader.push(known.as_bytes());
            reader.push(unknown.as_bytes());
        }
        while reader.next_frame().is_some() {}
        assert_eq!(reader.stats().frames(), 80);
        assert_eq!(reader.stats().lost, 0);
    }
}
