//! MAVLink 2 message signing on the radio link (SORA requirement D, link security).
//!
//! [`LinkSigner`] signs what a side sends on the radio and verifies what it receives:
//! unsigned frames, bad signatures and replays (a timestamp not above the last one accepted
//! from the same link id and sender) are rejected and counted. Verified frames have their
//! signature stripped before they go on to the flight controller or ground station, which
//! do not hold the key.
//!
//! The SHA-256 signature itself is the `mavlink` crate's
//! (`MAVLinkV2MessageRaw::calculate_signature`); its `SigningData` is not used because it
//! reads the system clock, and the engines take time as an argument.
//!
//! Key files hold the 32-byte secret as 64 hexadecimal characters (whitespace ignored), or
//! as 32 raw bytes.

mod key;
mod radio_leg;
mod signer;

pub use key::{KeyError, SigningKey};
pub use radio_leg::RadioLeg;
pub use signer::{LinkSigner, Rejection, SigningStats};

/// Signing settings of one radio link end.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SigningConfig {
    /// The shared secret.
    pub key: SigningKey,
    /// Link id stamped on our frames (different at each end helps reading logs).
    pub link_id: u8,
    /// Signing timestamp at engine time zero: 10 µs units since 2015-01-01 00:00 UTC.
    pub epoch: u64,
}

impl SigningConfig {
    /// The signer this configuration describes.
    pub fn signer(&self) -> LinkSigner {
        LinkSigner::new(self.key.clone(), self.link_id, self.epoch)
    }
}
