//! SiK's `RADIO_STATUS` (`mavlink.c`, `MAVLink_report`) and where it goes in the stream.
//!
//! What the firmware does: when MAVLink framing is on (`MAVLINK` ≥ 1), each HEARTBEAT the
//! host sends out through the radio (`check_heartbeat` in `packet.c`) arms one report,
//! written to the host's serial side by the main loop unless the radio is in command
//! mode: so about once a second, at the autopilot's heartbeat rate. The frame is MAVLink 1
//! (`0xFE`), message 109 with CRC extra 185, system `'3'` (51), component `'D'` (68), a
//! sequence of its own. `txbuf` is the free share of the serial receive buffer in percent
//! (`serial_read_space`), `rssi`/`noise` the local receiver's filtered readings,
//! `remrssi`/`remnoise` the far receiver's (carried back in the TDM trailer).
//!
//! Here: readings come from the model ([`crate::Link::receiver`] in dBm, converted with
//! SiK's scale dBm = value / 1.9 − 127), `txbuf` from [`crate::Link::buffer_free_share`].
//! Not modelled: SiK's 7/8 running average (the model's reading is already steady), and
//! `rxerrors`/`fixed` (the model has no CRC errors or Golay corrections to count: both 0).

use mavlink_core::MavHeader;
use mavlora_dialect::{MavMessage, RADIO_STATUS_DATA};

use super::frames::FrameScanner;
use crate::ReceiverReading;

/// System id SiK sends its reports with: `'3'`.
pub const SYSTEM_ID: u8 = b'3';
/// Component id: `'D'` (`MAV_COMP_ID_TELEMETRY_RADIO`).
pub const COMPONENT_ID: u8 = b'D';

/// What one report carries, before scaling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StatusInputs {
    /// This radio's receiver (the direction arriving here).
    pub local: ReceiverReading,
    /// The far radio's receiver (the direction leaving here).
    pub remote: ReceiverReading,
    /// Free share of this radio's transmit buffer, 0..=1.
    pub tx_free_share: f64,
}

/// dBm to SiK's RSSI units (0..=254; 255 is "unknown" in MAVLink).
pub fn sik_rssi(dbm: f64) -> u8 {
    ((dbm + 127.0) * 1.9).round().clamp(0.0, 254.0) as u8
}

/// The message SiK would send for `inputs`.
pub fn radio_status(inputs: &StatusInputs) -> RADIO_STATUS_DATA {
    RADIO_STATUS_DATA {
        rssi: sik_rssi(inputs.local.rssi_dbm),
        remrssi: sik_rssi(inputs.remote.rssi_dbm),
        // Integer percent, rounded down as `serial_read_space` does.
        txbuf: (inputs.tx_free_share.clamp(0.0, 1.0) * 100.0).floor() as u8,
        noise: sik_rssi(inputs.local.noise_dbm),
        remnoise: sik_rssi(inputs.remote.noise_dbm),
        rxerrors: 0,
        fixed: 0,
    }
}

/// The MAVLink 1 frame of `status` with sequence `seq`.
pub fn encode(status: &RADIO_STATUS_DATA, seq: u8) -> Vec<u8> {
    let header = MavHeader {
        system_id: SYSTEM_ID.into(),
        component_id: COMPONENT_ID,
        sequence: seq,
    };
    let mut out = Vec::with_capacity(17);
    // A 9-byte payload into a Vec: the writer cannot fail.
    mavlink_core::write_v1_msg(&mut out, header, &MavMessage::RADIO_STATUS(status.clone()))
        .expect("RADIO_STATUS fits MAVLink 1");
    out
}

/// The stream towards the host: data from the air with reports spliced in only where one
/// MAVLink frame ended and the next has not begun.
#[derive(Debug, Clone, Default)]
pub struct Splicer {
    scanner: FrameScanner,
    pending: Option<Vec<u8>>,
}

impl Splicer {
    /// Queues a report: out now if the stream is between frames, else after the frame.
    pub fn insert(&mut self, frame: Vec<u8>, out: &mut Vec<u8>) {
        if self.scanner.between_frames() {
            out.extend_from_slice(&frame);
        } else {
            // A second report before the first went out replaces it: the newer reading.
            self.pending = Some(frame);
        }
    }

    /// Data bytes from the air, with any held report after the frame they complete.
    pub fn data(&mut self, bytes: &[u8], out: &mut Vec<u8>) {
        for &b in bytes {
            out.push(b);
            self.scanner.push(b);
            if self.scanner.between_frames()
                && let Some(frame) = self.pending.take()
            {
                out.extend_from_slice(&frame);
            }
        }
    }

    /// Whether a report is held back for a frame to end.
    pub fn holding(&self) -> bool {
        self.pending.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink_core::Message;

    #[test]
    fn the_frame_is_what_sik_sends() {
        let inputs = StatusInputs {
            local: ReceiverReading {
                rssi_dbm: -77.0,
                noise_dbm: -110.0,
            },
            remote: ReceiverReading {
                rssi_dbm: -80.0,
                noise_dbm: -100.0,
            },
            tx_free_share: 0.999,
        };
        let status = radio_status(&inputs);
        assert_eq!((status.rssi, status.txbuf), (95, 99));
        let frame = encode(&status, 7);
        assert_eq!(frame.len(), 17);
        assert_eq!(&frame[..6], &[0xFE, 9, 7, b'3', b'D', 109]);
        // Decoded by the dialect: CRC extra 185 checks, the fields come back.
        let mut raw = [0u8; 263];
        raw[..frame.len()].copy_from_slice(&frame);
        let raw = mavlink_core::MAVLinkV1MessageRaw::from_bytes_unparsed(raw);
        assert!(raw.has_valid_crc::<MavMessage>());
        let msg = MavMessage::parse(mavlink_core::MavlinkVersion::V1, 109, raw.payload()).unwrap();
        assert_eq!(msg.message_id(), 109);
        assert_eq!(msg, MavMessage::RADIO_STATUS(status));
    }
}
