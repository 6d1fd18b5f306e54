//! What every frame crossing the radio gets, at both ends: frames leaving are made MAVLink 2
//! (a MAVLink 1 autopilot's frames too: same id, same payload), renumbered (so the far end
//! counts radio loss only) and signed unless the link was explicitly set up unsigned; frames
//! arriving are verified and stripped of their signature, or rejected and counted. A signed
//! leg whose state knows no peer proves the peer live first ([`Handshake`]).

use super::handshake::{Handshake, HandshakeFrame, random_nonce};
use super::{KeyAuthenticator, LinkSigner, Rejection, SigningConfig, SigningState, SigningStats};
use crate::dialect::MavMessage;
use crate::time::Instant;
use crate::wire::{FrameReader, OwnedFrame, Resequencer, to_v2};

/// One end's radio leg: version, sequence numbers and signing.
#[derive(Debug)]
pub struct RadioLeg {
    sequence: Resequencer,
    signer: Option<LinkSigner>,
    /// The freshness handshake (signed legs only).
    handshake: Option<Handshake>,
    /// Frames sent without a signature (signing off).
    sent_unsigned: u64,
    /// Frames [`RadioLeg::admit`] refused.
    dropped: u64,
}

impl RadioLeg {
    /// The reader of the radio's byte stream at this end: a frame counts as received only
    /// once the leg accepts it ([`FrameReader::counting_accepted`]), and on a signed link a
    /// waiting candidate with a frame signed by the link's key inside it is dropped at once
    /// ([`FrameReader::with_authenticator`]).
    pub fn reader(signing: Option<&SigningConfig>) -> FrameReader {
        let reader = FrameReader::counting_accepted();
        match signing {
            Some(s) => {
                reader.with_authenticator(std::sync::Arc::new(KeyAuthenticator(s.key.clone())))
            }
            None => reader,
        }
    }

    /// A leg that signs with `signing`, or passes frames unsigned when `None` (the binaries
    /// allow that only with `--unsigned`).
    pub fn new(signing: Option<&SigningConfig>) -> Self {
        Self::with_nonce(signing, random_nonce())
    }

    /// [`new`](Self::new) with the handshake's nonce given (tests).
    pub fn with_nonce(signing: Option<&SigningConfig>, nonce: i64) -> Self {
        let mut signer = signing.map(SigningConfig::signer);
        let handshake = signer.as_mut().map(|s| {
            let known = s.require_proof();
            if !known {
                tracing::warn!(
                    "no peer in the signing state: taking nothing from the radio until the \
                     peer proves it is live (answers our challenge)"
                );
            }
            Handshake::new(nonce, !known)
        });
        Self {
            sequence: Resequencer::new(),
            signer,
            handshake,
            sent_unsigned: 0,
            dropped: 0,
        }
    }

    /// The next handshake message for the radio at `now` (a challenge, or an answer to the
    /// peer's), to send as this end's own (system, component) with the commands' priority.
    pub fn poll_handshake(&mut self, now: Instant) -> Option<MavMessage> {
        let (Some(h), Some(s)) = (&mut self.handshake, &self.signer) else {
            return None;
        };
        // Our signing time, in the nanoseconds TIMESYNC carries.
        let time_ns = i64::try_from(s.timestamp(now).saturating_mul(10_000)).unwrap_or(i64::MAX);
        h.poll(now, time_ns)
    }

