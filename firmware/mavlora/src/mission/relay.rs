//! The bridge's mission relay: receiver on the radio leg, sender on the wire leg.

use crate::time::Duration;
use std::collections::VecDeque;

use tracing::{debug, info, warn};

use super::rtt::RttEstimator;
use crate::dialect::{
    MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA,
    MavMessage, MavMissionResult,
};
use crate::time::Instant;

/// Relay timeouts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionConfig {
    /// Radio round trip assumed before one is measured.
    pub initial_rtt: Duration,
    /// Lower bound of the radio timeout (queueing jitter).
    pub min_rto: Duration,
    /// Upper bound of the radio timeout after backoff.
    pub max_rto: Duration,
    /// Requests sent for one item over the radio before the upload is abandoned.
    pub radio_attempts: u32,
    /// Wire leg timeout (MAVLink mission protocol default: 1500 ms).
    pub wire_timeout: Duration,
    /// Wire leg attempts per step (protocol: up to 5 retries).
    pub wire_attempts: u32,
}

impl Default for MissionConfig {
    fn default() -> Self {
        Self {
            initial_rtt: Duration::from_millis(1500),
            min_rto: Duration::from_millis(300),
            max_rto: Duration::from_secs(8),
            radio_attempts: 10,
            wire_timeout: Duration::from_millis(1500),
            wire_attempts: 6,
        }
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MissionStats {
    /// Item requests sent over the radio, first attempts.
    pub radio_requests: u64,
    /// Item requests sent again after a timeout.
    pub radio_retries: u64,
    /// Items received over the radio.
    pub radio_items: u64,
    /// Items received that we already had (the ground retried too early).
    pub radio_duplicate_items: u64,
    /// Items sent to the flight controller (its retries included).
    pub wire_items: u64,
    /// Uploads the flight controller accepted.
    pub completed: u64,
    /// Uploads that failed on either leg.
    pub failed: u64,
}

#[derive(Debug)]
enum Radio {
    Idle,
    Receiving {
        ground: (u8, u8),
        items: Vec<MISSION_ITEM_INT_DATA>,
        count: u16,
        sent_at: Instant,
        attempts: u32,
    },
    /// All items in, the wire leg runs; the ground waits for our ack.
    Forwarding {
        ground: (u8, u8),
        count: u16,
    },
    /// Finished: a retried last item from the ground means our ack was lost.
    Done {
        ground: (u8, u8),
        count: u16,
        result: MavMissionResult,
    },
}

#[derive(Debug)]
enum Wire {
    Idle,
    Sending {
        items: Vec<MISSION_ITEM_INT_DATA>,
        /// Last step sent: `None` for MISSION_COUNT, else the item seq.
        last: Option<u16>,
        at: Instant,
        attempts: u32,
    },
}

/// Sans-IO mission relay of the bridge.
///
/// Feed it mission frames from the radio ([`handle_radio`](Self::handle_radio)) and those
/// the flight controller addresses to the bridge ([`handle_fc`](Self::handle_fc)); take what
/// to send with [`poll_radio`](Self::poll_radio) / [`poll_fc`](Self::poll_fc); wake it at
/// [`poll_timeout`](Self::poll_timeout) with [`handle_timeout`](Self::handle_timeout).
#[derive(Debug)]
pub struct MissionRelay {
    config: MissionConfig,
    rtt: RttEstimator,
    radio: Radio,
    wire: Wire,
    to_radio: VecDeque<MavMessage>,
    to_fc: VecDeque<MavMessage>,
    stats: MissionStats,
}

impl MissionRelay {
    /// An idle relay.
    pub fn new(config: MissionConfig) -> Self {
        Self {
            rtt: RttEstimator::new(config.initial_rtt, config.min_rto, config.max_rto),
            config,
            radio: Radio::Idle,
            wire: Wire::Idle,
            to_radio: VecDeque::new(),
            to_fc: VecDeque::new(),
            stats: MissionStats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> MissionStats {
        self.stats
    }

    /// The radio round-trip estimate.
    pub fn rtt(&self) -> &RttEstimator {
        &self.rtt
    }

    /// A message from the radio sent by `from` (system, component). Returns whether the relay
    /// took it (else the caller forwards it to the flight controller).
    pub fn handle_radio(&mut self, now: Instant, from: (u8, u8), msg: &MavMessage) -> bool {
        match msg {
            MavMessage::MISSION_COUNT(c) => {
                if let Radio::Receiving { ground, count, .. } = &self.radio
                    && *ground == from
                    && *count == c.count
                {
                    debug!("ground repeated MISSION_COUNT, our request is on its way");
                    return true;
                }
                info!(count = c.count, "mission upload from the ground");
                self.radio = Radio::Receiving {
                    ground: from,
                    items: Vec::with_capacity(c.count.into()),
                    count: c.count,
                    sent_at: now,
                    attempts: 0,
                };
                self.wire = Wire::Idle;
                self.advance_radio(now);
                true
            }
            MavMessage::MISSION_ITEM_INT(item) => {
                self.radio_item(from, item, now);
                true
            }
            _ => false,
        }
    }

    fn radio_item(&mut self, from: (u8, u8), item: &MISSION_ITEM_INT_DATA, now: Instant) {
        match &mut self.radio {
            Radio::Receiving {
                ground,
                items,
                sent_at,
                attempts,
                ..
            } if *ground == from => {
                let next = items.len() as u16;
                if item.seq != next {
                    if item.seq < next {
                        self.stats.radio_duplicate_items += 1;
                    }
                    let overdue = now.saturating_duration_since(*sent_at)
                        >= self.rtt.srtt().unwrap_or(self.rtt.rto());
                    if item.seq + 1 == next && overdue {
                        // The ground repeats the item we already have although our request
                        // for the next one had time to arrive: it was lost. Ask again now
                        // rather than at our own timeout (which may have backed off beyond the
                        // ground's patience). A repeat arriving sooner is an echo of an
                        // earlier double send; answering it would double every later item.
                        *sent_at = now;
                        *attempts += 1;
                        self.stats.radio_retries += 1;
                        self.to_radio.push_back(request(from, next));
                    }
                    return;
                }
                self.stats.radio_items += 1;
                if *attempts == 1 {
                    // Karn's rule: only unambiguous round trips are samples.
                    self.rtt.sample(now.saturating_duration_since(*sent_at));
                }
                items.push(item.clone());
                self.advance_radio(now);
            }
            Radio::Done {
                ground,
                count,
                result,
            } if *ground == from && item.seq + 1 == *count => {
                self.stats.radio_duplicate_items += 1;
                let ack = ack(*ground, *result);
                self.to_radio.push_back(ack);
            }
            _ => self.stats.radio_duplicate_items += 1,
        }
    }

    /// Requests the next item, or hands the full mission to the wire leg.
    fn advance_radio(&mut self, now: Instant) {
        let Radio::Receiving {
            ground,
            items,
            count,
            sent_at,
            attempts,
        } = &mut self.radio
        else {
            return;
        };
        if items.len() < usize::from(*count) {
            *sent_at = now;
            *attempts = 1;
            self.stats.radio_requests += 1;
            self.to_radio
                .push_back(request(*ground, items.len() as u16));
            return;
        }
        let (ground, count) = (*ground, *count);
        let items = std::mem::take(items);
        info!(
            count,
            "mission received over the radio, uploading to the flight controller"
        );
        self.radio = Radio::Forwarding { ground, count };
        self.to_fc
            .push_back(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count,
                target_system: 0,
                target_component: 0,
                ..Default::default()
            }));
        self.wire = Wire::Sending {
            items,
            last: None,
            at: now,
            attempts: 1,
        };
    }

    /// A mission message the flight controller addressed to the bridge. Returns whether the
    /// relay took it.
    // MISSION_REQUEST is deprecated but older autopilots and tools still send it.
    #[allow(deprecated)]
    pub fn handle_fc(&mut self, now: Instant, msg: &MavMessage) -> bool {
        let Wire::Sending {
            items,
            last,
            at,
            attempts,
        } = &mut self.wire
        else {
            return false;
        };
        let seq = match msg {
            MavMessage::MISSION_REQUEST_INT(r) => r.seq,
            MavMessage::MISSION_REQUEST(r) => r.seq,
            MavMessage::MISSION_ACK(a) => {
                let result = a.mavtype;
                self.wire = Wire::Idle;
                self.finish(result);
                return true;
            }
            _ => return false,
        };
        let Some(item) = items.get(usize::from(seq)) else {
            return true;
        };
        // Answer every request, repeats included: on the wire they cost nothing.
        self.to_fc
            .push_back(MavMessage::MISSION_ITEM_INT(item.clone()));
        self.stats.wire_items += 1;
        if *last != Some(seq) {
            *attempts = 1;
        }
        *last = Some(seq);
        *at = now;
        true
    }

    fn finish(&mut self, result: MavMissionResult) {
        let Radio::Forwarding { ground, count } = self.radio else {
            return;
        };
        if result == MavMissionResult::MAV_MISSION_ACCEPTED {
            self.stats.completed += 1;
            info!(count, "flight controller accepted the mission");
        } else {
            self.stats.failed += 1;
            warn!(?result, "flight controller refused the mission");
        }
        self.to_radio.push_back(ack(ground, result));
        self.radio = Radio::Done {
            ground,
            count,
            result,
        };
    }

    /// When a timeout is due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let radio = match &self.radio {
            Radio::Receiving { sent_at, .. } => Some(*sent_at + self.rtt.rto()),
            _ => None,
        };
        let wire = match &self.wire {
            Wire::Sending { at, .. } => Some(*at + self.config.wire_timeout),
            Wire::Idle => None,
        };
        radio.into_iter().chain(wire).min()
    }

