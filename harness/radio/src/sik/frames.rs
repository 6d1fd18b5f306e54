//! Where MAVLink frames begin and end in a byte stream, as SiK's `packet.c` finds them:
//! by start byte and length alone, no CRC. The radio needs no more to keep its own
//! frames out of the middle of another's, or to spot a HEARTBEAT going out.

/// MAVLink 1 start byte.
pub const STX_V1: u8 = 0xFE;
/// MAVLink 2 start byte.
pub const STX_V2: u8 = 0xFD;
/// MAVLink 2's "signed" incompatibility flag: 13 more bytes.
const IFLAG_SIGNED: u8 = 0x01;

/// A frame the scanner saw end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameEnd {
    /// Whether it looked like a HEARTBEAT as `check_heartbeat` judges it: v1 with a
    /// 9-byte payload and id 0, or v2 with at most 9 bytes (truncation) and id 0.
    pub heartbeat: bool,
}

/// Byte-by-byte frame boundary tracker.
#[derive(Debug, Clone, Default)]
pub struct FrameScanner {
    /// First bytes of the frame in progress (enough for the id), empty between frames.
    head: Vec<u8>,
    /// Bytes of the frame seen so far and its full length once the header told it.
    seen: usize,
    total: Option<usize>,
}

impl FrameScanner {
    /// Whether the stream is between frames (or in bytes that are no frame at all).
    pub fn between_frames(&self) -> bool {
        self.head.is_empty()
    }

    /// Takes one byte; says so when it ended a frame.
    pub fn push(&mut self, b: u8) -> Option<FrameEnd> {
        if self.head.is_empty() {
            if b == STX_V1 || b == STX_V2 {
                self.head.push(b);
                self.seen = 1;
                self.total = None;
            }
            // Anything else between frames is not MAVLink: still a boundary.
            return None;
        }
        if self.head.len() < 10 {
            self.head.push(b);
        }
        self.seen += 1;
        let v2 = self.head[0] == STX_V2;
        if self.total.is_none() {
            let len = usize::from(self.head[1]);
            self.total = match (v2, self.head.len()) {
                (false, 2) => Some(len + 8),
                (true, 3) => Some(len + 12 + if b & IFLAG_SIGNED != 0 { 13 } else { 0 }),
                _ => None,
            };
        }
        if self.total.is_some_and(|t| self.seen >= t) {
            let h = &self.head;
            let heartbeat = if v2 {
                h[1] <= 9 && h.len() >= 10 && h[7..10] == [0, 0, 0]
            } else {
                h[1] == 9 && h.len() >= 6 && h[5] == 0
            };
            self.head.clear();
            self.total = None;
            return Some(FrameEnd { heartbeat });
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(bytes: &[u8]) -> Vec<(usize, FrameEnd)> {
        let mut s = FrameScanner::default();
        bytes
            .iter()
            .enumerate()
            .filter_map(|(i, &b)| s.push(b).map(|e| (i, e)))
            .collect()
    }

    #[test]
    fn v1_and_v2_heartbeats_and_a_signed_frame_end_where_their_lengths_say() {
        let mut v1 = vec![STX_V1, 9, 0, 1, 1, 0];
        v1.extend([0; 9 + 2]);
        let mut v2 = vec![STX_V2, 9, 0, 0, 0, 1, 1, 0, 0, 0];
        v2.extend([0; 9 + 2]);
        let mut signed = vec![STX_V2, 3, IFLAG_SIGNED, 0, 0, 1, 1, 30, 0, 0];
        signed.extend([0; 3 + 2 + 13]);
        let stream = [b"junk".as_slice(), &v1, &v2, &signed].concat();
        let ends = frames(&stream);
        assert_eq!(
            ends,
            vec![
                (4 + 17 - 1, FrameEnd { heartbeat: true }),
                (4 + 17 + 21 - 1, FrameEnd { heartbeat: true }),
                (4 + 17 + 21 + 28 - 1, FrameEnd { heartbeat: false }),
            ]
        );
    }
}
