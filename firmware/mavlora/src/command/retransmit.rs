//! The router's half of the command relay: retransmission over the radio.

use std::net::IpAddr;
use std::time::Duration;

use super::command_key;
use crate::dialect::{MavMessage, MavResult};
use crate::mission::RttEstimator;
use crate::time::Instant;
use crate::wire::OwnedFrame;

/// Counters of the router's command relay.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RetransmitStats {
    /// Commands from the ground forwarded for the first time.
    pub commands: u64,
    /// Copies resent over the radio by the router.
    pub retransmissions: u64,
    /// Ground-station retries of a command in flight, dropped.
    pub ground_duplicates: u64,
    /// Commands whose ack came back.
    pub acked: u64,
    /// Commands given up after the last attempt (the ground station still has its own).
    pub given_up: u64,
}

/// What to do with a command from the ground.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Admission {
    /// New: send it over the radio (the relay now retries it).
    Forward,
    /// A retry of a command in flight: drop it (the relay is already retrying).
    Retry,
    /// Its source already has its budget of commands in flight: drop it.
    OverBudget,
}

#[derive(Debug)]
struct Pending {
    source: IpAddr,
    key: (u8, u32),
    frame: OwnedFrame,
    sent: Instant,
    attempts: u32,
}

/// Sans-IO retransmitter for commands crossing the radio from the ground.
#[derive(Debug)]
pub struct CommandRetransmitter {
    rtt: RttEstimator,
    max_attempts: u32,
    per_source: usize,
    pending: Vec<Pending>,
    stats: RetransmitStats,
}

impl CommandRetransmitter {
    /// Timeout starts at `initial` and stays within `min..=max`; each command goes at most
    /// `max_attempts` times.
    pub fn new(initial: Duration, min: Duration, max: Duration, max_attempts: u32) -> Self {
        Self {
            rtt: RttEstimator::new(initial, min, max),
            max_attempts: max_attempts.max(1),
            per_source: usize::MAX,
            pending: Vec::new(),
            stats: RetransmitStats::default(),
        }
    }

    /// At most `n` commands from one source in flight at once (at least 1).
    pub fn with_source_limit(mut self, n: usize) -> Self {
        self.per_source = n.max(1);
        self
    }

    /// Commands from `source` in flight.
    pub fn in_flight_from(&self, source: IpAddr) -> usize {
        self.pending.iter().filter(|p| p.source == source).count()
    }

    /// Counters so far.
    pub fn stats(&self) -> RetransmitStats {
        self.stats
    }

    /// The command round-trip estimate.
    pub fn rtt(&self) -> &RttEstimator {
        &self.rtt
    }

    /// A frame from the ground station at `source`: whether it goes on the radio.
    pub fn from_ground(
        &mut self,
        source: IpAddr,
        frame: &OwnedFrame,
        msg: &MavMessage,
        now: Instant,
    ) -> Admission {
        let Some(key) = command_key(msg) else {
            return Admission::Forward;
        };
        if self.pending.iter().any(|p| p.key == key) {
            self.stats.ground_duplicates += 1;
            return Admission::Retry;
        }
        if self.in_flight_from(source) >= self.per_source {
            return Admission::OverBudget;
        }
        self.stats.commands += 1;
        self.pending.push(Pending {
            source,
            key,
            frame: frame.clone(),
            sent: now,
            attempts: 1,
        });
        Admission::Forward
    }

    /// A frame from the radio: a `COMMAND_ACK` from `system` ends that command's retries
    /// (`IN_PROGRESS` too: the vehicle has it).
    pub fn from_radio(&mut self, system: u8, msg: &MavMessage, now: Instant) {
        let MavMessage::COMMAND_ACK(ack) = msg else {
            return;
        };
        let key = (system, ack.command as u32);
        let Some(i) = self.pending.iter().position(|p| p.key == key) else {
            return;
        };
        let p = self.pending.swap_remove(i);
        self.stats.acked += 1;
        // Karn: only an unambiguous round trip is a sample.
        if p.attempts == 1 && ack.result != MavResult::MAV_RESULT_IN_PROGRESS {
            self.rtt.sample(now.saturating_duration_since(p.sent));
        }
    }

    /// A command whose timeout ran out by `now`, to send again (at most one per call).
    pub fn poll_retransmit(&mut self, now: Instant) -> Option<OwnedFrame> {
        let rto = self.rtt.rto();
        let i = self
            .pending
            .iter()
            .position(|p| now.saturating_duration_since(p.sent) >= rto)?;
        if self.pending[i].attempts >= self.max_attempts {
            self.pending.swap_remove(i);
            self.stats.given_up += 1;
            return self.poll_retransmit(now);
        }
        // No exponential backoff (RFC 6298 5.5): on a radio a lost command is loss, not
        // congestion (the scheduler's byte budget already paces the link), and doubling the
        // timeout after a lost copy is what pushes the 99th percentile past 3 s.
        let p = &mut self.pending[i];
        p.attempts += 1;
        p.sent = now;
        self.stats.retransmissions += 1;
        Some(p.frame.clone())
    }

