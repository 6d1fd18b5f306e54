//! What every frame crossing the radio gets, at both ends: frames leaving are renumbered
//! (so the far end counts radio loss only) and signed when signing is on; frames arriving are
//! verified and stripped of their signature, or rejected and counted.

use super::{LinkSigner, SigningConfig, SigningStats};
use crate::time::Instant;
use crate::wire::{OwnedFrame, Resequencer};

/// One end's radio leg: sequence numbers and signing.
#[derive(Debug)]
pub struct RadioLeg {
    sequence: Resequencer,
    signer: Option<LinkSigner>,
}

impl RadioLeg {
    /// A leg that signs with `signing`, or passes frames unsigned when `None`.
    pub fn new(signing: Option<&SigningConfig>) -> Self {
        Self {
            sequence: Resequencer::new(),
            signer: signing.map(SigningConfig::signer),
        }
    }

    /// Signing counters (all zero when signing is off).
    pub fn stats(&self) -> SigningStats {
        self.signer.as_ref().map(|s| s.stats()).unwrap_or_default()
    }

    /// `frame` as it goes on the radio; `None` if it cannot be signed (MAVLink 1, unknown
    /// id): the far end would reject it anyway.
    pub fn outgoing(&mut self, mut frame: OwnedFrame, now: Instant) -> Option<OwnedFrame> {
        self.sequence.apply(&mut frame);
        match &mut self.signer {
            None => Some(frame),
            Some(signer) => signer.sign(&frame, now),
        }
    }

    /// `frame` as read from the radio, verified and without its signature; `None` if it is
    /// rejected (unsigned, bad signature, replayed: counted in [`RadioLeg::stats`]).
    pub fn incoming(&mut self, frame: OwnedFrame, now: Instant) -> Option<OwnedFrame> {
        let Some(signer) = &mut self.signer else {
            return Some(frame);
        };
        match signer.verify(&frame, now) {
            Ok(plain) => Some(plain),
            Err(why) => {
                tracing::debug!(?why, msgid = frame.message_id(), "radio frame rejected");
                None
            }
        }
    }
}