    /// When [`poll_handshake`](Self::poll_handshake) next has something.
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.handshake.as_ref().and_then(Handshake::poll_timeout)
    }

    /// Whether the peer is still to prove it is live (nothing of it is taken meanwhile).
    pub fn awaiting_proof(&self) -> bool {
        self.handshake.as_ref().is_some_and(Handshake::challenging)
    }

    /// Whether frames leaving are signed.
    pub fn signed(&self) -> bool {
        self.signer.is_some()
    }

    /// Bytes [`outgoing`](Self::outgoing) adds to a frame [`admit`](Self::admit) let through:
    /// the signature, when signing.
    pub fn frame_extra(&self) -> usize {
        if self.signed() {
            crate::wire::SIGNATURE_LEN
        } else {
            0
        }
    }

    /// Signing counters (only `sent_unsigned` when signing is off).
    pub fn stats(&self) -> SigningStats {
        let signer = self.signer.as_ref().map(|s| s.stats()).unwrap_or_default();
        SigningStats {
            sent_unsigned: self.sent_unsigned,
            unsignable: signer.unsignable + self.dropped,
            ..signer
        }
    }

    /// What the signer must store to resume after a restart; `None` when signing is off.
    pub fn signing_state(&self, now: Instant) -> Option<SigningState> {
        self.signer.as_ref().map(|s| s.state(now))
    }

    /// `frame` in the form it will take on the radio before its signature: MAVLink 2. Called
    /// before the radio budget so it counts the bytes that are sent. `None` (counted in
    /// `unsignable`) for a frame whose checksum no CRC_EXTRA reproduces: an unknown id's
    /// corrupted frame, which the reader could not check.
    pub fn admit(&mut self, frame: OwnedFrame) -> Option<OwnedFrame> {
        let v2 = to_v2(frame);
        if v2.is_none() {
            self.dropped += 1;
        }
        v2
    }

    /// `frame` as it goes on the radio; `None` if it cannot be made MAVLink 2 and signed
    /// (counted in `unsignable`), which a checksum-valid frame always can.
    pub fn outgoing(&mut self, frame: OwnedFrame, now: Instant) -> Option<OwnedFrame> {
        let mut frame = self.admit(frame)?;
        self.sequence.apply(&mut frame);
        match &mut self.signer {
            None => {
                self.sent_unsigned += 1;
                Some(frame)
            }
            Some(signer) => signer.sign(&frame, now),
        }
    }

    /// `frame` as read from the radio, verified and without its signature; `None` if it is
    /// rejected (unsigned, bad signature, replayed, stale, ahead, unproven: counted in
    /// [`RadioLeg::stats`]). A handshake frame is handled here and returned for the
    /// engine's counts only: [`is_link_frame`] says to go no further with it.
    pub fn incoming(&mut self, frame: OwnedFrame, now: Instant) -> Option<OwnedFrame> {
        let (Some(signer), Some(handshake)) = (&mut self.signer, &mut self.handshake) else {
            return Some(frame);
        };
        if let Some(kind) = HandshakeFrame::parse(&frame) {
            let plain = signer.verify_handshake(&frame, now).ok()?;
            match kind {
                HandshakeFrame::Challenge { nonce } => {
                    handshake.challenged(frame.system_id(), frame.component_id(), nonce);
                }
                HandshakeFrame::Answer { nonce } => {
                    if let Some((link, timestamp)) = super::signer::signed_timestamp(&frame)
                        && handshake.answered(nonce)
                    {
                        let stream = (link, frame.system_id(), frame.component_id());
                        if !signer.trusts(link) {
                            tracing::info!(
                                link,
                                "the peer proved it is live: taking its frames signed from now on"
                            );
                        }
                        signer.prove(stream, timestamp);
                    }
                }
            }
            return Some(plain);
        }
        match signer.verify(&frame, now) {
            Ok(plain) => Some(plain),
            Err(Rejection::Unproven) => {
                handshake.start(now);
                // On the 1st, 2nd, 4th, 8th... such frame.
                let n = signer.stats().unproven;
                if n.is_power_of_two() {
                    tracing::warn!(
                        refused = n,
                        "radio frame refused: waiting for the peer to prove it is live (this \
                         end has no signing state of it, and a recording would look the same)"
                    );
                }
                None
            }
            Err(Rejection::Ahead { seconds }) => {
                // A clock off by more than a minute stops the link: say which and where, on
                // the 1st, 2nd, 4th, 8th... such frame.
                let n = signer.stats().ahead;
                if n.is_power_of_two() {
                    tracing::warn!(
                        seconds,
                        refused = n,
                        "radio frame stamped more than a minute ahead of this clock refused: \
                         this clock is behind or the peer's is ahead (both must agree within a \
                         minute: NTP, GPS or an RTC)"
                    );
                }
                None
            }
            Err(why) => {
                tracing::debug!(?why, msgid = frame.message_id(), "radio frame rejected");
                None
            }
        }
    }
}

/// Whether `frame` (as [`RadioLeg::incoming`] returned it) is one of the handshake's: for the
/// two ends only, never passed on.
pub fn is_link_frame(frame: &OwnedFrame) -> bool {
    HandshakeFrame::parse(frame).is_some()
}

#[cfg(test)]
mod tests {
    use mavlink::MavlinkVersion;

    use super::*;
    use crate::signing::{SigningKey, answer_to};
    use crate::testutil::arm_command;
    use crate::wire::Sender;

    const CLOCK: u64 = 300_000_000_000;
    const SECOND: u64 = 100_000;

    fn config(link_id: u8, epoch: u64, state: SigningState) -> SigningConfig {
        SigningConfig {
            key: SigningKey([4; 32]),
            link_id,
            epoch,
            state,
        }
    }

    fn knowing(peer: u8) -> SigningState {
        let mut state = SigningState::default();
        state.streams.insert((peer, 255, 191), CLOCK - SECOND);
        state
    }

    /// `msg` from (`sys`, `comp`) as `leg` puts it on the radio at `now`.
    fn sent(leg: &mut RadioLeg, sys: u8, comp: u8, msg: &MavMessage, now: Instant) -> OwnedFrame {
        let frame = Sender::new(sys, comp, MavlinkVersion::V2).frame(msg);
        leg.outgoing(frame, now).unwrap()
    }

    /// The router's leg (its state knows the bridge) and a pilot's ARM it signed at world
    /// time 0; a bridge leg starting fresh 30 s later, challenging with `nonce`.
    fn setup(nonce: i64) -> (RadioLeg, OwnedFrame, RadioLeg) {
        let mut router = RadioLeg::with_nonce(Some(&config(2, CLOCK, knowing(1))), -1);
        let recorded = sent(&mut router, 255, 190, &arm_command(), Instant::ZERO);
        let bridge = RadioLeg::with_nonce(
            Some(&config(1, CLOCK + 30 * SECOND, SigningState::default())),
            nonce,
        );
        (router, recorded, bridge)
    }

