//! The bridge's half of the command relay: at most one execution per command copy.

use crate::time::Duration;

use super::ack_tag::tag_ack;
use super::{CommandId, confirmation, split_confirmation, with_confirmation};
use crate::dialect::{MavMessage, MavResult};
use crate::time::Instant;
use crate::wire::OwnedFrame;

/// What to do with a command from the radio.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CacheVerdict {
    /// New (or the flight controller may have lost it): forward this frame to it.
    Forward(OwnedFrame),
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
    id: CommandId,
    /// The router's generation of this identity (0 for `COMMAND_INT`).
    generation: u8,
    /// When its first copy arrived: the entry lives [`AckCache::new`]'s `hold` from then.
    first: Instant,
    forwarded: Instant,
    /// Times forwarded to the flight controller.
    forwards: u8,
    ack: Option<OwnedFrame>,
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
    /// Commands and their acks are kept `hold` after a command's first copy arrived (at
    /// least [`ACK_HOLD`](super::ACK_HOLD): the router's copies arrive within it); a copy
    /// within `in_flight` of the forwarded command, before its ack, is dropped (after that it
    /// goes to the flight controller again: the first may have been lost on the wire).
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

    /// A command from the radio (`frame` decodes to `msg`). Its confirmation is read as the
    /// router's (generation, attempt): attempt 0 is a new command, more is a copy of the
    /// command with the same identity and generation (if none is known, its earlier copies
    /// were lost: it is new here). `COMMAND_INT` has no confirmation: an identical one is a
    /// copy.
    pub fn command(&mut self, frame: &OwnedFrame, msg: &MavMessage, now: Instant) -> CacheVerdict {
        let Some(id) = CommandId::of(msg) else {
            return CacheVerdict::Forward(frame.clone());
        };
        self.expire(now);
        let (generation, attempt) = confirmation(msg).map_or((0, 1), split_confirmation);
        if attempt > 0
            && let Some(e) = self
                .entries
                .iter_mut()
                .find(|e| e.id == id && e.generation == generation)
        {
            return match &e.ack {
                Some(ack) => {
                    self.stats.replayed += 1;
                    CacheVerdict::Replay(ack.clone())
                }
                None if now.saturating_duration_since(e.forwarded) < self.in_flight => {
                    self.stats.dropped += 1;
                    CacheVerdict::Drop
                }
                None => {
                    e.forwarded = now;
                    e.forwards = e.forwards.saturating_add(1);
                    self.stats.forwarded += 1;
                    CacheVerdict::Forward(with_confirmation(frame, msg, e.forwards - 1))
                }
            };
        }
        self.entries.retain(|e| e.id != id);
        self.entries.push(Entry {
            id,
            generation,
            first: now,
            forwarded: now,
            forwards: 1,
            ack: None,
        });
        self.stats.forwarded += 1;
        CacheVerdict::Forward(with_confirmation(frame, msg, 0))
    }

    /// A `COMMAND_ACK` from the flight controller's (`system`, `component`) on its way to
    /// the radio: cached for the latest unanswered command it can answer (`IN_PROGRESS` is
    /// replaced by the final ack). Returns the frame to send on the radio in its place: the
    /// ack tagged with that command's generation ([`tag_ack`]); `None`: send it as it is
    /// (it answers no command from the radio, or cannot be tagged).
    pub fn ack(
        &mut self,
        system: u8,
        component: u8,
        frame: &OwnedFrame,
        msg: &MavMessage,
    ) -> Option<OwnedFrame> {
        let MavMessage::COMMAND_ACK(ack) = msg else {
            return None;
        };
        let command = ack.command as u32;
        let e = self
            .entries
            .iter_mut()
            .filter(|e| e.id.answered_by(system, component, command))
            .filter(|e| {
                e.ack.as_ref().is_none_or(|a| {
                    matches!(
                        a.decode::<MavMessage>(),
                        Ok(MavMessage::COMMAND_ACK(a)) if a.result == MavResult::MAV_RESULT_IN_PROGRESS
                    )
                })
            })
            .max_by_key(|e| e.forwarded)?;
        // COMMAND_INT carries no generation: its acks stay as they are.
        let radio = (!e.id.is_int())
            .then(|| tag_ack(frame, ack, e.generation))
            .flatten();
        e.ack = Some(radio.clone().unwrap_or_else(|| frame.clone()));
        radio
    }

    fn expire(&mut self, now: Instant) {
        let hold = self.hold;
        self.entries
            .retain(|e| now.saturating_duration_since(e.first) < hold);
    }
}

#[cfg(test)]
mod tests {
    use mavlink::MavlinkVersion;

