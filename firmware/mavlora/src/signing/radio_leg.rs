//! What every frame crossing the radio gets, at both ends: frames leaving are made MAVLink 2
//! (a MAVLink 1 autopilot's frames too: same id, same payload), renumbered (so the far end
//! counts radio loss only) and signed unless the link was explicitly set up unsigned; frames
//! arriving are verified and stripped of their signature, or rejected and counted.

use super::{KeyAuthenticator, LinkSigner, Rejection, SigningConfig, SigningState, SigningStats};
use crate::time::Instant;
use crate::wire::{FrameReader, OwnedFrame, Resequencer, to_v2};

/// One end's radio leg: version, sequence numbers and signing.
#[derive(Debug)]
pub struct RadioLeg {
    sequence: Resequencer,
    signer: Option<LinkSigner>,
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
        Self {
            sequence: Resequencer::new(),
            signer: signing.map(SigningConfig::signer),
            sent_unsigned: 0,
            dropped: 0,
        }
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
    /// rejected (unsigned, bad signature, replayed, stale, ahead: counted in
    /// [`RadioLeg::stats`]).
    pub fn incoming(&mut self, frame: OwnedFrame, now: Instant) -> Option<OwnedFrame> {
        let Some(signer) = &mut self.signer else {
            return Some(frame);
        };
        match signer.verify(&frame, now) {
            Ok(plain) => Some(plain),
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