    /// The fresh bridge's challenge, answered by `router` at router time `at`.
    fn answer(bridge: &mut RadioLeg, router: &mut RadioLeg, at: Instant) -> OwnedFrame {
        let challenge = bridge.poll_handshake(Instant::ZERO).expect("a challenge");
        let challenge = sent(bridge, 1, 191, &challenge, Instant::ZERO);
        let plain = router.incoming(challenge, at).expect("verified");
        assert!(is_link_frame(&plain));
        let answer = router.poll_handshake(at).expect("the answer");
        assert!(answer_to(&plain, 1).is_some(), "a challenge");
        sent(router, 255, 191, &answer, at)
    }

    /// Regression: a bridge without a state took a pilot's ARM recorded 30 s before (a
    /// stream it had not seen, within the spec's minute of its clock) and ran it.
    #[test]
    fn a_fresh_end_refuses_a_frame_recorded_30_s_before_it_started_before_and_after_the_handshake()
    {
        let (mut router, recorded, mut bridge) = setup(-77);
        assert!(bridge.awaiting_proof());
        assert_eq!(bridge.incoming(recorded.clone(), Instant::ZERO), None);
        assert_eq!(bridge.stats().unproven, 1);
        let t = Instant::from_secs(30);
        let answer = answer(&mut bridge, &mut router, t);
        let plain = bridge
            .incoming(answer, Instant::ZERO)
            .expect("the answer verifies");
        assert!(
            is_link_frame(&plain),
            "consumed by the ends, never passed on"
        );
        assert!(!bridge.awaiting_proof());
        assert_eq!(
            bridge.poll_handshake(Instant::from_secs(5)),
            None,
            "no more challenges"
        );
        assert_eq!(bridge.incoming(recorded, Instant::ZERO), None);
        assert_eq!(bridge.stats().replayed, 1, "below the floor the answer set");
        let live = sent(&mut router, 255, 190, &arm_command(), t);
        assert!(
            bridge.incoming(live, Instant::ZERO).is_some(),
            "signed after the answer"
        );
        // what it stores from now on knows the router
        let state = bridge.signing_state(Instant::ZERO).unwrap();
        assert!(state.streams.keys().any(|&(link, _, _)| link == 2));
    }

    #[test]
    fn an_answer_to_another_nonce_or_an_earlier_run_proves_nothing() {
        let (mut router, _, mut bridge) = setup(-77);
        // the bridge's previous run challenged with another nonce; its answer was recorded
        let (_, _, mut previous) = setup(-55);
        let old = answer(&mut previous, &mut router, Instant::from_secs(10));
        assert!(bridge.incoming(old, Instant::ZERO).is_some());
        assert!(bridge.awaiting_proof());
        // a fresh answer, but echoing a nonce that is not ours
        let wrong = MavMessage::TIMESYNC(crate::dialect::TIMESYNC_DATA {
            tc1: 5,
            ts1: -78,
            target_system: 1,
            target_component: 191,
        });
        let wrong = sent(&mut router, 255, 191, &wrong, Instant::from_secs(30));
        assert!(bridge.incoming(wrong, Instant::ZERO).is_some());
        assert!(bridge.awaiting_proof());
        let live = sent(
            &mut router,
            255,
            190,
            &arm_command(),
            Instant::from_secs(30),
        );
        assert_eq!(bridge.incoming(live, Instant::ZERO), None);
        assert_eq!(bridge.stats().unproven, 1);
        // the state it would store before the proof knows nothing of the router
        let state = bridge.signing_state(Instant::ZERO).unwrap();
        assert!(state.streams.is_empty(), "{state:?}");
    }

    /// An end whose state knows its peer behaves as the spec says: no challenge, a first
    /// frame of a new stream within the minute taken.
    #[test]
    fn an_end_with_a_stored_state_of_its_peer_does_not_challenge() {
        let (_, recorded, _) = setup(-77);
        let mut bridge =
            RadioLeg::with_nonce(Some(&config(1, CLOCK + 30 * SECOND, knowing(2))), -77);
        assert!(!bridge.awaiting_proof());
        assert_eq!(bridge.poll_handshake(Instant::ZERO), None);
        assert_eq!(bridge.poll_timeout(), None);
        assert!(bridge.incoming(recorded, Instant::ZERO).is_some());
        // and still answers a challenge (the router's, had it lost its own state)
        let mut fresh_router = RadioLeg::with_nonce(
            Some(&config(2, CLOCK + 30 * SECOND, SigningState::default())),
            -3,
        );
        let challenge = fresh_router.poll_handshake(Instant::ZERO).unwrap();
        let challenge = sent(&mut fresh_router, 255, 191, &challenge, Instant::ZERO);
        assert!(bridge.incoming(challenge, Instant::ZERO).is_some());
        assert!(bridge.poll_handshake(Instant::ZERO).is_some());
    }
}