    use super::*;
    use crate::command::{ACK_HOLD, radio_confirmation};
    use crate::dialect::{COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd};
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
            ..Default::default()
        });
        (fc.frame(&msg), msg)
    }

    fn forwarded_confirmation(v: CacheVerdict) -> u8 {
        match v {
            CacheVerdict::Forward(f) => match f.decode::<MavMessage>() {
                Ok(MavMessage::COMMAND_LONG(c)) => c.confirmation,
                other => panic!("{other:?}"),
            },
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_copy_is_dropped_in_flight_and_answered_after_the_ack() {
        let mut c = AckCache::new(ACK_HOLD, MS(1000));
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        let t0 = Instant::from_millis(0);
        let (f, m) = command(&mut gcs, 0, 4.0);
        assert_eq!(forwarded_confirmation(c.command(&f, &m, t0)), 0);
        // a retry (confirmation + 1) while the FC executes it
        let (f2, m2) = command(&mut gcs, 1, 4.0);
        assert_eq!(c.command(&f2, &m2, t0 + MS(300)), CacheVerdict::Drop);
        let (af, am) = ack(&mut fc);
        let radio = c
            .ack(1, 1, &af, &am)
            .expect("answers a command from the radio");
        // the ack was lost on the radio: the next copy gets it again, not a second execution
        match c.command(&f2, &m2, t0 + MS(1200)) {
            CacheVerdict::Replay(a) => assert_eq!(a.as_bytes(), radio.as_bytes()),
            other => panic!("{other:?}"),
        }
        // a different command with the same id is new
        let (f3, m3) = command(&mut gcs, 0, 5.0);
        assert_eq!(
            forwarded_confirmation(c.command(&f3, &m3, t0 + MS(1300))),
            0
        );
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
    fn a_late_copy_within_the_router_window_is_not_run_again() {
        // the camera trigger ran, its acks were lost for 7 s: a copy at 7.1 s is answered
        let mut c = AckCache::new(ACK_HOLD, MS(1000));
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        let t0 = Instant::from_millis(0);
        let (f, m) = command(&mut gcs, radio_confirmation(0, 0), 1.0);
        c.command(&f, &m, t0);
        let (af, am) = ack(&mut fc);
        c.ack(1, 1, &af, &am);
        let (late, late_m) = command(&mut gcs, radio_confirmation(0, 7), 1.0);
        assert!(matches!(
            c.command(&late, &late_m, t0 + MS(7100)),
            CacheVerdict::Replay(_)
        ));
        assert!(matches!(
            c.command(&late, &late_m, t0 + ACK_HOLD - MS(1)),
            CacheVerdict::Replay(_)
        ));
    }

    #[test]
    fn a_deliberate_repeat_runs_again_even_if_its_first_copy_was_lost() {
        let mut c = AckCache::new(ACK_HOLD, MS(1000));
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        let t0 = Instant::from_millis(0);
        let (f, m) = command(&mut gcs, radio_confirmation(0, 0), 1.0);
        c.command(&f, &m, t0);
        let (af, am) = ack(&mut fc);
        c.ack(1, 1, &af, &am);
        // the second trigger, 2.5 s later: its first copy arrives
        let (f2, m2) = command(&mut gcs, radio_confirmation(1, 0), 1.0);
        assert_eq!(
            forwarded_confirmation(c.command(&f2, &m2, t0 + MS(2500))),
            0
        );
        c.ack(1, 1, &af, &am);
        // a third: only its second copy arrives; still a new command here
        let (f3, m3) = command(&mut gcs, radio_confirmation(2, 1), 1.0);
        assert_eq!(
            forwarded_confirmation(c.command(&f3, &m3, t0 + MS(5000))),
            0
        );
        assert_eq!(c.stats().forwarded, 3);
    }

    #[test]
    fn cached_acks_expire_after_the_hold() {
        let mut c = AckCache::new(MS(5000), MS(1000));
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        let t0 = Instant::from_millis(0);
        let (f, m) = command(&mut gcs, 0, 4.0);
        c.command(&f, &m, t0);
        let (af, am) = ack(&mut fc);
        c.ack(1, 1, &af, &am);
        let (f2, m2) = command(&mut gcs, 1, 4.0);
        // after the hold a copy is unknown: forwarded (the router never sends one that late)
        assert_eq!(
            forwarded_confirmation(c.command(&f2, &m2, t0 + MS(6000))),
            0
        );
        // and a copy unanswered for longer than `in_flight` goes to the FC again
        assert_eq!(
            forwarded_confirmation(c.command(&f2, &m2, t0 + MS(7100))),
            1
        );
    }

    #[test]
    fn acks_on_the_radio_name_the_generation_they_answer() {
        use crate::command::ack_tag::untag_ack;
        let mut c = AckCache::new(ACK_HOLD, MS(1000));
        let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
        let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
        let t0 = Instant::from_millis(0);
        let (af, am) = ack(&mut fc);
        // an ack that answers nothing from the radio goes as the autopilot sent it
        assert!(c.ack(1, 1, &af, &am).is_none());
        for (k, generation) in [0u8, 1, 31].into_iter().enumerate() {
            let (f, m) = command(&mut gcs, radio_confirmation(generation, 0), 1.0);
            c.command(&f, &m, t0 + MS(3000 * k as u64));
            let radio = c.ack(1, 1, &af, &am).expect("tagged");
            let MavMessage::COMMAND_ACK(a) = radio.decode::<MavMessage>().unwrap() else {
                panic!()
            };
            let (g, plain, _) = untag_ack(&radio, &a).expect("tag");
            assert_eq!(g, generation);
            assert_eq!(plain.as_bytes(), af.as_bytes());
        }
    }
}
