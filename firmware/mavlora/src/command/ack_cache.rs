//! The bridge's half of the command relay: at most one execution per command copy.

use crate::time::Duration;

use super::command_key;
use crate::dialect::MavMessage;
use crate::time::Instant;
use crate::wire::OwnedFrame;

/// What to do with a command from the radio.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CacheVerdict {
    /// New: forward it to the flight controller.
    Forward,
    /// Already acknowledged: send this ack back over the radio instead.
    Replay(OwnedFrame),
    /// A copy of a command the flight controller is executing: drop it.
    Drop,
}

/// Counters of the bridge's command cache.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AckCacheStats {
    /// Commands forwarded to the flight controller.
    pub forwarded: u64,
    /// Copies answered with the cached ack.
    pub replayed: u64,
    /// Copies dropped while the first was in progress.
    pub dropped: u64,
}

#[derive(Debug)]
struct Entry {
    key: (u8, u32),
    /// The command's payload, so a changed command with the same id is a new one.
    payload: Vec<u8>,
    forwarded: Instant,
    ack: Option<(OwnedFrame, Instant)>,
}

/// Sans-IO cache of recent commands and their acks.
#[derive(Debug)]
pub struct AckCache {
    hold: Duration,
    in_flight: Duration,
    entries: Vec<Entry>,
    stats: AckCacheStats,
}

impl AckCache {
    /// Acks are replayed for `hold` after they were seen; a copy within `in_flight` of the
    /// forwarded command, before its ack, is dropped (after that it goes to the flight
    /// controller again: the first may have been lost on the wire).
    pub fn new(hold: Duration, in_flight: Duration) -> Self {
        Self {
            hold,
            in_flight,
            entries: Vec::new(),
            stats: AckCacheStats::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> AckCacheStats {
        self.stats
    }

    /// A command from the radio (`frame` decodes to `msg`).
    pub fn command(&mut self, frame: &OwnedFrame, msg: &MavMessage, now: Instant) -> CacheVerdict {
        let Some(key) = command_key(msg) else {
            return CacheVerdict::Forward;
        };
        self.expire(now);
        let payload = comparable_payload(frame, msg);
        if let Some(e) = self
            .entries
            .iter_mut()
            .find(|e| e.key == key && e.payload == payload)
        {
            match &e.ack {
                Some((ack, _)) => {
                    self.stats.replayed += 1;
                    return CacheVerdict::Replay(ack.clone());
                }
                None if now.saturating_duration_since(e.forwarded) < self.in_flight => {
                    self.stats.dropped += 1;
                    return CacheVerdict::Drop;
                }
                None => {
                    e.forwarded = now;
                    self.stats.forwarded += 1;
                    return CacheVerdict::Forward;
                }
            }
        }
        self.entries.retain(|e| e.key != key);
        self.entries.push(Entry {
            key,
            payload,
            forwarded: now,
            ack: None,
        });
        self.stats.forwarded += 1;
        CacheVerdict::Forward
    }

    /// A `COMMAND_ACK` from the flight controller `system` on its way to the radio.
    pub fn ack(&mut self, system: u8, frame: &OwnedFrame, msg: &MavMessage, now: Instant) {
        let MavMessage::COMMAND_ACK(ack) = msg else {
            return;
        };
        let key = (system, ack.command as u32);
        if let Some(e) = self.entries.iter_mut().find(|e| e.key == key) {
            e.ack = Some((frame.clone(), now));
        }
    }

    fn expire(&mut self, now: Instant) {
        let (hold, in_flight) = (self.hold, self.in_flight);
        self.entries.retain(|e| match &e.ack {
            Some((_, at)) => now.saturating_duration_since(*at) < hold,
            None => now.saturating_duration_since(e.forwarded) < hold.max(in_flight),
        });
    }
}

/// `COMMAND_LONG` payload length on the wire and the offset of `confirmation` (last field,
/// after seven floats, the u16 command and the two target bytes).
const COMMAND_LONG_LEN: usize = 33;
const CONFIRMATION_AT: usize = 32;

/// The payload as sent before MAVLink 2 trimmed its trailing zeros, without
/// `COMMAND_LONG.confirmation`, which a sender increments on each retry of the same command.
fn comparable_payload(frame: &OwnedFrame, msg: &MavMessage) -> Vec<u8> {
    let mut payload = frame.payload().to_vec();
    if let MavMessage::COMMAND_LONG(_) = msg {
        payload.resize(COMMAND_LONG_LEN, 0);
        payload[CONFIRMATION_AT] = 0;
    }
    // Trailing zeros are trimmed in MAVLink 2 and not in 1: compare without them.
    while payload.last() == Some(&0) {
        payload.pop();
    }
    payload
}

#[cfg(test)]
mod tests {
    use mavlink::MavlinkVersion;

    use super::*;
    use crate::dialect::{COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd, MavResult};
    use crate::wire::Sender;

    const MS: fn(u64) -> Duration = Duration::from_millis;

    fn command(s: &mut Sender, confirmation: u8, param1: f32) -> (OwnedFrame, MavMessage) {
        let msg = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 1,
            target_component: 1,
            command: MavCmd::MAV_CMD_DO_SET_MODE,
            confirmation,
            param1,
            ..Default::default()
        });
        (s.frame(&msg), msg)
    }

    fn ack(fc: &mut Sender) -> (OwnedFrame, MavMessage) {
        let msg = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_DO_SET_MODE,
            result: MavResult::MAV_RESULT_ACCEPTED,
        });
        (fc.frame(&msg), msg)
    }

    #[test]
    fn a_copy_is_dropped_in_flight_and_answered_after_the_ack() {
        let mut c = AckCache::new(MS(5000), MS(1000));
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        let t0 = Instant::from_millis(0);
        let (f, m) = command(&mut gcs, 0, 4.0);
        assert_eq!(c.command(&f, &m, t0), CacheVerdict::Forward);
        // a retry (confirmation + 1) while the FC executes it
        let (f2, m2) = command(&mut gcs, 1, 4.0);
        assert_eq!(c.command(&f2, &m2, t0 + MS(300)), CacheVerdict::Drop);
        let (af, am) = ack(&mut fc);
        c.ack(1, &af, &am, t0 + MS(400));
        // the ack was lost on the radio: the next copy gets it again, not a second execution
        match c.command(&f2, &m2, t0 + MS(1200)) {
            CacheVerdict::Replay(a) => assert_eq!(a.as_bytes(), af.as_bytes()),
            other => panic!("{other:?}"),
        }
        // a different command with the same id is new
        let (f3, m3) = command(&mut gcs, 0, 5.0);
        assert_eq!(c.command(&f3, &m3, t0 + MS(1300)), CacheVerdict::Forward);
        assert_eq!(
            c.stats(),
            AckCacheStats {
                forwarded: 2,
                replayed: 1,
                dropped: 1
            }
        );
    }

    #[test]
    fn cached_acks_expire() {
        let mut c = AckCache::new(MS(5000), MS(1000));
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        let t0 = Instant::from_millis(0);
        let (f, m) = command(&mut gcs, 0, 4.0);
        c.command(&f, &m, t0);
        let (af, am) = ack(&mut fc);
        c.ack(1, &af, &am, t0 + MS(100));
        // much later the same command is a new request the FC must see
        assert_eq!(c.command(&f, &m, t0 + MS(6000)), CacheVerdict::Forward);
        // and a copy unanswered for longer than `in_flight` goes to the FC again
        assert_eq!(c.command(&f, &m, t0 + MS(7100)), CacheVerdict::Forward);
    }
}
