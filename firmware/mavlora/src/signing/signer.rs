//! Signing and verification state of one radio link end, with the timestamp rules of the
//! MAVLink signing spec ("Timestamp handling"):
//! - our timestamp is the larger of the clock, our last one + 1, and the newest timestamp of
//!   an accepted frame (so a side whose clock is behind catches up with its peer after one
//!   good frame instead of having its own frames rejected as old);
//! - a stream's frame must carry a timestamp above the last accepted from that stream;
//! - a stream not seen before is accepted only if its timestamp is at most one minute behind
//!   ours;
//! - no frame is accepted, adopted or stored whose timestamp is more than [`MAX_AHEAD`] (a
//!   minute) ahead of our clock: one such frame from a key holder would otherwise carry both
//!   ends' timestamps to wherever it was stamped (2^48 - 60: past the 48-bit wrap, after
//!   which each end took the other's frames for replays, across restarts too);
//! - at start the timestamp and the streams come from the stored [`SigningState`], so a
//!   restart neither reuses timestamps nor forgets what it accepted before;
//! - beyond the spec, on the radio leg ([`LinkSigner::require_proof`]): a peer link id the
//!   stored state holds no stream of (a fresh state) is not taken at all ([`Rejection::Unproven`])
//!   until the peer answered our challenge ([`super::Handshake`]); the answer's timestamp then
//!   is that link's floor, every frame of it must be above. A clock cannot say how old a
//!   frame is when the clock itself may be behind; the peer's own counter can.

use std::collections::BTreeMap;

use mavlink::MAVLinkV2MessageRaw;

use super::key::SigningKey;
use super::state::{SigningState, StreamKey};
use crate::time::Instant;
use crate::wire::{Frame, IFLAG_SIGNED, OwnedFrame, crc_extra_of};

const SIGNATURE_LEN: usize = 13;
/// A new stream's first timestamp may lag our timestamp by this much (the spec's one minute,
/// in 10 µs units).
pub const NEW_STREAM_SLACK: u64 = 60 * 100_000;
/// How far ahead of our clock a received timestamp may be (10 µs units): the spec's own
/// tolerance between two clocks, its one minute for a new stream's lag, taken the other way.
/// Beyond it one of the two clocks is wrong (or a key holder stamps the future), and the link
/// refuses rather than follow it. So both ends' clocks must agree within a minute.
pub const MAX_AHEAD: u64 = NEW_STREAM_SLACK;
/// Timestamps are 48 bits on the wire.
const TIMESTAMP_MASK: u64 = (1 << 48) - 1;

/// Why a received frame was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// No signature (MAVLink 1, or MAVLink 2 without the signed flag).
    Unsigned,
    /// The signature does not match the key.
    BadSignature,
    /// Signed with our own link id: a frame of ours sent back to us (reflected or recorded on
    /// the air). Our two ends sign as different links, and a new stream would otherwise take
    /// it as the peer's (the bridge's own signed NAV_LAND, replayed 30 s later, reached the
    /// flight controller).
    Reflected,
    /// Timestamp not above the last accepted one of its stream (also across a restart).
    Replayed,
    /// A stream not seen before whose timestamp is more than a minute behind ours (a
    /// captured frame, or a peer whose clock is behind and has not yet heard from us).
    Stale,
    /// A timestamp more than [`MAX_AHEAD`] ahead of our clock: our clock is behind, the
    /// sender's ahead, or a key holder stamped it there; never adopted.
    Ahead {
        /// How far ahead of our clock, whole seconds.
        seconds: u64,
    },
    /// From a peer link id our state holds nothing of (a fresh state) that has not yet
    /// answered our challenge: it may be a recording (see [`LinkSigner::require_proof`]).
    Unproven,
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SigningStats {
    /// Frames signed for the radio.
    pub signed: u64,
    /// Frames not sent on the radio because they could not be made MAVLink 2 and signed (a
    /// checksum no CRC_EXTRA reproduces: corrupted).
    pub unsignable: u64,
    /// Frames sent on the radio without a signature (only with signing off, `--unsigned`).
    pub sent_unsigned: u64,
    /// Received frames accepted.
    pub accepted: u64,
    /// Received frames rejected as unsigned.
    pub unsigned: u64,
    /// Received frames rejected for a bad signature.
    pub bad_signature: u64,
    /// Received frames rejected as our own (signed with our link id).
    pub reflected: u64,
    /// Received frames rejected as replays.
    pub replayed: u64,
    /// Received frames of a new stream rejected as more than a minute old.
    pub stale: u64,
    /// Received frames rejected as stamped more than [`MAX_AHEAD`] ahead of our clock.
    pub ahead: u64,
    /// Received frames rejected because their peer has not yet proven it is live (a fresh
    /// state waiting for the answer to its challenge).
    pub unproven: u64,
}

