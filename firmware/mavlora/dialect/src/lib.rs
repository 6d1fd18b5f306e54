//! MavLora's MAVLink dialect: everything in `common.xml` plus
//! [`MAVLORA_COMPACT`](mavlora::MAVLORA_COMPACT_DATA) (id 14),
//! [`LINK_QUALITY`](mavlora::LINK_QUALITY_DATA) (id 15),
//! [`MAVLORA_TELEMETRY`](mavlora::MAVLORA_TELEMETRY_DATA) (id 16),
//! [`MAVLORA_POSITION_BATCH`](mavlora::MAVLORA_POSITION_BATCH_DATA) (id 17),
//! [`MAVLORA_STATUS`](mavlora::MAVLORA_STATUS_DATA) (id 18) and
//! [`MAVLORA_MISSION_ITEMS`](mavlora::MAVLORA_MISSION_ITEMS_DATA) (id 19).
//!
//! Generated at build time by `mavlink-bindgen` from `message_definitions/mavlora.xml` (in the
//! `mavlora` crate directory), so the Rust types, the CRC_EXTRA values and the XML that
//! pymavlink's `mavgen` reads cannot drift apart. Messages use the `mavlink` crate's traits
//! ([`mavlink_core::Message`], [`mavlink_core::MessageData`]).

include!(concat!(env!("OUT_DIR"), "/dialect_mod.rs"));

/// The CRC_EXTRA of the messages ArduPilot speaks (`ardupilotmega.xml` and its includes,
/// `common.xml` among them): a third of a real ArduPilot stream is its own messages (SIMSTATE,
/// AHRS2, EKF_STATUS_REPORT, ...), which a reader must check and a converter rebuild without
/// decoding them.
pub mod ardupilotmega {
    include!(concat!(env!("OUT_DIR"), "/ardupilotmega_crc_extra.rs"));
}

pub use mavlora::*;
