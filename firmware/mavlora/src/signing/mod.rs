//! MAVLink 2 message signing on the radio link (SORA requirement D, link security).
//!
//! [`LinkSigner`] signs what a side sends on the radio and verifies what it receives:
//! unsigned frames, bad signatures, replays (a timestamp not above the last one accepted
//! from the same link id and sender) and timestamps more than a minute ahead of our clock are
//! rejected and counted. Verified frames have their
//! signature stripped before they go on to the flight controller or ground station, which
//! do not hold the key.
//!
//! The SHA-256 signature itself is the `mavlink` crate's
//! (`MAVLinkV2MessageRaw::calculate_signature`); its `SigningData` is not used because it
//! reads the system clock, and the engines take time as an argument.
//!
//! An end whose state knows nothing of its peer (a first start, a lost state file) cannot
//! judge a frame's age by its clock: it takes nothing of the peer until the peer answered a
//! signed challenge with a fresh nonce ([`Handshake`], a `TIMESYNC` exchange), and from then
//! only frames the peer signed after its answer ([`LinkSigner::require_proof`]).
//!
//! Key files hold the 32-byte secret as 64 hexadecimal characters and an optional newline,
//! readable by their owner only ([`SigningKey::load`]). Timestamps follow the spec's rules
//! and survive restarts through [`SigningState`] (see [`signer`](LinkSigner)).

mod handshake;
mod key;
mod radio_leg;
mod signer;
mod state;

pub use handshake::{
    ANSWER_GAP, CHALLENGE_EVERY, Handshake, HandshakeFrame, answer_to, random_nonce,
};
pub use key::{FormatError, KeyError, SigningKey};
pub use radio_leg::{RadioLeg, is_link_frame};
pub use signer::{
    KeyAuthenticator, LinkSigner, MAX_AHEAD, NEW_STREAM_SLACK, Rejection, SigningStats,
};
pub use state::{AheadError, SigningState, StateError, StreamKey};

/// Signing settings of one radio link end.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SigningConfig {
    /// The shared secret.
    pub key: SigningKey,
    /// Link id stamped on our frames (different at each end helps reading logs).
    pub link_id: u8,
    /// Signing timestamp at engine time zero: 10 µs units since 2015-01-01 00:00 UTC.
    pub epoch: u64,
    /// What a previous run stored (its timestamp, the streams it accepted); empty at first.
    pub state: SigningState,
}

impl SigningConfig {
    /// The signer this configuration describes, resuming from its stored state.
    pub fn signer(&self) -> LinkSigner {
        LinkSigner::with_state(
            self.key.clone(),
            self.link_id,
            self.epoch,
            self.state.clone(),
        )
    }
}

#[cfg(test)]
mod mavlink1_tests;
