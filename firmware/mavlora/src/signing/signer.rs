//! Signing and verification state of one radio link end.

use std::collections::HashMap;

use mavlink::MAVLinkV2MessageRaw;

use super::key::SigningKey;
use crate::time::Instant;
use crate::wire::{Frame, IFLAG_SIGNED, OwnedFrame, known};

const SIGNATURE_LEN: usize = 13;
/// A new stream's first timestamp may lag our clock by this much (the spec's one minute, in
/// 10 µs units).
const NEW_STREAM_SLACK: u64 = 60 * 100_000;

/// Why a received frame was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// No signature (MAVLink 1, or MAVLink 2 without the signed flag).
    Unsigned,
    /// The signature does not match the key.
    BadSignature,
    /// Timestamp not above the last accepted one of its stream, or a new stream older than
    /// a minute.
    Replayed,
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SigningStats {
    /// Frames signed for the radio.
    pub signed: u64,
    /// Frames that could not be signed (MAVLink 1 or unknown id) and were not sent.
    pub unsignable: u64,
    /// Received frames accepted.
    pub accepted: u64,
    /// Received frames rejected as unsigned.
    pub unsigned: u64,
    /// Received frames rejected for a bad signature.
    pub bad_signature: u64,
    /// Received frames rejected as replays.
    pub replayed: u64,
}

/// Sans-IO signer/verifier for one end of the radio link.
#[derive(Debug)]
pub struct LinkSigner {
    key: SigningKey,
    link_id: u8,
    /// Signing timestamp (10 µs units since 2015-01-01) at engine time zero.
    epoch: u64,
    last_sent: u64,
    streams: HashMap<(u8, u8, u8), u64>,
    stats: SigningStats,
}