/// The signature `key` gives the signed frame `bytes` (its last six bytes are not read).
fn signature_of(key: &SigningKey, bytes: &[u8]) -> [u8; 6] {
    let mut raw = MAVLinkV2MessageRaw::new();
    raw.as_mut_slice()[..bytes.len()].copy_from_slice(bytes);
    let mut sig = [0u8; 6];
    raw.calculate_signature(&key.0, &mut sig);
    sig
}

/// Vouches for frames signed with the link's key, for a radio reader's resynchronisation
/// ([`crate::wire::FrameReader::with_authenticator`]); the verifier still judges them.
#[derive(Debug)]
pub struct KeyAuthenticator(pub SigningKey);

impl crate::wire::Authenticator for KeyAuthenticator {
    fn authentic(&self, frame: &[u8]) -> bool {
        let view = Frame::new_unchecked(frame);
        let Some(sig) = view.signature() else {
            return false;
        };
        sig.len() == SIGNATURE_LEN && signature_of(&self.0, frame) == sig[7..13]
    }
}

/// Sans-IO signer/verifier for one end of the radio link.
#[derive(Debug)]
pub struct LinkSigner {
    key: SigningKey,
    link_id: u8,
    /// Signing timestamp (10 µs units since 2015-01-01) at engine time zero.
    epoch: u64,
    /// The last timestamp used or adopted from an accepted frame.
    timestamp: u64,
    streams: BTreeMap<StreamKey, u64>,
    /// Per peer link id, the timestamp its frames must be above; `None`: every link is taken
    /// as the spec says (no proof required). A link the stored state knew has floor 0; one
    /// without an entry is unproven.
    floors: Option<BTreeMap<u8, u64>>,
    stats: SigningStats,
}

/// The signing timestamp of a signed frame.
pub(crate) fn signed_timestamp(frame: &OwnedFrame) -> Option<(u8, u64)> {
    let sig = frame.signature()?;
    let mut ts = [0u8; 8];
    ts[..6].copy_from_slice(&sig[1..7]);
    Some((sig[0], u64::from_le_bytes(ts)))
}

impl LinkSigner {
    /// A signer with `key`, stamping `link_id`; `epoch` is the signing timestamp (10 µs units
    /// since 2015-01-01 00:00 UTC) at engine time zero, given by the driver from its clock.
    pub fn new(key: SigningKey, link_id: u8, epoch: u64) -> Self {
        Self::with_state(key, link_id, epoch, SigningState::default())
    }

    /// A signer that resumes from `state` (stored by a previous run): it starts from the
    /// larger of the stored timestamp and the clock, and keeps rejecting what the previous
    /// run accepted. A state stamped beyond [`MAX_AHEAD`] of the clock is the driver's to
    /// refuse ([`SigningState::check_ahead`]) before it gets here.
    pub fn with_state(key: SigningKey, link_id: u8, epoch: u64, state: SigningState) -> Self {
        Self {
            key,
            link_id,
            epoch,
            timestamp: state.timestamp,
            streams: state.streams,
            floors: None,
            stats: SigningStats::default(),
        }
    }

    /// From now on, frames of a peer link id the stored state holds no stream of are refused
    /// ([`Rejection::Unproven`]) until [`prove`](Self::prove) gives that link a floor: a fresh
    /// state cannot tell a recording made a minute ago from a live frame by its clock. Links
    /// the state knows keep the spec's rules. Returns whether some peer link is known.
    pub fn require_proof(&mut self) -> bool {
        let own = self.link_id;
        let known: BTreeMap<u8, u64> = self
            .streams
            .keys()
            .filter(|&&(link, _, _)| link != own)
            .map(|&(link, _, _)| (link, 0))
            .collect();
        let any = !known.is_empty();
        self.floors = Some(known);
        any
    }

    /// The peer signing as `link` proved it is live with a frame stamped `timestamp` from
    /// `stream` (the answer to our challenge): everything it signed before, recordings
    /// included, is older. Recorded as that stream's last, so a state stored from now on
    /// knows the link.
    pub fn prove(&mut self, stream: StreamKey, timestamp: u64) {
        if let Some(floors) = &mut self.floors {
            let floor = floors.entry(stream.0).or_insert(0);
            *floor = (*floor).max(timestamp);
        }
        let last = self.streams.entry(stream).or_insert(0);
        *last = (*last).max(timestamp);
    }

