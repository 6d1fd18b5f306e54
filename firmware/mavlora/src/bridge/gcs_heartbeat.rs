//! Ground-station heartbeats towards the flight controller. The router sends them over the
//! radio sparsely (they are periodic traffic, cut like the drone's); the bridge regenerates
//! them at the usual 1 Hz while the ground is heard, so the flight controller's data-link
//! loss detection still works: when the radio goes quiet, regeneration stops after `hold`.

use crate::time::Duration;

use mavlink::MavlinkVersion;

use crate::dialect::{HEARTBEAT_DATA, MavMessage};
use crate::time::Instant;
use crate::wire::{OwnedFrame, Sender};

/// Sans-IO regenerator of the ground station's heartbeat.
#[derive(Debug)]
pub struct GcsHeartbeat {
    period: Duration,
    hold: Duration,
    last: Option<(HEARTBEAT_DATA, Instant)>,
    sender: Option<Sender>,
    next: Option<Instant>,
}

impl GcsHeartbeat {
    /// A regenerator that has heard nothing.
    pub fn new(period: Duration, hold: Duration) -> Self {
        Self {
            period,
            hold,
            last: None,
            sender: None,
            next: None,
        }
    }

    /// A ground heartbeat arrived from the radio (it is forwarded as is by the caller).
    pub fn heard(&mut self, frame: &OwnedFrame, hb: HEARTBEAT_DATA, now: Instant) {
        let same = self.sender.as_ref().is_some_and(|s| {
            (s.system(), s.component()) == (frame.system_id(), frame.component_id())
        });
        if !same {
            let mut sender =
                Sender::new(frame.system_id(), frame.component_id(), MavlinkVersion::V2);
            sender.set_next_sequence(frame.sequence().wrapping_add(1));
            self.sender = Some(sender);
        }
        self.last = Some((hb, now));
        self.next = Some(now + self.period);
    }

    /// When the next regenerated heartbeat is due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.next
    }

    /// A regenerated heartbeat if one is due at `now`.
    pub fn poll(&mut self, now: Instant) -> Option<OwnedFrame> {
        let next = self.next?;
        if now < next {
            return None;
        }
        let (hb, heard_at) = self.last.clone()?;
        if now.saturating_duration_since(heard_at) > self.hold {
            self.next = None;
            return None;
        }
        self.next = Some((next + self.period).max(now));
        let sender = self.sender.as_mut()?;
        Some(sender.frame(&MavMessage::HEARTBEAT(hb)))
    }
}