impl LinkSigner {
    /// A signer with `key`, stamping `link_id`; `epoch` is the signing timestamp (10 µs units
    /// since 2015-01-01 00:00 UTC) at engine time zero, given by the driver from its clock.
    pub fn new(key: SigningKey, link_id: u8, epoch: u64) -> Self {
        Self {
            key,
            link_id,
            epoch,
            last_sent: 0,
            streams: HashMap::new(),
            stats: SigningStats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> SigningStats {
        self.stats
    }

    fn clock(&self, now: Instant) -> u64 {
        self.epoch + now.as_micros() / 10
    }

    /// The signed form of `frame`, `None` if it cannot be signed (MAVLink 1, unknown id).
    pub fn sign(&mut self, frame: &OwnedFrame, now: Instant) -> Option<OwnedFrame> {
        let extra = known::crc_extra(frame.message_id());
        let (Some(extra), false) = (extra, frame.version() == mavlink::MavlinkVersion::V1) else {
            self.stats.unsignable += 1;
            return None;
        };
        let mut bytes = if frame.is_signed() {
            frame.as_bytes()[..frame.as_bytes().len() - SIGNATURE_LEN].to_vec()
        } else {
            frame.as_bytes().to_vec()
        };
        bytes[2] |= IFLAG_SIGNED;
        // the flags are covered by the checksum
        let mut unsigned_view = Frame::new_unchecked(&mut bytes[..]);
        unsigned_view.fill_checksum(extra);
        let timestamp = self.clock(now).max(self.last_sent + 1);
        self.last_sent = timestamp;
        bytes.push(self.link_id);
        bytes.extend_from_slice(&timestamp.to_le_bytes()[..6]);
        bytes.extend_from_slice(&[0; 6]);
        let signature = self.signature(&bytes);
        let at = bytes.len() - 6;
        bytes[at..].copy_from_slice(&signature);
        self.stats.signed += 1;
        Some(Frame::new_unchecked(bytes))
    }

    fn signature(&self, bytes: &[u8]) -> [u8; 6] {
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.as_mut_slice()[..bytes.len()].copy_from_slice(bytes);
        let mut sig = [0u8; 6];
        raw.calculate_signature(&self.key.0, &mut sig);
        sig
    }

    /// Checks a frame received from the radio at `now`; on success returns it without its
    /// signature (flag cleared, checksum fixed) for peers that do not hold the key.
    pub fn verify(&mut self, frame: &OwnedFrame, now: Instant) -> Result<OwnedFrame, Rejection> {
        let result = self.check(frame, now);
        match result {
            Ok(_) => self.stats.accepted += 1,
            Err(Rejection::Unsigned) => self.stats.unsigned += 1,
            Err(Rejection::BadSignature) => self.stats.bad_signature += 1,
            Err(Rejection::Replayed) => self.stats.replayed += 1,
        }
        result
    }

    fn check(&mut self, frame: &OwnedFrame, now: Instant) -> Result<OwnedFrame, Rejection> {
        let Some(sig) = frame.signature() else {
            return Err(Rejection::Unsigned);
        };
        let link_id = sig[0];
        let mut ts = [0u8; 8];
        ts[..6].copy_from_slice(&sig[1..7]);
        let timestamp = u64::from_le_bytes(ts);
        if self.signature(frame.as_bytes()) != sig[7..13] {
            return Err(Rejection::BadSignature);
        }
        let stream = (link_id, frame.system_id(), frame.component_id());
        match self.streams.get(&stream) {
            Some(&last) if timestamp <= last => return Err(Rejection::Replayed),
            None if timestamp + NEW_STREAM_SLACK < self.clock(now) => {
                return Err(Rejection::Replayed);
            }
            _ => {}
        }
        self.streams.insert(stream, timestamp);
        let mut bytes = frame.as_bytes()[..frame.as_bytes().len() - SIGNATURE_LEN].to_vec();
        bytes[2] &= !IFLAG_SIGNED;
        let mut plain = Frame::new_unchecked(bytes);
        if let Some(extra) = known::crc_extra(plain.message_id()) {
            plain.fill_checksum(extra);
        }
        Ok(plain)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::frame;
    use crate::wire::ids::{GLOBAL_POSITION_INT, HEARTBEAT};

    fn pair() -> (LinkSigner, LinkSigner) {
        let key = SigningKey([7; 32]);
        (
            LinkSigner::new(key.clone(), 1, 1_000_000),
            LinkSigner::new(key, 2, 1_000_000),
        )
    }

    #[test]
    fn signed_frame_verifies_and_comes_back_plain() {
        let (mut a, mut b) = pair();
        let f = frame(GLOBAL_POSITION_INT, 1, 1, 9);
        let signed = a.sign(&f, Instant::ZERO).unwrap();
        assert!(signed.is_signed());
        assert_eq!(signed.as_bytes().len(), f.as_bytes().len() + 13);
        let plain = b.verify(&signed, Instant::ZERO).unwrap();
        assert_eq!(plain, f);
        assert_eq!(b.stats().accepted, 1);
    }

    #[test]
    fn tampered_unsigned_and_replayed_frames_are_rejected() {
        let (mut a, mut b) = pair();
        let signed = a.sign(&frame(HEARTBEAT, 1, 1, 0), Instant::ZERO).unwrap();
        let mut bytes = signed.as_bytes().to_vec();
        bytes[12] ^= 1; // payload bit
        let tampered = Frame::new_unchecked(bytes);
        assert_eq!(
            b.verify(&tampered, Instant::ZERO),
            Err(Rejection::BadSignature)
        );
        assert_eq!(
            b.verify(&frame(HEARTBEAT, 1, 1, 0), Instant::ZERO),
            Err(Rejection::Unsigned)
        );
        assert!(b.verify(&signed, Instant::ZERO).is_ok());
        assert_eq!(
            b.verify(&signed, Instant::from_millis(5)),
            Err(Rejection::Replayed)
        );
        // a wrong key fails too
        let mut c = LinkSigner::new(SigningKey([8; 32]), 3, 1_000_000);
        let later = a.sign(&frame(HEARTBEAT, 1, 1, 1), Instant::ZERO).unwrap();
        assert_eq!(
            c.verify(&later, Instant::ZERO),
            Err(Rejection::BadSignature)
        );
        let s = b.stats();
        assert_eq!(
            (s.bad_signature, s.unsigned, s.replayed, s.accepted),
            (1, 1, 1, 1)
        );
    }

    #[test]
    fn timestamps_increase_even_within_one_tick() {
        let (mut a, mut b) = pair();
        for seq in 0..5 {
            let s = a.sign(&frame(HEARTBEAT, 1, 1, seq), Instant::ZERO).unwrap();
            assert!(b.verify(&s, Instant::ZERO).is_ok(), "frame {seq}");
        }
    }

    #[test]
    fn stale_new_stream_is_a_replay() {
        let key = SigningKey([7; 32]);
        let mut old = LinkSigner::new(key.clone(), 1, 0);
        let mut now = LinkSigner::new(key, 2, 10 * NEW_STREAM_SLACK);
        let s = old.sign(&frame(HEARTBEAT, 1, 1, 0), Instant::ZERO).unwrap();
        assert_eq!(now.verify(&s, Instant::ZERO), Err(Rejection::Replayed));
    }
}