    /// Retries or gives up whatever timed out at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        if let Radio::Receiving {
            ground,
            items,
            sent_at,
            attempts,
            ..
        } = &mut self.radio
            && now >= *sent_at + self.rtt.rto()
        {
            let ground = *ground;
            if *attempts >= self.config.radio_attempts {
                warn!(seq = items.len(), "mission upload over the radio abandoned");
                self.stats.failed += 1;
                self.to_radio.push_back(ack(
                    ground,
                    MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
                ));
                self.radio = Radio::Idle;
            } else {
                *attempts += 1;
                *sent_at = now;
                self.rtt.backoff();
                self.stats.radio_retries += 1;
                debug!(seq = items.len(), rto = ?self.rtt.rto(), "item request timed out, again");
                self.to_radio.push_back(request(ground, items.len() as u16));
            }
        }
        if let Wire::Sending {
            items,
            last,
            at,
            attempts,
        } = &mut self.wire
            && now >= *at + self.config.wire_timeout
        {
            if *attempts >= self.config.wire_attempts {
                self.wire = Wire::Idle;
                self.finish(MavMissionResult::MAV_MISSION_ERROR);
                return;
            }
            *attempts += 1;
            *at = now;
            match last {
                None => self
                    .to_fc
                    .push_back(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                        count: items.len() as u16,
                        target_system: 0,
                        target_component: 0,
                        ..Default::default()
                    })),
                Some(seq) => {
                    if let Some(item) = items.get(usize::from(*seq)) {
                        self.to_fc
                            .push_back(MavMessage::MISSION_ITEM_INT(item.clone()));
                    }
                }
            }
        }
    }

    /// Next message for the radio (targets filled in).
    pub fn poll_radio(&mut self) -> Option<MavMessage> {
        self.to_radio.pop_front()
    }

    /// Next message for the flight controller `fc` (system, component): targets rewritten to
    /// it, since the ground addressed its items to the vehicle, not to the bridge.
    pub fn poll_fc(&mut self, fc: (u8, u8)) -> Option<MavMessage> {
        let mut msg = self.to_fc.pop_front()?;
        match &mut msg {
            MavMessage::MISSION_COUNT(m) => (m.target_system, m.target_component) = fc,
            MavMessage::MISSION_ITEM_INT(m) => (m.target_system, m.target_component) = fc,
            _ => {}
        }
        Some(msg)
    }
}

