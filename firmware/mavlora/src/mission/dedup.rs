//! The router's side of the relay: a ground station retries `MISSION_COUNT` and items on its
//! own timer (1.5 s in the spec, 250 ms in some tools), blind to the radio. A retransmission
//! of a frame forwarded less than one radio round trip ago only adds to the queue; it is
//! dropped and counted, unless the vehicle asked for that item again in between (then it is
//! the answer, not a duplicate). The round trip is measured from an item forwarded to the
//! request for the next one coming back.

use crate::time::Duration;

use super::rtt::RttEstimator;
use crate::dialect::MavMessage;
use crate::time::Instant;
use crate::wire::ids;

/// Sans-IO duplicate suppressor for mission uploads passing through the router.
#[derive(Debug)]
pub struct DuplicateSuppressor {
    rtt: RttEstimator,
    /// (message id, seq or count) of the last forwarded upload frame, when, and whether it was
    /// a retransmission (Karn: no RTT sample from those).
    last: Option<(u32, u16, Instant, bool)>,
    suppressed: u64,
}

impl DuplicateSuppressor {
    /// A suppressor whose round-trip estimate starts at `initial`.
    pub fn new(initial: Duration, min: Duration, max: Duration) -> Self {
        Self {
            rtt: RttEstimator::new(initial, min, max),
            last: None,
            suppressed: 0,
        }
    }

    /// Frames dropped as duplicates so far.
    pub fn suppressed(&self) -> u64 {
        self.suppressed
    }

    /// The round-trip estimate.
    pub fn rtt(&self) -> &RttEstimator {
        &self.rtt
    }

    /// A frame from the ground station: `false` if it is a retransmission to drop.
    pub fn from_ground(&mut self, msg: &MavMessage, now: Instant) -> bool {
        let key = match msg {
            MavMessage::MISSION_COUNT(m) => (ids::MISSION_COUNT, m.count),
            MavMessage::MISSION_ITEM_INT(m) => (ids::MISSION_ITEM_INT, m.seq),
            _ => return true,
        };
        if let Some((id, n, at, _)) = self.last
            && (id, n) == key
        {
            if now.saturating_duration_since(at) < self.rtt.rto() {
                self.suppressed += 1;
                return false;
            }
            self.last = Some((id, n, now, true));
            return true;
        }
        self.last = Some((key.0, key.1, now, false));
        true
    }

    /// A frame from the radio: a request for the item after the one forwarded last is a
    /// round-trip sample.
    // MISSION_REQUEST is deprecated but older autopilots and tools still send it.
    #[allow(deprecated)]
    pub fn from_radio(&mut self, msg: &MavMessage, now: Instant) {
        let seq = match msg {
            MavMessage::MISSION_REQUEST_INT(m) => m.seq,
            MavMessage::MISSION_REQUEST(m) => m.seq,
            _ => return,
        };
        if let Some((id, n, at, retransmitted)) = self.last {
            if id == ids::MISSION_ITEM_INT && seq == n {
                // The vehicle asks again for the item we forwarded (it was lost on the radio):
                // the ground's answer is wanted, not a duplicate.
                self.last = None;
                return;
            }
            let answers = (id == ids::MISSION_COUNT && seq == 0)
                || (id == ids::MISSION_ITEM_INT && seq == n.wrapping_add(1));
            if answers && !retransmitted {
                self.rtt.sample(now.saturating_duration_since(at));
                self.last = Some((id, n, at, true));
            }
        }
    }
}
