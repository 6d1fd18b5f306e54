//! The bridge's half of the command relay: at most one execution per command, however many
//! copies of it come, and each ack twice on a lossy link.

use crate::command::ack_tag::Epoch;
use crate::time::Duration;

use super::ack_tag::{AckTag, tag_ack, untag_command};
use super::{CommandId, LossGate, Redundancy, split_confirmation, with_confirmation};
use crate::dialect::{COMMAND_ACK_DATA, MavMessage, MavResult};
use crate::time::Instant;
use crate::wire::OwnedFrame;

/// A copy can wait longer in the router's radio queue than its command's first copy did:
/// a copy whose first came up to this long after the bridge started may still have had
/// that first copy come before (see [`AckCache::new`]).
const RESTART_MARGIN: Duration = super::MAX_RTO;

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
    /// Acks sent a second time of the bridge's own accord (a lossy link).
    pub repeated: u64,
    /// Copies that arrived while their ack's repeat was due: the repeat answers them.
    pub covered: u64,
    /// Copies of a command this bridge never saw, soon after it started: it may have
    /// forwarded the command before (its ack lost), so it does not forward it now.
    pub refused_after_restart: u64,
    /// Commands without the router's tag, forwarded as they came (uncached).
    pub untagged: u64,
}

#[derive(Debug)]
struct Entry {
    id: CommandId,
    /// The router run that sent it.
    epoch: Epoch,
    /// The router's generation of this identity.
    generation: u8,
    /// When its first copy arrived: the entry lives [`AckCache::new`]'s `hold` from then.
    first: Instant,
    forwarded: Instant,
    /// Never forwarded: its copies come from before this bridge started.
    refused: bool,
    /// The radio attempt of the copy forwarded.
    attempt: Option<u8>,
    ack: Option<Cached>,
    /// When its ack goes again, if it does.
    repeat_at: Option<Instant>,
}

/// An ack the flight controller sent for a command from the radio.
#[derive(Debug)]
struct Cached {
    /// As the flight controller sent it.
    frame: OwnedFrame,
    ack: COMMAND_ACK_DATA,
    /// As it first went on the radio (tagged, or as it came).
    radio: OwnedFrame,
    /// It carries the tag (a `COMMAND_LONG`'s ack whose value fits beside it).
    tagged: bool,
}

impl Cached {
    /// The ack as it goes on the radio answering the copy `attempt` (`None`: a repeat) of
    /// the router run `epoch`'s `generation`.
    fn answer(&self, epoch: Epoch, generation: u8, attempt: Option<u8>) -> OwnedFrame {
        if !self.tagged {
            return self.radio.clone();
        }
        tag_ack(
            &self.frame,
            &self.ack,
            AckTag::new(epoch, generation, attempt),
        )
        .unwrap_or_else(|| self.radio.clone())
    }
}

/// Sans-IO cache of recent commands and their acks.
#[derive(Debug)]
pub struct AckCache {
    hold: Duration,
    /// When this bridge started (see [`AckCache::new`]).
    started: Instant,
    redundancy: Option<Redundancy>,
    /// Whether the measured loss calls for repeats (see [`AckCache::set_link_loss`]).
    gate: LossGate,
    entries: Vec<Entry>,
    stats: AckCacheStats,
}

impl AckCache {
    /// A cache for a bridge started at `started`. Commands and their acks are kept `hold`
    /// after a command's first copy arrived (at least [`ACK_HOLD`](super::ACK_HOLD): the
    /// router's copies arrive within it).
    ///
    /// A copy of a command whose ack has not come yet is dropped: the flight controller
    /// has it (some take seconds to answer) and would run it again, and a command lost on
    /// the wire is rarer than a slow answer (the ground sends a new one then).
    ///
    /// A copy (attempt > 0) of a command this bridge never saw, whose first copy went
    /// before `started` by its age (within a margin for queueing), is not forwarded: it may
    /// have reached the flight controller before this bridge restarted, and nothing here
    /// tells whether it ran. It gets no ack, so the ground's timeout says the outcome is
    /// unknown (as the command protocol does when no ack comes); running it twice could
    /// take a second photo or drop a second payload. A copy of a command whose first copy
    /// went later is one whose earlier copies were lost, and goes.
    pub fn new(hold: Duration, started: Instant) -> Self {
        Self {
            hold,
            started,
            redundancy: None,
            gate: LossGate::default(),
            entries: Vec::new(),
            stats: AckCacheStats::default(),
        }
    }

    /// On a lossy link (see [`set_link_loss`](Self::set_link_loss)) each tagged ack goes a
    /// second time `spacing` after the first (see the [module](super) doc); a copy of its
    /// command that arrives before then is answered by that repeat.
    pub fn with_redundancy(mut self, redundancy: Redundancy) -> Self {
        self.redundancy = Some(redundancy);
        self
    }

    /// The link's measured loss at `now` (the worse direction; `None`: not measured), as
    /// often as it is known: acks are repeated unless the link was measured clean for
    /// [`Redundancy::clean_for`].
    pub fn set_link_loss(&mut self, now: Instant, loss: Option<f64>) {
        if let Some(r) = &self.redundancy {
            self.gate.observe(now, loss, r);
        }
    }

    /// When the ack going at `now` goes again, if the link calls for it.
    fn repeat_after(&self, now: Instant) -> Option<Instant> {
        let r = self.redundancy.filter(|r| self.gate.lossy(now, r))?;
        Some(now + r.spacing)
    }

    /// Counters so far.
    pub fn stats(&self) -> AckCacheStats {
        self.stats
    }