    /// Whether `link` is a peer whose frames are taken (known from the stored state, proven,
    /// or no proof required).
    pub fn trusts(&self, link: u8) -> bool {
        self.floors.as_ref().is_none_or(|f| f.contains_key(&link))
    }

    /// Our signing timestamp at `now` (10 µs units since 2015-01-01).
    pub fn timestamp(&self, now: Instant) -> u64 {
        self.local(now)
    }

    /// What to store so a restart resumes safely (see [`LinkSigner::with_state`]); taken at
    /// `now`, so the stored timestamp is at least the clock's.
    pub fn state(&self, now: Instant) -> SigningState {
        SigningState {
            timestamp: self.local(now),
            streams: self.streams.clone(),
        }
    }

    /// Our timestamp at `now`: the clock, or what we used or adopted if that is later.
    fn local(&self, now: Instant) -> u64 {
        self.clock(now).max(self.timestamp)
    }

    /// Counters so far.
    pub fn stats(&self) -> SigningStats {
        self.stats
    }

    fn clock(&self, now: Instant) -> u64 {
        self.epoch + now.as_micros() / 10
    }

    /// The signed form of `frame`, `None` if it cannot be signed (MAVLink 1: make it
    /// MAVLink 2 first, [`crate::wire::to_v2`]). Ids outside the dialect are signed with the
    /// CRC_EXTRA their checksum was made with.
    pub fn sign(&mut self, frame: &OwnedFrame, now: Instant) -> Option<OwnedFrame> {
        let extra = crc_extra_of(frame);
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
        let timestamp = self.clock(now).max(self.timestamp + 1) & TIMESTAMP_MASK;
        self.timestamp = timestamp;
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
        signature_of(&self.key, bytes)
    }

    /// Checks a frame received from the radio at `now`; on success returns it without its
    /// signature (flag cleared, checksum fixed) for peers that do not hold the key.
    pub fn verify(&mut self, frame: &OwnedFrame, now: Instant) -> Result<OwnedFrame, Rejection> {
        let result = self.check(frame, now, false);
        self.count(&result);
        result
    }

    /// [`verify`](Self::verify) for a frame of the freshness handshake (a challenge or its
    /// answer): taken from a peer not yet proven (answering is always allowed: a replayed
    /// challenge gets an answer echoing an old nonce, useless), and then not recorded as its
    /// stream's last, so a state stored before the proof still knows nothing of that link.
    pub fn verify_handshake(
        &mut self,
        frame: &OwnedFrame,
        now: Instant,
    ) -> Result<OwnedFrame, Rejection> {
        let result = self.check(frame, now, true);
        self.count(&result);
        result
    }

    fn count(&mut self, result: &Result<OwnedFrame, Rejection>) {
        match result {
            Ok(_) => self.stats.accepted += 1,
            Err(Rejection::Unsigned) => self.stats.unsigned += 1,
            Err(Rejection::BadSignature) => self.stats.bad_signature += 1,
            Err(Rejection::Reflected) => self.stats.reflected += 1,
            Err(Rejection::Replayed) => self.stats.replayed += 1,
            Err(Rejection::Stale) => self.stats.stale += 1,
            Err(Rejection::Ahead { .. }) => self.stats.ahead += 1,
            Err(Rejection::Unproven) => self.stats.unproven += 1,
        }
    }

