//! The autopilot side of the MAVLink mission protocol, for any simulated flight controller:
//! one stored plan per `mission_type` (mission, fence, rally), upload (the autopilot drives
//! it: requests each item, re-requests after `item_retry` whatever the link, as PX4 does
//! with 250 ms), download, clear, cancel by the peer's `MISSION_ACK`, and a reboot that
//! drops an upload in progress (the stored plans survive, as on an SD card or in EEPROM).
//!
//! The flight controller owns its framing and ids: it hands decoded messages to
//! [`MissionStore::handle`] and sends what [`MissionStore::poll_message`] returns.

use mavlora::Duration;
use mavlora::Instant;
use mavlora::dialect::{
    MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA,
    MavMessage, MavMissionResult, MavMissionType,
};
use std::collections::VecDeque;

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MissionStoreStats {
    /// Item requests sent (retries included).
    pub item_requests: u64,
    /// Items received that were not the one asked for (duplicates, another type).
    pub duplicate_items: u64,
    /// Uploads accepted (any type).
    pub accepted: u64,
    /// Uploads the peer cancelled.
    pub cancelled: u64,
    /// Uploads dropped by a reboot.
    pub lost_to_reboot: u64,
}

#[derive(Debug)]
struct Upload {
    peer: (u8, u8),
    mission_type: MavMissionType,
    count: u16,
    items: Vec<MISSION_ITEM_INT_DATA>,
    requested_at: Instant,
    last_progress: Instant,
}

/// One autopilot's stored plans and its side of the protocol.
#[derive(Debug)]
pub struct MissionStore {
    system: u8,
    plans: [Vec<MISSION_ITEM_INT_DATA>; 3],
    upload: Option<Upload>,
    item_retry: Duration,
    give_up: Duration,
    out: VecDeque<MavMessage>,
    stats: MissionStoreStats,
}

fn slot(t: MavMissionType) -> Option<usize> {
    match t {
        MavMissionType::MAV_MISSION_TYPE_MISSION => Some(0),
        MavMissionType::MAV_MISSION_TYPE_FENCE => Some(1),
        MavMissionType::MAV_MISSION_TYPE_RALLY => Some(2),
        MavMissionType::MAV_MISSION_TYPE_ALL => None,
    }
}

impl MissionStore {
    /// Plans of autopilot `system`; an upload's item is asked again after `item_retry`
    /// (PX4: 250 ms), an upload without progress for `give_up` (PX4: 5 s) is dropped.
    pub fn new(system: u8, item_retry: Duration, give_up: Duration) -> Self {
        Self {
            system,
            plans: Default::default(),
            upload: None,
            item_retry,
            give_up,
            out: VecDeque::new(),
            stats: MissionStoreStats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> MissionStoreStats {
        self.stats
    }

    /// The stored plan of `mission_type` (empty for `ALL`).
    pub fn plan(&self, mission_type: MavMissionType) -> &[MISSION_ITEM_INT_DATA] {
        slot(mission_type).map_or(&[], |i| &self.plans[i][..])
    }

    /// Whether an upload is in progress.
    pub fn uploading(&self) -> bool {
        self.upload.is_some()
    }

    /// The autopilot rebooted: an upload in progress is gone, the stored plans are not.
    pub fn reboot(&mut self) {
        if self.upload.take().is_some() {
            self.stats.lost_to_reboot += 1;
        }
        self.out.clear();
    }

    /// A message from `from` (system, component); returns whether it was a mission message
    /// for this autopilot.
    pub fn handle(&mut self, from: (u8, u8), msg: &MavMessage, now: Instant) -> bool {
        let me = self.system;
        match msg {
            MavMessage::MISSION_COUNT(c) if c.target_system == me => {
                // A new count always starts a new upload (the protocol's restart).
                self.upload = Some(Upload {
                    peer: from,
                    mission_type: c.mission_type,
                    count: c.count,
                    items: Vec::with_capacity(c.count.into()),
                    requested_at: now,
                    last_progress: now,
                });
                self.request_next(now);
            }
            MavMessage::MISSION_ITEM_INT(item) if item.target_system == me => {
                let Some(up) = &mut self.upload else {
                    self.stats.duplicate_items += 1;
                    return true;
                };
                if up.peer != from
                    || item.mission_type != up.mission_type
                    || usize::from(item.seq) != up.items.len()
                {
                    self.stats.duplicate_items += 1;
                    return true;
                }
                up.items.push(item.clone());
                up.last_progress = now;
                self.request_next(now);
            }
            MavMessage::MISSION_ACK(a) if a.target_system == me => {
                if let Some(up) = &self.upload
                    && up.peer == from
                    && a.mavtype != MavMissionResult::MAV_MISSION_ACCEPTED
                {
                    self.upload = None;
                    self.stats.cancelled += 1;
                }
            }
            // Download and clear: answered once each; only the requester retries.
            MavMessage::MISSION_REQUEST_LIST(r) if r.target_system == me => {
                let count = self.plan(r.mission_type).len() as u16;
                self.out
                    .push_back(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                        count,
                        target_system: from.0,
                        target_component: from.1,
                        mission_type: r.mission_type,
                        ..Default::default()
                    }));
            }
            MavMessage::MISSION_REQUEST_INT(r) if r.target_system == me => {
                if let Some(item) = self.plan(r.mission_type).get(usize::from(r.seq)) {
                    let item = MISSION_ITEM_INT_DATA {
                        target_system: from.0,
                        target_component: from.1,
                        ..item.clone()
                    };
                    self.out.push_back(MavMessage::MISSION_ITEM_INT(item));
                }
            }
            MavMessage::MISSION_CLEAR_ALL(c) if c.target_system == me => {
                match slot(c.mission_type) {
                    Some(i) => self.plans[i].clear(),
                    None => self.plans.iter_mut().for_each(Vec::clear),
                }
                self.ack(from, c.mission_type, MavMissionResult::MAV_MISSION_ACCEPTED);
            }
            _ => return false,
        }
        true
    }

