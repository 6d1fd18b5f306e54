//! Ground-station heartbeats towards the flight controller. The router sends them over the
//! radio sparsely (one per its `gcs_heartbeat_period`, which follows the radio budget); the
//! bridge regenerates them at the usual 1 Hz while the ground is heard, so the flight
//! controller's data-link loss detection still works: when the radio goes quiet,
//! regeneration stops one ground period and a margin after the last heartbeat heard.
//!
//! The hold is the trade-off between the two failures of a GCS failsafe: ended sooner, a
//! lost heartbeat or two leaves the flight controller a gap it takes for a link loss
//! (ArduPilot's `FS_GCS_TIMEOUT`, 5 s by default); ended later, a real loss reaches it later.
//! A fixed 7 s hold with the router's fixed 5 s period did both: a real loss reached the
//! autopilot up to 7 s late, and two lost heartbeats in a row (1 % of periods at 10 % loss)
//! left it an 8 s gap. The bridge measures the router's period (the shortest interval
//! between the ground heartbeats it heard lately), so a router that sends once a second (a
//! SiK link's budget) gets a 3 s hold: a loss reaches the autopilot at most 3 s late, and a
//! false failsafe needs seven heartbeats lost in a row.

use std::collections::VecDeque;

use crate::time::Duration;

use mavlink::MavlinkVersion;

use crate::dialect::{HEARTBEAT_DATA, MavMessage};
use crate::time::Instant;
use crate::wire::{OwnedFrame, Sender};

/// Intervals between heard ground heartbeats the period is measured over: the shortest of
/// them is the router's period unless all eight were stretched by loss (10⁻⁸ at 10 %).
const INTERVALS_KEPT: usize = 8;

/// Sans-IO regenerator of the ground station's heartbeat.
#[derive(Debug)]
pub struct GcsHeartbeat {
    period: Duration,
    margin: Duration,
    /// The router's period until two heartbeats have been heard: the longest it uses by
    /// default.
    assumed_ground_period: Duration,
    intervals: VecDeque<Duration>,
    last: Option<(HEARTBEAT_DATA, Instant)>,
    sender: Option<Sender>,
    next: Option<Instant>,
}

impl GcsHeartbeat {
    /// A regenerator that has heard nothing: it sends one heartbeat each `period` until
    /// `margin` after the ground's next one was due (`assumed_ground_period` until it has
    /// measured the ground's period).
    pub fn new(period: Duration, margin: Duration, assumed_ground_period: Duration) -> Self {
        Self {
            period,
            margin,
            assumed_ground_period,
            intervals: VecDeque::new(),
            last: None,
            sender: None,
            next: None,
        }
    }

    /// The ground's heartbeat period over the radio, as measured (never below our own).
    pub fn ground_period(&self) -> Duration {
        self.intervals
            .iter()
            .min()
            .copied()
            .unwrap_or(self.assumed_ground_period)
            .max(self.period)
    }

    /// How long after the last ground heartbeat heard regeneration goes on.
    pub fn hold(&self) -> Duration {
        self.ground_period() + self.margin
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
        if let Some((_, before)) = &self.last {
            if self.intervals.len() == INTERVALS_KEPT {
                self.intervals.pop_front();
            }
            self.intervals
                .push_back(now.saturating_duration_since(*before));
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
        if now.saturating_duration_since(heard_at) > self.hold() {
            self.next = None;
            return None;
        }
        self.next = Some((next + self.period).max(now));
        let sender = self.sender.as_mut()?;
        Some(sender.frame(&MavMessage::HEARTBEAT(hb)))
    }
}

#[cfg(test)]
mod tests;