    /// When the next retransmission is due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let rto = self.rtt.rto();
        self.pending.iter().map(|p| p.sent + rto).min()
    }
}

#[cfg(test)]
mod tests {
    use mavlink::MavlinkVersion;

    use super::*;
    use crate::dialect::{COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd};
    use crate::wire::Sender;

    const MS: fn(u64) -> Duration = Duration::from_millis;
    const GCS: IpAddr = IpAddr::V4(std::net::Ipv4Addr::LOCALHOST);

    fn command(s: &mut Sender, cmd: MavCmd) -> (OwnedFrame, MavMessage) {
        let msg = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 1,
            target_component: 1,
            command: cmd,
            ..Default::default()
        });
        (s.frame(&msg), msg)
    }

    fn ack(cmd: MavCmd) -> MavMessage {
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: cmd,
            result: MavResult::MAV_RESULT_ACCEPTED,
        })
    }

    fn retransmitter() -> CommandRetransmitter {
        CommandRetransmitter::new(MS(1000), MS(200), MS(3000), 4)
    }

    #[test]
    fn resends_until_acked_then_stops() {
        let mut r = retransmitter();
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let (frame, msg) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
        let t0 = Instant::from_millis(0);
        assert_eq!(r.from_ground(GCS, &frame, &msg, t0), Admission::Forward);
        assert_eq!(r.poll_timeout(), Some(t0 + MS(1000)));
        assert!(r.poll_retransmit(t0 + MS(999)).is_none());
        let again = r.poll_retransmit(t0 + MS(1000)).expect("due");
        assert_eq!(again.as_bytes(), frame.as_bytes());
        // the ground station's own retry while we are at it goes nowhere
        assert_eq!(
            r.from_ground(GCS, &frame, &msg, t0 + MS(1500)),
            Admission::Retry
        );
        r.from_radio(1, &ack(MavCmd::MAV_CMD_DO_SET_MODE), t0 + MS(1600));
        assert!(r.poll_timeout().is_none());
        assert!(r.poll_retransmit(t0 + MS(10_000)).is_none());
        let s = r.stats();
        assert_eq!(
            (s.commands, s.retransmissions, s.ground_duplicates, s.acked),
            (1, 1, 1, 1)
        );
        // the retransmitted command's round trip is ambiguous: no sample (Karn)
        assert_eq!(r.rtt().samples(), 0);
    }

    #[test]
    fn timeout_follows_the_measured_round_trip() {
        let mut r = retransmitter();
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let mut now = Instant::from_millis(0);
        for _ in 0..20 {
            let (frame, msg) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
            assert_eq!(r.from_ground(GCS, &frame, &msg, now), Admission::Forward);
            now = now + MS(150);
            r.from_radio(1, &ack(MavCmd::MAV_CMD_DO_SET_MODE), now);
            now = now + MS(1000);
        }
        assert!(r.rtt().rto() <= MS(300), "{:?}", r.rtt().rto());
    }

    #[test]
    fn an_ack_from_another_vehicle_or_command_does_not_count() {
        let mut r = retransmitter();
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let (frame, msg) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
        let t0 = Instant::from_millis(0);
        r.from_ground(GCS, &frame, &msg, t0);
        r.from_radio(2, &ack(MavCmd::MAV_CMD_DO_SET_MODE), t0 + MS(100));
        r.from_radio(1, &ack(MavCmd::MAV_CMD_NAV_LAND), t0 + MS(100));
        assert!(r.poll_retransmit(t0 + MS(1000)).is_some());
    }

    #[test]
    fn gives_up_after_the_last_attempt() {
        let mut r = retransmitter();
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let (frame, msg) = command(&mut gcs, MavCmd::MAV_CMD_DO_SET_MODE);
        r.from_ground(GCS, &frame, &msg, Instant::from_millis(0));
        let mut sent = 0;
        let mut now = Instant::from_millis(0);
        while let Some(t) = r.poll_timeout() {
            now = now.max(t);
            if r.poll_retransmit(now).is_some() {
                sent += 1;
            }
        }
        assert_eq!(sent, 3, "4 attempts in all");
        assert_eq!(r.stats().given_up, 1);
        // a later retry by the ground station is a new command
        assert_eq!(
            r.from_ground(GCS, &frame, &msg, now + MS(1)),
            Admission::Forward
        );
    }
}