    /// A command from the radio (`frame` decodes to `msg`). Its tag names the router run
    /// (epoch) and the router's (generation, attempt): attempt 0 is a new command, more is a
    /// copy of the command with the same run, identity and generation (if none is known,
    /// its earlier copies were lost: it is new here, unless this bridge may have seen them
    /// before it restarted, see [`new`](Self::new)). A command without a tag is forwarded
    /// as it came.
    pub fn command(&mut self, frame: &OwnedFrame, msg: &MavMessage, now: Instant) -> CacheVerdict {
        let Some(id) = CommandId::of(msg) else {
            return CacheVerdict::Forward(frame.clone());
        };
        let Some(tag) = untag_command(frame, msg) else {
            self.stats.untagged += 1;
            return CacheVerdict::Forward(frame.clone());
        };
        self.expire(now);
        let epoch = tag.epoch;
        let (generation, attempt) = split_confirmation(tag.confirmation);
        let radio_attempt = Some(attempt);
        let repeat = self.repeat_after(now);
        let same = |e: &Entry| e.id == id && e.epoch == epoch && e.generation == generation;
        if attempt > 0
            && let Some(e) = self.entries.iter_mut().find(|e| same(e))
        {
            return match &e.ack {
                // The repeat still to come answers it, in another air packet than the
                // first ack (an answer now would share the first one's).
                Some(_) if e.repeat_at.is_some_and(|at| now < at) => {
                    self.stats.covered += 1;
                    CacheVerdict::Drop
                }
                Some(ack) => {
                    // The answer (and its own repeat) takes the place of a repeat overdue.
                    self.stats.replayed += 1;
                    let out = ack.answer(epoch, generation, radio_attempt);
                    e.repeat_at = repeat.filter(|_| ack.tagged);
                    CacheVerdict::Replay(out)
                }
                // The flight controller has it, or it was refused: never again.
                None => {
                    self.stats.dropped += 1;
                    CacheVerdict::Drop
                }
            };
        }
        // A newer generation of the identity replaces the older (the router sends it only
        // after the older's ack); another run's entries stay, for its late copies.
        self.entries.retain(|e| !(e.id == id && e.epoch == epoch));
        // When its first copy arrived, if it did: about this copy's age ago.
        let first_copy = Instant::from_micros(now.as_micros().saturating_sub(tag.age.as_micros()));
        let refused = attempt > 0 && first_copy < self.started + RESTART_MARGIN;
        self.entries.push(Entry {
            id,
            epoch,
            generation,
            first: now,
            forwarded: now,
            refused,
            attempt: radio_attempt,
            ack: None,
            repeat_at: None,
        });
        if refused {
            tracing::warn!(
                command = id.command,
                generation,
                attempt,
                "copy of a command that may have run before this bridge started: not forwarded"
            );
            self.stats.refused_after_restart += 1;
            return CacheVerdict::Drop;
        }
        self.stats.forwarded += 1;
        CacheVerdict::Forward(with_confirmation(frame, msg, 0))
    }

    /// A `COMMAND_ACK` from the flight controller's (`system`, `component`) on its way to
    /// the radio at `now`: cached for the latest unanswered command it can answer
    /// (`IN_PROGRESS` is replaced by the final ack). Returns the frame to send on the radio
    /// in its place: the ack tagged with that command's generation and the copy forwarded
    /// ([`tag_ack`]); `None`: send it as it is (it answers no command from the radio, or
    /// cannot be tagged). A final tagged ack goes again later on a lossy link
    /// ([`poll_repeat`](Self::poll_repeat)).
    pub fn ack(
        &mut self,
        now: Instant,
        system: u8,
        component: u8,
        frame: &OwnedFrame,
        msg: &MavMessage,
    ) -> Option<OwnedFrame> {
        let MavMessage::COMMAND_ACK(ack) = msg else {
            return None;
        };
        let command = ack.command as u32;
        let repeat = self.repeat_after(now);
        let e = self
            .entries
            .iter_mut()
            .filter(|e| !e.refused && e.id.answered_by(system, component, command))
            .filter(|e| {
                e.ack
                    .as_ref()
                    .is_none_or(|a| a.ack.result == MavResult::MAV_RESULT_IN_PROGRESS)
            })
            .max_by_key(|e| e.forwarded)?;
        let radio = tag_ack(frame, ack, AckTag::new(e.epoch, e.generation, e.attempt));
        let tagged = radio.is_some();
        e.ack = Some(Cached {
            frame: frame.clone(),
            ack: ack.clone(),
            radio: radio.clone().unwrap_or_else(|| frame.clone()),
            tagged,
        });
        // Only a final, tagged ack is repeated: an untagged one could be taken for the
        // next command's with the same id.
        e.repeat_at = repeat.filter(|_| tagged && ack.result != MavResult::MAV_RESULT_IN_PROGRESS);
        radio
    }

    /// When an ack is next due to go again.
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.entries.iter().filter_map(|e| e.repeat_at).min()
    }

    /// An ack due to go again at `now` (tagged as answering no copy): send it on the radio.
    pub fn poll_repeat(&mut self, now: Instant) -> Option<OwnedFrame> {
        self.expire(now);
        let e = self
            .entries
            .iter_mut()
            .find(|e| e.repeat_at.is_some_and(|at| now >= at))?;
        e.repeat_at = None;
        let out = e.ack.as_ref()?.answer(e.epoch, e.generation, None);
        self.stats.repeated += 1;
        Some(out)
    }

    fn expire(&mut self, now: Instant) {
        let hold = self.hold;
        self.entries
            .retain(|e| now.saturating_duration_since(e.first) < hold);
    }
}

#[cfg(test)]
mod tests;