fn request(ground: (u8, u8), seq: u16) -> MavMessage {
    MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq,
        target_system: ground.0,
        target_component: ground.1,
        ..Default::default()
    })
}

fn ack(ground: (u8, u8), result: MavMissionResult) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: ground.0,
        target_component: ground.1,
        mavtype: result,
        ..Default::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{MISSION_ACK_DATA, MavMissionResult};

    const GROUND: (u8, u8) = (255, 190);

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    fn count(n: u16) -> MavMessage {
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: n,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        })
    }

    fn item(seq: u16) -> MavMessage {
        MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
            seq,
            x: i32::from(seq),
            ..Default::default()
        })
    }

    fn radio_out(r: &mut MissionRelay) -> Vec<MavMessage> {
        std::iter::from_fn(|| r.poll_radio()).collect()
    }

    fn requested(msgs: &[MavMessage]) -> Vec<u16> {
        msgs.iter()
            .filter_map(|m| match m {
                MavMessage::MISSION_REQUEST_INT(r) => Some(r.seq),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn timeout_follows_the_measured_round_trip() {
        let mut r = MissionRelay::new(MissionConfig::default());
        assert!(r.handle_radio(ms(0), GROUND, &count(20)));
        let mut t = 0;
        for seq in 0..20 {
            assert_eq!(requested(&radio_out(&mut r)), vec![seq]);
            t += 400;
            r.handle_radio(ms(t), GROUND, &item(seq));
        }
        let rto = r.rtt().rto();
        assert!(
            rto >= Duration::from_millis(400) && rto < Duration::from_millis(700),
            "{rto:?}"
        );
        assert_eq!(r.stats().radio_retries, 0);
    }

    #[test]
    fn lost_request_is_retried_after_the_timeout_only() {
        let mut r = MissionRelay::new(MissionConfig::default());
        r.handle_radio(ms(0), GROUND, &count(2));
        assert_eq!(requested(&radio_out(&mut r)), vec![0]);
        let due = r.poll_timeout().unwrap();
        assert_eq!(due, ms(1500), "initial RTO");
        r.handle_timeout(ms(1499));
        assert!(radio_out(&mut r).is_empty());
        r.handle_timeout(due);
        assert_eq!(requested(&radio_out(&mut r)), vec![0]);
        assert_eq!(r.stats().radio_retries, 1);
    }

    #[test]
    fn repeated_item_from_the_ground_gets_the_next_request_at_once() {
        let mut r = MissionRelay::new(MissionConfig::default());
        r.handle_radio(ms(0), GROUND, &count(3));
        radio_out(&mut r);
        r.handle_radio(ms(300), GROUND, &item(0));
        assert_eq!(requested(&radio_out(&mut r)), vec![1]);
        // our request for 1 was lost; the ground repeats item 0
        r.handle_radio(ms(1800), GROUND, &item(0));
        assert_eq!(requested(&radio_out(&mut r)), vec![1]);
        assert_eq!(r.stats().radio_duplicate_items, 1);
    }

    #[test]
    fn full_upload_reaches_the_fc_and_its_ack_the_ground_and_a_lost_ack_is_resent() {
        let mut r = MissionRelay::new(MissionConfig::default());
        r.handle_radio(ms(0), GROUND, &count(2));
        r.handle_radio(ms(100), GROUND, &item(0));
        r.handle_radio(ms(200), GROUND, &item(1));
        radio_out(&mut r);
        let fc: Vec<_> = std::iter::from_fn(|| r.poll_fc((1, 1))).collect();
        assert!(
            matches!(&fc[..], [MavMessage::MISSION_COUNT(c)] if c.count == 2 && c.target_system == 1)
        );
        for seq in [0, 0, 1] {
            // the FC's 250 ms repeat of request 0 is answered too: harmless on the wire
            let req = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq,
                target_system: 1,
                target_component: 191,
                ..Default::default()
            });
            assert!(r.handle_fc(ms(300), &req));
        }
        let items: Vec<_> = std::iter::from_fn(|| r.poll_fc((1, 1))).collect();
        assert_eq!(items.len(), 3);
        let ack = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: 1,
            target_component: 191,
            mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
            ..Default::default()
        });
        assert!(r.handle_fc(ms(400), &ack));
        let to_ground = radio_out(&mut r);
        assert!(matches!(&to_ground[..], [MavMessage::MISSION_ACK(a)]
            if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED && a.target_system == 255));
        // the ack was lost: the ground repeats its last item, the ack goes again
        r.handle_radio(ms(2000), GROUND, &item(1));
        assert!(matches!(
            &radio_out(&mut r)[..],
            [MavMessage::MISSION_ACK(_)]
        ));
        assert_eq!(r.stats().completed, 1);
    }

    #[test]
    fn silent_fc_and_silent_ground_end_in_an_error_ack() {
        let mut r = MissionRelay::new(MissionConfig::default());
        r.handle_radio(ms(0), GROUND, &count(0));
        let mut now = ms(0);
        while let Some(t) = r.poll_timeout() {
            now = t;
            r.handle_timeout(now);
        }
        let counts = std::iter::from_fn(|| r.poll_fc((1, 1))).count();
        assert_eq!(counts, 6, "COUNT sent wire_attempts times");
        assert!(
            matches!(&radio_out(&mut r)[..], [MavMessage::MISSION_ACK(a)]
            if a.mavtype == MavMissionResult::MAV_MISSION_ERROR)
        );
        assert_eq!(now, ms(6 * 1500));

        let mut r = MissionRelay::new(MissionConfig::default());
        r.handle_radio(ms(0), GROUND, &count(5));
        while let Some(t) = r.poll_timeout() {
            r.handle_timeout(t);
        }
        let out = radio_out(&mut r);
        assert_eq!(requested(&out).len(), 10, "radio_attempts requests");
        assert!(matches!(out.last(), Some(MavMessage::MISSION_ACK(a))
            if a.mavtype == MavMissionResult::MAV_MISSION_OPERATION_CANCELLED));
        assert_eq!(r.stats().failed, 1);
    }
}
