//! A ground station's own MAVLink version: the engine makes MAVLink 2, and each endpoint
//! gives a station that speaks MAVLink 1 its own MAVLink 1 copy.

use crate::wire::{Frame, OwnedFrame, to_v1};

/// `frame` as MAVLink 1; `None` when MAVLink 1 cannot carry it (a message id above 255, or a
/// frame signed for the ground).
pub fn as_v1(frame: &[u8]) -> Option<Vec<u8>> {
    let owned: OwnedFrame = Frame::new_checked(frame.to_vec()).ok()?;
    to_v1(owned).map(|f| f.as_bytes().to_vec())
}
