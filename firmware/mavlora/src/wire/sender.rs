//! Frames that a MavLora component originates itself (stream-rate requests, link quality).

use mavlink::{MavHeader, MavlinkVersion, Message};

use super::frame::{OwnedFrame, encode};

/// One originating component: its (system id, component id) and its sequence counter, which
/// MAVLink keeps per sender across all message ids (receivers count gaps in it).
#[derive(Debug, Clone)]
pub struct Sender {
    system: u8,
    component: u8,
    version: MavlinkVersion,
    next_sequence: u8,
}

impl Sender {
    /// A sender starting at sequence 0.
    pub fn new(system: u8, component: u8, version: MavlinkVersion) -> Self {
        Self {
            system,
            component,
            version,
            next_sequence: 0,
        }
    }

    /// Our system id.
    pub fn system(&self) -> u8 {
        self.system
    }

    /// Our component id.
    pub fn component(&self) -> u8 {
        self.component
    }

    /// Changes our system id (learned after start, e.g. from the flight controller).
    pub fn set_system(&mut self, system: u8) {
        self.system = system;
    }

    /// Frames from now on use `version` (a MAVLink 1 peer cannot parse MAVLink 2).
    pub fn set_version(&mut self, version: MavlinkVersion) {
        self.version = version;
    }

    /// Continues another sender's sequence (regenerated or resequenced streams).
    pub fn set_next_sequence(&mut self, sequence: u8) {
        self.next_sequence = sequence;
    }

    /// The sequence number the next frame gets, and advances it.
    pub fn take_sequence(&mut self) -> u8 {
        let seq = self.next_sequence;
        self.next_sequence = seq.wrapping_add(1);
        seq
    }

    /// Frames `message` with the next sequence number.
    pub fn frame<M: Message>(&mut self, message: &M) -> OwnedFrame {
        let header = MavHeader {
            system_id: self.system.into(),
            component_id: self.component,
            sequence: self.next_sequence,
        };
        self.next_sequence = self.next_sequence.wrapping_add(1);
        encode(self.version, header, message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{HEARTBEAT_DATA, MavMessage};

    #[test]
    fn sequence_advances_and_wraps() {
        let mut s = Sender::new(1, 191, MavlinkVersion::V2);
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        let seqs: Vec<u8> = (0..257).map(|_| s.frame(&hb).sequence()).collect();
        assert_eq!(&seqs[..3], &[0, 1, 2]);
        assert_eq!(&seqs[255..], &[255, 0]);
        let f = s.frame(&hb);
        assert_eq!((f.system_id(), f.component_id()), (1, 191));
    }
}
