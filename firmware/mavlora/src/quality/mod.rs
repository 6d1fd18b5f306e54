//! Link quality in both directions: each side reports what it hears in `LINK_QUALITY`
//! (id 15) and learns what the other side hears.

mod engine;
mod rssi;

pub use engine::{LinkQuality, LinkQualityConfig, PeerReport, PeerState};
pub use rssi::RssiScale;