    fn check(
        &mut self,
        frame: &OwnedFrame,
        now: Instant,
        handshake: bool,
    ) -> Result<OwnedFrame, Rejection> {
        let (Some(sig), Some((link_id, timestamp))) = (frame.signature(), signed_timestamp(frame))
        else {
            return Err(Rejection::Unsigned);
        };
        if self.signature(frame.as_bytes()) != sig[7..13] {
            return Err(Rejection::BadSignature);
        }
        if link_id == self.link_id {
            return Err(Rejection::Reflected);
        }
        // Measured from the clock, not from what we adopted: adoption cannot ratchet it.
        let clock = self.clock(now);
        if timestamp > clock + MAX_AHEAD {
            return Err(Rejection::Ahead {
                seconds: (timestamp - clock) / 100_000,
            });
        }
        let floor = self.floors.as_ref().map(|f| f.get(&link_id).copied());
        let proven = match floor {
            // Adopted all the same (within MAX_AHEAD, checked above): our own frames, the
            // challenge first, then sign above what the peer accepted from us before.
            Some(None) if !handshake => {
                self.timestamp = self.timestamp.max(timestamp);
                return Err(Rejection::Unproven);
            }
            Some(Some(floor)) if timestamp <= floor && !handshake => {
                return Err(Rejection::Replayed);
            }
            Some(None) => false,
            _ => true,
        };
        let stream = (link_id, frame.system_id(), frame.component_id());
        match self.streams.get(&stream) {
            Some(&last) if timestamp <= last => return Err(Rejection::Replayed),
            None if timestamp + NEW_STREAM_SLACK < self.local(now) => {
                return Err(Rejection::Stale);
            }
            _ => {}
        }
        if proven {
            self.streams.insert(stream, timestamp);
        }
        // the spec: adopt a newer timestamp from an accepted frame (at most MAX_AHEAD of our
        // clock, checked above)
        self.timestamp = self.timestamp.max(timestamp);
        let mut bytes = frame.as_bytes()[..frame.as_bytes().len() - SIGNATURE_LEN].to_vec();
        bytes[2] &= !IFLAG_SIGNED;
        let extra = crc_extra_of(frame);
        let mut plain = Frame::new_unchecked(bytes);
        if let Some(extra) = extra {
            plain.fill_checksum(extra);
        }
        Ok(plain)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::frame;
    use crate::wire::ids::{COMMAND_LONG, GLOBAL_POSITION_INT, HEARTBEAT, TIMESYNC};

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
    fn a_frame_signed_with_our_own_link_id_is_refused() {
        let (mut a, mut b) = pair();
        let f = frame(GLOBAL_POSITION_INT, 1, 1, 9);
        let ours = a.sign(&f, Instant::ZERO).unwrap();
        assert_eq!(a.verify(&ours, Instant::ZERO), Err(Rejection::Reflected));
        assert_eq!(a.stats().reflected, 1);
        assert!(b.verify(&ours, Instant::ZERO).is_ok(), "the peer takes it");
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
        assert_eq!(now.verify(&s, Instant::ZERO), Err(Rejection::Stale));
        assert_eq!(now.stats().stale, 1);
    }

    /// A frame captured before the receiver restarts is rejected after it: the restarted
    /// receiver resumes from the state its previous run stored.
    #[test]
    fn frames_captured_before_a_restart_are_replays_after_it() {
        let key = SigningKey([7; 32]);
        let mut sender = LinkSigner::new(key.clone(), 1, 1_000_000);
        let mut receiver = LinkSigner::new(key.clone(), 2, 1_000_000);
        let mut captured = Vec::new();
        for seq in 0..20u8 {
            let at = Instant::from_millis(u64::from(seq) * 100);
            let s = sender.sign(&frame(HEARTBEAT, 1, 1, seq), at).unwrap();
            assert!(receiver.verify(&s, at).is_ok());
            captured.push(s);
        }
        let stored = receiver.state(Instant::from_secs(2));
        // restart one second later (engine time starts again at zero, the epoch moved on)
        let mut restarted = LinkSigner::with_state(key.clone(), 2, 1_000_000 + 300_000, stored);
        for s in &captured {
            assert_eq!(restarted.verify(s, Instant::ZERO), Err(Rejection::Replayed));
        }
        assert_eq!(restarted.stats().replayed, 20);
        // without the stored state they would all pass: the window the spec leaves is a minute
        let mut amnesiac = LinkSigner::new(key, 2, 1_000_000 + 300_000);
        assert!(
            captured
                .iter()
                .all(|s| amnesiac.verify(s, Instant::ZERO).is_ok())
        );
        // the sender's own next frame is still accepted by the restarted receiver
        let next = sender.sign(&frame(HEARTBEAT, 1, 1, 20), Instant::from_secs(3));
        assert!(restarted.verify(&next.unwrap(), Instant::ZERO).is_ok());
    }

    /// Our signer restarted with a clock that went back (no RTC) continues above what it used.
    #[test]
    fn restart_starts_from_the_larger_of_stored_and_clock() {
        let key = SigningKey([7; 32]);
        let mut before = LinkSigner::new(key.clone(), 1, 5_000_000);
        let last = before.sign(&frame(HEARTBEAT, 1, 1, 0), Instant::from_secs(9));
        let stored = before.state(Instant::from_secs(10));
        let mut after = LinkSigner::with_state(key.clone(), 1, 0, stored.clone());
        let first = after
            .sign(&frame(HEARTBEAT, 1, 1, 1), Instant::ZERO)
            .unwrap();
        let stamp = |f: &OwnedFrame| {
            let mut ts = [0u8; 8];
            ts[..6].copy_from_slice(&f.signature().unwrap()[1..7]);
            u64::from_le_bytes(ts)
        };
        assert!(stamp(&first) > stamp(&last.unwrap()));
        assert!(stamp(&first) > stored.timestamp);
        // and with a clock ahead of the stored value, the clock wins
        let mut ahead = LinkSigner::with_state(key, 1, stored.timestamp + 1_000, stored);
        let s = ahead
            .sign(&frame(HEARTBEAT, 1, 1, 2), Instant::ZERO)
            .unwrap();
        assert_eq!(stamp(&s), ahead.state(Instant::ZERO).timestamp);
    }

    /// Regression: one frame a key holder stamped 2^48 - 60 was adopted by both ends; their
    /// timestamps wrapped past 48 bits to small values, every frame after that was a replay to
    /// the other end, and the state files kept the wedge across restarts.
    #[test]
    fn a_frame_stamped_near_the_48_bit_wrap_is_refused_and_the_link_keeps_working() {
        let key = SigningKey([7; 32]);
        let epoch = 300_000_000_000; // 2024, in 10 us units since 2015
        let mut drone = LinkSigner::new(key.clone(), 1, epoch);
        let mut ground = LinkSigner::new(key.clone(), 2, epoch);
        let mut rogue = LinkSigner::new(key, 9, (1 << 48) - 60);
        let poison = rogue
            .sign(&frame(HEARTBEAT, 3, 1, 0), Instant::ZERO)
            .unwrap();
        let t = Instant::from_secs(1);
        for end in [&mut drone, &mut ground] {
            let refused = end.verify(&poison, t);
            assert!(
                matches!(refused, Err(Rejection::Ahead { .. })),
                "{refused:?}"
            );
            assert_eq!(end.stats().ahead, 1);
        }
        // both ends go on: 200 frames each way (the wrap came after 60)
        for seq in 0..200u8 {
            let at = t + crate::Duration::from_millis(10 * u64::from(seq));
            let up = ground
                .sign(&frame(COMMAND_LONG, 255, 190, seq), at)
                .unwrap();
            assert!(drone.verify(&up, at).is_ok(), "command {seq} refused");
            let down = drone.sign(&frame(HEARTBEAT, 1, 1, seq), at).unwrap();
            assert!(ground.verify(&down, at).is_ok(), "telemetry {seq} refused");
        }
        // and nothing of it is stored for the next start
        let later = Instant::from_secs(5);
        for state in [drone.state(later), ground.state(later)] {
            let near = |t: u64| t < epoch + 10 * NEW_STREAM_SLACK;
            assert!(near(state.timestamp), "{state:?}");
            assert!(state.streams.values().all(|&t| near(t)), "{state:?}");
        }
    }

    /// Regression: a bridge that lost its state file, with its clock a day behind, took a
    /// ground ARM recorded ten minutes before as fresh (a stream it had not seen, and far
    /// "newer" than its clock) and ran it.
    #[test]
    fn a_fresh_signer_with_its_clock_a_day_behind_refuses_a_ten_minute_old_arm() {
        let key = SigningKey([7; 32]);
        let now = 300_000_000_000u64;
        let (day, ten_minutes) = (86_400 * 100_000, 600 * 100_000);
        let mut router_then = LinkSigner::new(key.clone(), 2, now - ten_minutes);
        let captured = router_then
            .sign(&frame(COMMAND_LONG, 255, 190, 0), Instant::ZERO)
            .unwrap();
        let mut bridge = LinkSigner::with_state(key, 1, now - day, SigningState::default());
        let refused = bridge.verify(&captured, Instant::ZERO);
        assert!(
            matches!(refused, Err(Rejection::Ahead { .. })),
            "{refused:?}"
        );
        assert_eq!(bridge.stats().accepted, 0);
    }

    /// The spec's clock-behind peer, within the minute both clocks must agree to: a drone that
    /// lost its state, its clock 50 s behind, signs below what the ground accepted from it
    /// before (replays); once it accepted a frame of ours (50 s ahead of its clock: within the
    /// minute) it signs above and gets through. A clock more than a minute behind is refused
    /// both ways, loudly, instead of following frames that may be recorded.
    #[test]
    fn a_peer_within_the_minute_catches_up_and_one_beyond_it_is_refused_both_ways() {
        let key = SigningKey([7; 32]);
        let ground_clock = 300_000_000_000;
        let mut stored = SigningState::default();
        stored
            .streams
            .insert((1, 1, 1), ground_clock - 10 * 100_000);
        let mut ground = LinkSigner::with_state(key.clone(), 2, ground_clock, stored.clone());
        let t = Instant::from_secs(1);
        let mut drone = LinkSigner::new(key.clone(), 1, ground_clock - 50 * 100_000);
        let early = drone.sign(&frame(HEARTBEAT, 1, 1, 0), t).unwrap();
        assert_eq!(ground.verify(&early, t), Err(Rejection::Replayed));
        let hello = ground.sign(&frame(HEARTBEAT, 255, 190, 0), t).unwrap();
        assert!(
            drone.verify(&hello, t).is_ok(),
            "50 s ahead is within the minute"
        );
        let later = drone.sign(&frame(HEARTBEAT, 1, 1, 1), t).unwrap();
        assert!(ground.verify(&later, t).is_ok(), "caught up");

        let mut ground = LinkSigner::with_state(key.clone(), 2, ground_clock, stored);
        let hour = 3600 * 100_000;
        let mut behind = LinkSigner::new(key, 1, ground_clock - hour);
        let early = behind.sign(&frame(HEARTBEAT, 1, 1, 0), t).unwrap();
        assert_eq!(ground.verify(&early, t), Err(Rejection::Replayed));
        let hello = ground.sign(&frame(HEARTBEAT, 255, 190, 0), t).unwrap();
        assert_eq!(
            behind.verify(&hello, t),
            Err(Rejection::Ahead { seconds: 3600 })
        );
        let still = behind.sign(&frame(HEARTBEAT, 1, 1, 1), t).unwrap();
        assert_eq!(ground.verify(&still, t), Err(Rejection::Replayed));
        assert_eq!(behind.stats().ahead, 1);
    }

    /// Regression: a signer without a state took a ground ARM recorded 30 s before it
    /// started (a new stream within the spec's minute). Required to, it takes nothing of the
    /// peer until the peer's answer, and then only what the peer signed after it.
    #[test]
    fn a_fresh_signer_takes_nothing_of_an_unproven_peer_and_only_what_it_signed_after_the_proof() {
        let key = SigningKey([7; 32]);
        let thirty = 30 * 100_000;
        let mut router = LinkSigner::new(key.clone(), 2, 1_000_000);
        let captured = router
            .sign(&frame(COMMAND_LONG, 255, 190, 0), Instant::ZERO)
            .unwrap();
        let mut spec_only = LinkSigner::new(key.clone(), 1, 1_000_000 + thirty);
        assert!(
            spec_only.verify(&captured, Instant::ZERO).is_ok(),
            "the spec takes it"
        );
        let mut bridge = LinkSigner::new(key.clone(), 1, 1_000_000 + thirty);
        assert!(!bridge.require_proof(), "knows no peer");
        assert_eq!(
            bridge.verify(&captured, Instant::ZERO),
            Err(Rejection::Unproven)
        );
        assert_eq!(bridge.stats().unproven, 1);
        let t = Instant::from_secs(30);
        let answer = router.sign(&frame(TIMESYNC, 255, 191, 1), t).unwrap();
        assert!(bridge.verify_handshake(&answer, Instant::ZERO).is_ok());
        assert!(!bridge.trusts(2), "verifying is not proving");
        let (link, stamp) = signed_timestamp(&answer).unwrap();
        bridge.prove((link, 255, 191), stamp);
        assert!(bridge.trusts(2));
        assert_eq!(
            bridge.verify(&captured, Instant::ZERO),
            Err(Rejection::Replayed)
        );
        let live = router.sign(&frame(COMMAND_LONG, 255, 190, 2), t).unwrap();
        assert!(bridge.verify(&live, Instant::ZERO).is_ok());
        // a state knowing the peer's link needs no proof: the spec's rules
        let stored = bridge.state(Instant::ZERO);
        let mut restarted = LinkSigner::with_state(key, 1, 1_000_000 + thirty, stored);
        assert!(restarted.require_proof());
        let next = router.sign(&frame(COMMAND_LONG, 255, 190, 3), t).unwrap();
        assert!(restarted.verify(&next, Instant::ZERO).is_ok());
        assert_eq!(
            restarted.verify(&captured, Instant::ZERO),
            Err(Rejection::Replayed)
        );
    }
}