    fn ack(&mut self, to: (u8, u8), mission_type: MavMissionType, result: MavMissionResult) {
        self.out
            .push_back(MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                target_system: to.0,
                target_component: to.1,
                mavtype: result,
                mission_type,
                ..Default::default()
            }));
    }

    // `..Default::default()` on a full literal: the dialect may grow.
    #[allow(clippy::needless_update)]
    fn request_next(&mut self, now: Instant) {
        let Some(up) = &mut self.upload else { return };
        let (peer, mission_type) = (up.peer, up.mission_type);
        if up.items.len() == usize::from(up.count) {
            let items = std::mem::take(&mut up.items);
            self.upload = None;
            let result = match slot(mission_type) {
                Some(i) => {
                    self.plans[i] = items;
                    self.stats.accepted += 1;
                    MavMissionResult::MAV_MISSION_ACCEPTED
                }
                None => MavMissionResult::MAV_MISSION_UNSUPPORTED,
            };
            self.ack(peer, mission_type, result);
            return;
        }
        up.requested_at = now;
        let seq = up.items.len() as u16;
        self.stats.item_requests += 1;
        self.out
            .push_back(MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq,
                target_system: peer.0,
                target_component: peer.1,
                mission_type,
                ..Default::default()
            }));
    }

    /// When an item retry is due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.upload
            .as_ref()
            .map(|u| u.requested_at + self.item_retry)
    }

    /// Item retries and give-ups due at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        if let Some(up) = &self.upload {
            if now.saturating_duration_since(up.last_progress) > self.give_up {
                self.upload = None;
            } else if now >= up.requested_at + self.item_retry {
                self.request_next(now);
            }
        }
    }

    /// The next message to send.
    pub fn poll_message(&mut self) -> Option<MavMessage> {
        self.out.pop_front()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlora::dialect::MISSION_CLEAR_ALL_DATA;

    const GCS: (u8, u8) = (255, 190);

    fn count(n: u16, t: MavMissionType) -> MavMessage {
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: n,
            target_system: 1,
            mission_type: t,
            ..Default::default()
        })
    }

    fn item(seq: u16, t: MavMissionType) -> MavMessage {
        MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
            seq,
            target_system: 1,
            mission_type: t,
            x: i32::from(seq) + 7,
            ..Default::default()
        })
    }

    #[test]
    fn a_fence_upload_leaves_the_mission_alone_and_clear_takes_one_type() {
        let mut s = MissionStore::new(1, Duration::from_millis(250), Duration::from_secs(5));
        let t0 = Instant::ZERO;
        use MavMissionType::*;
        s.handle(GCS, &count(2, MAV_MISSION_TYPE_MISSION), t0);
        s.handle(GCS, &item(0, MAV_MISSION_TYPE_MISSION), t0);
        s.handle(GCS, &item(1, MAV_MISSION_TYPE_MISSION), t0);
        s.handle(GCS, &count(1, MAV_MISSION_TYPE_FENCE), t0);
        // a mission item during the fence upload is not a fence item
        s.handle(GCS, &item(0, MAV_MISSION_TYPE_MISSION), t0);
        s.handle(GCS, &item(0, MAV_MISSION_TYPE_FENCE), t0);
        assert_eq!(s.plan(MAV_MISSION_TYPE_MISSION).len(), 2);
        assert_eq!(s.plan(MAV_MISSION_TYPE_FENCE).len(), 1);
        let clear = MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
            target_system: 1,
            mission_type: MAV_MISSION_TYPE_FENCE,
            ..Default::default()
        });
        s.handle(GCS, &clear, t0);
        assert!(s.plan(MAV_MISSION_TYPE_FENCE).is_empty());
        assert_eq!(s.plan(MAV_MISSION_TYPE_MISSION).len(), 2);
    }

    #[test]
    fn reboot_drops_the_upload_but_keeps_the_plans() {
        use MavMissionType::*;
        let mut s = MissionStore::new(1, Duration::from_millis(250), Duration::from_secs(5));
        let t0 = Instant::ZERO;
        s.handle(GCS, &count(1, MAV_MISSION_TYPE_MISSION), t0);
        s.handle(GCS, &item(0, MAV_MISSION_TYPE_MISSION), t0);
        s.handle(GCS, &count(3, MAV_MISSION_TYPE_MISSION), t0);
        s.handle(GCS, &item(0, MAV_MISSION_TYPE_MISSION), t0);
        s.reboot();
        assert!(!s.uploading());
        assert_eq!(s.plan(MAV_MISSION_TYPE_MISSION).len(), 1);
        // items after the reboot do not complete the old upload
        s.handle(GCS, &item(1, MAV_MISSION_TYPE_MISSION), t0);
        assert_eq!(s.plan(MAV_MISSION_TYPE_MISSION).len(), 1);
    }
}
