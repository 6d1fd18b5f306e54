//! The router's half of the command relay: retransmission over the radio.

use crate::command::ack_tag::Epoch;
use std::collections::{HashMap, VecDeque};
use std::net::SocketAddr;

use super::ack_tag::{CommandTag, tag_command};
use super::{
    ACK_HOLD, AckTag, CommandId, LossGate, MAX_ATTEMPTS, MAX_RTO, RETRANSMIT_WINDOW, Redundancy,
    confirmation, radio_confirmation, with_confirmation,
};
use crate::dialect::{MavMessage, MavResult};
use crate::mission::RttEstimator;
use crate::time::{Duration, Instant};
use crate::wire::OwnedFrame;

/// Counters of the router's command relay.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RetransmitStats {
    /// Commands from the ground forwarded for the first time.
    pub commands: u64,
    /// Copies resent over the radio by the router (ground retries sent again included).
    pub retransmissions: u64,
    /// Ground-station retries of a command in flight (or too old to send again), dropped.
    pub ground_duplicates: u64,
    /// Commands that waited for an older one with the same target and id.
    pub queued: u64,
    /// Commands whose ack came back.
    pub acked: u64,
    /// Redundant copies sent before any timeout (see
    /// [`CommandRetransmitter::with_redundancy`]); not in `retransmissions`.
    pub early_copies: u64,
    /// Commands (or ground retries sent again) that went with redundant copies: the
    /// measured loss called for them.
    pub redundant: u64,
    /// Round trips measured (from the copy an ack names, or from a single send).
    pub rtt_samples: u64,
    /// Acks that came back after their command was answered or given up, swallowed.
    pub late_acks: u64,
    /// Commands given up after the last attempt (the ground station still has its own).
    pub given_up: u64,
    /// Commands the ground stopped asking for while a newer one with the same id waited,
    /// or that waited until the ground stopped asking: not sent (further).
    pub abandoned: u64,
    /// Copies resent while nothing had come from the radio since the last (a silent
    /// link): one per maximum timeout, and they use up no attempt (in `retransmissions`).
    pub blind: u64,
    /// Ground retries (`confirmation` > 0) of a command this router never saw, soon after
    /// it started: its previous run may have sent it, and the vehicle may have run it, so it
    /// is not sent as a new command (see [`CommandRetransmitter::with_epoch`]).
    pub refused_after_restart: u64,
    /// Tagged acks of another router run's commands, swallowed.
    pub foreign_acks: u64,
}

/// What to do with a command from the ground.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Admission {
    /// Send this frame over the radio (the command, numbered for the radio leg).
    Forward(OwnedFrame),
    /// A command with the same target and id is on the radio: this one waits its turn
    /// ([`CommandRetransmitter::handle_timeout`] queues it when its turn comes).
    Hold,
    /// A retry of a command in flight: drop it (the relay is already retrying).
    Retry,
    /// Its source already has its budget of commands in flight: drop it.
    OverBudget,
}

/// A command from the ground, waiting or on the radio.
#[derive(Debug)]
struct Pending {
    source: SocketAddr,
    id: CommandId,
    generation: u8,
    frame: OwnedFrame,
    msg: MavMessage,
    first_sent: Instant,
    /// Its last copy.
    sent: Instant,
    /// When each attempt went (the radio confirmation's attempt field, 0..=7): an ack that
    /// names its copy measures the round trip from that copy.
    sent_at: [Option<Instant>; MAX_ATTEMPTS as usize],
    /// Sends so far; 0 while waiting.
    attempts: u32,
    /// The vehicle answered `IN_PROGRESS`: no more copies, the final ack will come.
    in_progress: bool,
    /// Its redundant copies still to send, by when (set when it goes on the radio and the
    /// measured loss calls for them; cleared by `IN_PROGRESS`).
    planned: [Option<Instant>; PLANNED],
    /// When the ground last sent it (first send or retry): it still waits for the ack until
    /// about [`GROUND_PATIENCE`] later, and sends it again by [`GROUND_RETRY`] unless it
    /// gave up.
    last_ground: Instant,
}

/// How long after its last copy a ground station still waits for a command's ack: the
/// protocol's 1.5 s retry timeout, less a margin so that an ack forwarded in time is not
/// taken for the next command's by a station that has just given up.
const GROUND_PATIENCE: Duration = Duration::from_millis(1400);

/// How long after its last copy a ground station that has not sent a command again has
/// stopped retrying it: the protocol's 1.5 s retry timeout and a margin for the ground
/// link and the station's timer. Until then its retry may still come, and the ground still
/// waits for that command's ack: a newer command with the same id must not be answered
/// before (the station would take that ack for the older one's).
const GROUND_RETRY: Duration = Duration::from_millis(1500 + 250);

/// Redundant copies of a command before any timeout.
const PLANNED: usize = 3;

impl Pending {
    /// The copy last counted, as it goes on the radio at `now`: tagged with the router's
    /// `epoch` and its age.
    fn copy(&self, epoch: Epoch, now: Instant) -> OwnedFrame {
        let confirmation = radio_confirmation(self.generation, self.attempts.saturating_sub(1));
        let frame = with_confirmation(&self.frame, &self.msg, confirmation);
        tag_command(
            &frame,
            &self.msg,
            CommandTag {
                epoch,
                confirmation,
                age: now.saturating_duration_since(self.first_sent),
            },
        )
    }

    /// A resend at `now` into a link that has been silent since the last copy: it goes as
    /// that copy again (same attempt), so a silence does not use up the attempts. Never as
    /// the first copy: the bridge takes attempt 0 for a new command and would run it again.
    fn resend_blind(&mut self, now: Instant) {
        if self.attempts < 2 {
            self.count_send(now);
            return;
        }
        self.sent = now;
        if let Some(at) = self.sent_at.get_mut(self.attempts as usize - 1) {
            *at = Some(now);
        }
    }

    /// Counts a send at `now` (after which [`copy`](Self::copy) is that send's frame).
    fn count_send(&mut self, now: Instant) {
        self.attempts += 1;
        self.sent = now;
        if let Some(at) = self.sent_at.get_mut(self.attempts as usize - 1) {
            *at = Some(now);
        }
    }
}

/// A command answered or given up, remembered for the rest of its window.
#[derive(Debug)]
struct Finished {
    pending: Pending,
    /// The vehicle's ack came back (else: given up, outcome unknown).
    acked: bool,
}

/// Sans-IO retransmitter for commands crossing the radio from the ground (see the module
/// doc for identities, generations and how acks are matched).
#[derive(Debug)]
pub struct CommandRetransmitter {
    rtt: RttEstimator,
    max_rto: Duration,
    max_attempts: u32,
    window: Duration,
    per_source: usize,
    redundancy: Option<Redundancy>,
    /// The radio budget, bytes/s (see [`CommandRetransmitter::with_budget`]).
    budget: Option<u32>,
    /// Whether the measured loss calls for redundancy (see
    /// [`CommandRetransmitter::set_link_loss`]).
    gate: LossGate,
    on_air: Vec<Pending>,
    waiting: Vec<Pending>,
    finished: Vec<Finished>,
    /// Slots whose late acks are swallowed until then.
    draining: Vec<((u8, u32), Instant)>,
    /// The last generation given to each identity and when it was last sent: kept while the
    /// bridge may remember it ([`ACK_HOLD`] after its first arrival), so a re-issued command
    /// never reuses a generation the bridge still holds.
    generations: HashMap<CommandId, (u8, Instant)>,
    /// A waiting command may start.
    wake: Option<Instant>,
    /// When a frame last came from the radio (see [`CommandRetransmitter::heard_radio`]).
    heard: Option<Instant>,
    /// Frames due, waiting for [`poll_retransmit`](CommandRetransmitter::poll_retransmit).
    due: VecDeque<OwnedFrame>,
    /// This run's epoch, in every copy's tag (see [`CommandRetransmitter::with_epoch`]).
    epoch: Epoch,
    /// When this run started, if it may follow another.
    started: Option<Instant>,
    stats: RetransmitStats,
}

impl CommandRetransmitter {
    /// Timeout starts at `initial` and stays within `min..=max` (`max` at most [`MAX_RTO`]);
    /// each command goes at most `max_attempts` ([`MAX_ATTEMPTS`] at most) times, within
    /// `max_attempts` × `max` of its first send.
    pub fn new(initial: Duration, min: Duration, max: Duration, max_attempts: u32) -> Self {
        let max = max.min(MAX_RTO);
        let max_attempts = max_attempts.clamp(1, MAX_ATTEMPTS);
        Self {
            rtt: RttEstimator::new(initial.min(max), min.min(max), max),
            max_rto: max,
            max_attempts,
            window: (max * max_attempts).min(RETRANSMIT_WINDOW),
            per_source: usize::MAX,
            redundancy: None,
            budget: None,
            gate: LossGate::default(),
            on_air: Vec::new(),
            waiting: Vec::new(),
            finished: Vec::new(),
            draining: Vec::new(),
            generations: HashMap::new(),
            wake: None,
            heard: None,
            due: VecDeque::new(),
            epoch: 0,
            started: None,
            stats: RetransmitStats::default(),
        }
    }

    /// This run of the router, started at `started`, tags its copies with `epoch` (drawn at
    /// random at each start): the bridge keeps each run's generations apart, since a new
    /// run's start again at 0 while the bridge still holds the previous run's acks. Acks
    /// tagged with another epoch answer nothing here.
    ///
    /// For [`RETRANSMIT_WINDOW`] after `started`, a ground retry (`confirmation` > 0) of a
    /// command this run never saw is dropped: the previous run may have sent it and the
    /// vehicle run it (its ack lost), and this run cannot tell; sent as new, it would run
    /// again. The ground station's own timeout then says the outcome is unknown, as the
    /// command protocol does when no ack comes. (A `COMMAND_INT` carries no such mark: each
    /// one a new run sees is new.)
    pub fn with_epoch(mut self, epoch: Epoch, started: Instant) -> Self {
        self.epoch = epoch;
        self.started = Some(started);
        self
    }

    /// At most `n` commands from one source in flight (waiting or on the radio) at once.
    pub fn with_source_limit(mut self, n: usize) -> Self {
        self.per_source = n.max(1);
        self
    }

    /// On a lossy link (see [`set_link_loss`](Self::set_link_loss)) each command goes three
    /// times before any timeout: at once, `pair_gap` later and `spacing` after the first
    /// (see the [module](super) doc: separate air packets of the first round); the bridge
    /// answers the copies from its cache. A resend never goes sooner than `spacing` after
    /// the last copy. Needs at least three attempts.
    pub fn with_redundancy(mut self, redundancy: Redundancy) -> Self {
        self.redundancy = (self.max_attempts >= 3).then_some(redundancy);
        self
    }

    /// The radio budget, `bytes_per_s`: a command's copy `pair_gap` after the first goes
    /// only if the budget carries the frame in less than that gap. On a fast TDM radio
    /// (SiK 64k's ~3 kB/s: 45 bytes in 15 ms) it is another packet of the same window; on
    /// a slow half-duplex one (LoRa SF7's ~250 B/s: 180 ms) it would hold the channel when
    /// the ack should come back (in the simulated world it raises the median from 179 to
    /// 267 ms), so the copies go half a round and a round after the first only.
    pub fn with_budget(mut self, bytes_per_s: u32) -> Self {
        self.budget = Some(bytes_per_s.max(1));
        self
    }

    /// The link's measured loss at `now` (the worse direction; `None`: not measured), as
    /// often as it is known: commands that go on the radio are sent redundantly unless the
    /// link was measured clean for [`Redundancy::clean_for`].
    pub fn set_link_loss(&mut self, now: Instant, loss: Option<f64>) {
        if let Some(r) = &self.redundancy {
            self.gate.observe(now, loss, r);
        }
    }

    /// `p` goes on the radio at `now` (its first copy, or a ground retry sent again): counts
    /// the send and plans its redundant copies if the measured loss calls for them.
    fn start_round(&mut self, p: &mut Pending, now: Instant) {
        p.count_send(now);
        p.planned = [None; PLANNED];
        if let Some(r) = self.redundancy.filter(|r| self.gate.lossy(now, r)) {
            let bytes = p.frame.as_bytes().len() as u64;
            let on_air = |rate: u32| Duration::from_micros(bytes * 1_000_000 / u64::from(rate));
            let pair = self.budget.is_none_or(|rate| on_air(rate) < r.pair_gap);
            p.planned = [
                pair.then_some(now + r.pair_gap),
                Some(now + r.spacing),
                Some(now + r.spacing * 2),
            ];
            self.stats.redundant += 1;
        }
    }

    /// The shortest time between a copy and the next resend: the timeout, never less than
    /// the spacing that puts a copy in another air packet.
    fn resend_after(&self) -> Duration {
        let floor = self.redundancy.map_or(Duration::ZERO, |r| r.spacing);
        self.rtt.rto().max(floor)
    }

    /// A frame came from the radio at `now` (any frame: the link carries something).
    pub fn heard_radio(&mut self, now: Instant) {
        self.heard = Some(now);
    }

    /// Whether the link has fallen silent: something came from the radio once, and
    /// nothing since `p`'s last copy. Its timeout then says nothing about the command.
    fn blind(&self, p: &Pending) -> bool {
        self.heard.is_some_and(|h| h < p.sent)
    }

    /// How long after its last copy `p` is resent: the timeout `rto`, or while the link is
    /// silent the maximum timeout (a resend into silence only keeps the command alive
    /// until the link returns; at the normal timeout a 5 s silence would use up all eight
    /// attempts, and the command would never run although the ground still asks for it).
    fn resend_timeout(&self, p: &Pending, rto: Duration) -> Duration {
        if self.blind(p) {
            rto.max(self.max_rto)
        } else {
            rto
        }
    }

    /// Commands from `source` in flight.
    pub fn in_flight_from(&self, source: SocketAddr) -> usize {
        self.on_air
            .iter()
            .chain(&self.waiting)
            .filter(|p| p.source == source)
            .count()
    }

    /// Counters so far.
    pub fn stats(&self) -> RetransmitStats {
        self.stats
    }

    /// The command round-trip estimate.
    pub fn rtt(&self) -> &RttEstimator {
        &self.rtt
    }

    fn slot_busy(&self, slot: (u8, u32)) -> bool {
        self.on_air.iter().any(|p| p.id.slot() == slot) || self.draining.iter().any(|d| d.0 == slot)
    }

    fn expire(&mut self, now: Instant) {
        // A finished command stays known for the whole RETRANSMIT_WINDOW, not just for the
        // router's own attempts (`window`): with few attempts (1: the ground's copies are
        // the only ones) the ground's retry 1.5 s later must still go as that command,
        // and the bridge holds it for ACK_HOLD, longer than RETRANSMIT_WINDOW.
        self.finished
            .retain(|f| now.saturating_duration_since(f.pending.first_sent) < RETRANSMIT_WINDOW);
        self.draining.retain(|d| d.1 > now);
        self.generations
            .retain(|_, g| now.saturating_duration_since(g.1) < ACK_HOLD + MAX_RTO);
    }

    /// Notes that a copy of `p` goes on the radio at `now`.
    fn note_sent(&mut self, id: CommandId, generation: u8, now: Instant) {
        self.generations.insert(id, (generation, now));
    }

    /// The generation for a new command `id`: unique among the commands with its slot that
    /// the bridge may still hold, so that an ack tagged with it names one command (and a
    /// copy of it is never taken for an older identical command).
    fn next_generation(&self, id: CommandId) -> u8 {
        let slot = id.slot();
        let in_slot = || self.generations.iter().filter(|(i, _)| i.slot() == slot);
        let used = in_slot().fold(0u32, |m, (_, (g, _))| m | 1 << (g & 0x1f));
        let start = in_slot()
            .max_by_key(|(_, (_, at))| *at)
            .map_or(0, |(_, (g, _))| g.wrapping_add(1));
        (0..32)
            .map(|k| start.wrapping_add(k) & 0x1f)
            .find(|g| used & (1 << g) == 0)
            // 32 commands of one slot within the bridge's hold: reuse the oldest's.
            .unwrap_or(start & 0x1f)
    }

    /// A frame from the ground station at `source` (`frame` decodes to `msg`): its address
    /// and port, so each application on a host has its own budget.
    pub fn from_ground(
        &mut self,
        now: Instant,
        source: SocketAddr,
        frame: &OwnedFrame,
        msg: &MavMessage,
    ) -> Admission {
        let Some(id) = CommandId::of(msg) else {
            return Admission::Forward(frame.clone());
        };
        self.expire(now);
        // COMMAND_INT has no confirmation: an identical one is a retry while the first is
        // unanswered (a ground station retries only then).
        let is_int = confirmation(msg).is_none();
        let copy = confirmation(msg).is_none_or(|c| c > 0);
        if copy {
            if let Some(p) = self
                .on_air
                .iter_mut()
                .chain(&mut self.waiting)
                .find(|p| p.id == id)
            {
                p.last_ground = now;
                self.stats.ground_duplicates += 1;
                return Admission::Retry;
            }
            // A COMMAND_INT whose ack the ground got is done: an identical one after it is a
            // new command (ARM, DISARM, ARM), not a retry to answer from the bridge's cache.
            let last = self.finished.iter().rposition(|f| f.pending.id == id);
            if let Some(i) = last.filter(|&i| !(is_int && self.finished[i].acked)) {
                // The ground did not get the ack (or we gave up): send that command again,
                // as itself, unless a newer one is on the radio. A newer one that waits
                // keeps waiting: while the ground retries the older one it expects the
                // older one's ack first.
                if self.on_air.iter().any(|p| p.id.slot() == id.slot())
                    || (self.finished[i].acked
                        && self.waiting.iter().any(|p| p.id.slot() == id.slot()))
                    || self.in_flight_from(source) >= self.per_source
                {
                    self.stats.ground_duplicates += 1;
                    return Admission::Retry;
                }
                let mut p = self.finished.remove(i).pending;
                if p.attempts == 0 {
                    p.first_sent = now;
                }
                if self
                    .finished
                    .iter()
                    .all(|f| f.pending.id.slot() != id.slot())
                {
                    self.draining.retain(|d| d.0 != id.slot());
                }
                self.start_round(&mut p, now);
                p.source = source;
                p.last_ground = now;
                p.in_progress = false;
                self.stats.retransmissions += 1;
                self.note_sent(p.id, p.generation, now);
                let out = p.copy(self.epoch, now);
                self.on_air.push(p);
                return Admission::Forward(out);
            }
            if self.generations.contains_key(&id) && !is_int {
                // A retry of a command whose window is over: the bridge may still hold it,
                // so it must not go as a new one; the ground has to send a new command.
                self.stats.ground_duplicates += 1;
                return Admission::Retry;
            }
            if !is_int
                && self
                    .started
                    .is_some_and(|s| now.saturating_duration_since(s) < RETRANSMIT_WINDOW)
            {
                // A retry of a command this run never saw: the previous run may have had it
                // executed (see `with_epoch`).
                tracing::warn!(
                    command = id.command,
                    "ground retry of a command sent before this router started: not sent"
                );
                self.stats.refused_after_restart += 1;
                return Admission::Retry;
            }
        }
        if self.in_flight_from(source) >= self.per_source {
            return Admission::OverBudget;
        }
        let generation = self.next_generation(id);
        self.note_sent(id, generation, now);
        self.stats.commands += 1;
        let mut p = Pending {
            source,
            id,
            generation,
            frame: frame.clone(),
            msg: msg.clone(),
            first_sent: now,
            sent: now,
            sent_at: [None; MAX_ATTEMPTS as usize],
            attempts: 0,
            in_progress: false,
            planned: [None; PLANNED],
            last_ground: now,
        };
        if self.slot_busy(id.slot()) || self.waiting.iter().any(|w| w.id.slot() == id.slot()) {
            self.stats.queued += 1;
            self.waiting.push(p);
            return Admission::Hold;
        }
        self.start_round(&mut p, now);
        let out = p.copy(self.epoch, now);
        self.on_air.push(p);
        Admission::Forward(out)
    }

    /// A `COMMAND_ACK` from the radio, sent by (`system`, `component`): ends the retries of
    /// the command it answers (`IN_PROGRESS`: the vehicle has it; the slot stays taken
    /// until the final ack). Returns whether the ack goes on to the ground station (`false`
    /// for a late copy's ack). An untagged ack: see [`from_radio_tagged`](Self::from_radio_tagged).
    pub fn from_radio(
        &mut self,
        now: Instant,
        system: u8,
        component: u8,
        msg: &MavMessage,
    ) -> bool {
        self.from_radio_tagged(now, system, component, msg, None)
    }

    /// As [`from_radio`](Self::from_radio), for an ack the bridge tagged with the
    /// generation of the command it answers and the copy it answers
    /// ([`untag_ack`](super::ack_tag::untag_ack)): it answers that command only, a newer one
    /// with the same id need not wait for late copies' acks, and the round trip is measured
    /// from that copy. `None`: untagged, it answers the command of its id on the radio.
    pub fn from_radio_tagged(
        &mut self,
        now: Instant,
        system: u8,
        component: u8,
        msg: &MavMessage,
        tag: Option<AckTag>,
    ) -> bool {
        let MavMessage::COMMAND_ACK(ack) = msg else {
            return true;
        };
        self.expire(now);
        if tag.is_some_and(|t| t.epoch != self.epoch) {
            // An ack for a previous run's command (the bridge's repeat, or a late copy's
            // answer): its generation may be one this run gave another command.
            self.stats.foreign_acks += 1;
            return false;
        }
        let generation = tag.map(|t| t.generation);
        let command = ack.command as u32;
        // A tagged ack answers only the command of its generation.
        let answers = |p: &Pending| {
            p.id.answered_by(system, component, command)
                && generation.is_none_or(|g| p.generation == g)
        };
        let Some(i) = self.on_air.iter().position(answers) else {
            // The first ack of a command the router gave up on (it sent every attempt it
            // had; with one attempt, the ground's copies are the resends) answers it: the
            // ground still waits for it unless a newer command with the same id waits.
            let slot = (system, command);
            let newer_waits = self.waiting.iter().any(|w| w.id.slot() == slot);
            if !newer_waits
                && let Some(f) = self
                    .finished
                    .iter_mut()
                    .rev()
                    .find(|f| !f.acked && f.pending.attempts > 0 && answers(&f.pending))
            {
                f.acked = true;
                self.stats.acked += 1;
                return true;
            }
            let known = generation.is_some_and(|g| {
                self.finished.iter().any(|f| answers(&f.pending))
                    || self.on_air.iter().any(|p| p.id.slot() == slot)
                    || self.generations.iter().any(|(id, (last, _))| {
                        id.answered_by(system, component, command) && *last == g
                    })
            });
            if known || self.draining.iter().any(|d| d.0 == slot) {
                self.stats.late_acks += 1;
                return false;
            }
            return true;
        };
        let stale = now >= self.on_air[i].last_ground + GROUND_PATIENCE
            && self
                .waiting
                .iter()
                .any(|w| w.id.slot() == self.on_air[i].id.slot());
        if stale {
            // The ground may be giving up on it as this ack reaches it, and then take it
            // for the newer one's with the same id that it waits for: swallowed. It may
            // retry it instead: the newer one waits until that retry is overdue, and the
            // retry sends this command again (answered from the bridge's cache).
            let p = self.on_air.swap_remove(i);
            self.stats.abandoned += 1;
            self.stats.late_acks += 1;
            let until = (p.sent + self.max_rto).max(p.last_ground + GROUND_RETRY);
            self.draining.push((p.id.slot(), until));
            self.finish(p, false, now);
            return false;
        }
        if ack.result == MavResult::MAV_RESULT_IN_PROGRESS {
            let p = &mut self.on_air[i];
            p.in_progress = true;
            p.planned = [None; PLANNED];
            return true;
        }
        let p = self.on_air.swap_remove(i);
        self.stats.acked += 1;
        // Only an unambiguous round trip is a sample: from the copy a tagged ack names, or
        // (Karn) from the only copy; a tagged ack that names none (the bridge's repeat) is
        // none.
        let from = match tag {
            Some(t) => t
                .attempt
                .and_then(|a| p.sent_at.get(usize::from(a)).copied().flatten()),
            None => (p.attempts == 1).then_some(p.sent),
        };
        if let Some(from) = from.filter(|_| !p.in_progress) {
            self.rtt.sample(now.saturating_duration_since(from));
            self.stats.rtt_samples += 1;
        }
        if p.attempts > 1 && generation.is_none() {
            // Copies still on their way get acks (the bridge replays it) that name no
            // generation: not to be taken for the next one's.
            self.draining.push((p.id.slot(), p.sent + self.max_rto));
        }
        self.finish(p, true, now);
        true
    }

    fn finish(&mut self, p: Pending, acked: bool, now: Instant) {
        if self.waiting.iter().any(|w| w.id.slot() == p.id.slot()) {
            self.wake = Some(now);
        }
        self.finished.push(Finished { pending: p, acked });
    }

    /// Does what is due at `now`: abandons what the ground stopped asking for, gives up
    /// what is out of attempts or window, and queues every frame to send (a waiting command
    /// whose turn came, a copy of one whose timeout ran out) for
    /// [`poll_retransmit`](Self::poll_retransmit).
    pub fn handle_timeout(&mut self, now: Instant) {
        while let Some(frame) = self.next_due(now) {
            self.due.push_back(frame);
        }
    }

    /// The next frame to send, queued by [`handle_timeout`](Self::handle_timeout).
    pub fn poll_retransmit(&mut self) -> Option<OwnedFrame> {
        self.due.pop_front()
    }

    /// A command to send at `now`: a waiting one whose turn came, or one whose timeout ran
    /// out (at most one per call).
    fn next_due(&mut self, now: Instant) -> Option<OwnedFrame> {
        self.expire(now);
        self.wake = None;
        // A waiting command the ground stopped asking for (no retry for two of its
        // timeouts) is not sent: its ack would come when the ground waits for another. It
        // stays known, so a late retry of it is not taken for an older identical command.
        let mut i = 0;
        while i < self.waiting.len() {
            if now >= self.waiting[i].last_ground + self.max_rto * 2 {
                let p = self.waiting.remove(i);
                self.stats.abandoned += 1;
                self.finished.push(Finished {
                    pending: p,
                    acked: false,
                });
            } else {
                i += 1;
            }
        }
        // A newer command waits and the ground stopped asking for the one on the radio (its
        // retry is overdue, not merely its ack: a station that retries still waits for the
        // older one's ack, and would take the newer one's for it): the older is abandoned
        // (its late acks swallowed), the newer goes.
        if let Some(i) = self.on_air.iter().position(|p| {
            now >= p.last_ground + GROUND_RETRY
                && self.waiting.iter().any(|w| w.id.slot() == p.id.slot())
        }) {
            let p = self.on_air.swap_remove(i);
            self.stats.abandoned += 1;
            self.draining.push((p.id.slot(), p.sent + self.max_rto));
            self.finish(p, false, now);
        }
        if let Some(i) = (0..self.waiting.len()).find(|&i| {
            let slot = self.waiting[i].id.slot();
            !self.slot_busy(slot) && !self.waiting[..i].iter().any(|w| w.id.slot() == slot)
        }) {
            let mut p = self.waiting.remove(i);
            p.first_sent = now;
            self.start_round(&mut p, now);
            self.note_sent(p.id, p.generation, now);
            let out = p.copy(self.epoch, now);
            self.on_air.push(p);
            return Some(out);
        }
        let max_attempts = self.max_attempts;
        if let Some(p) = self
            .on_air
            .iter_mut()
            .find(|p| Self::early_at(p).is_some_and(|at| now >= at))
        {
            let k = p.planned.iter().position(|t| t.is_some_and(|t| now >= t));
            if let Some(k) = k {
                p.planned[k] = None;
            }
            if p.attempts >= max_attempts {
                // No attempt left for it: the timeout decides.
                p.planned = [None; PLANNED];
                return self.next_due(now);
            }
            p.count_send(now);
            let (id, generation, out) = (p.id, p.generation, p.copy(self.epoch, now));
            self.stats.early_copies += 1;
            self.note_sent(id, generation, now);
            return Some(out);
        }
        let rto = self.resend_after();
        let window = self.window;
        let i = self.on_air.iter().position(|p| {
            if p.in_progress {
                now.saturating_duration_since(p.first_sent) >= window
            } else {
                Self::early_at(p).is_none()
                    && now.saturating_duration_since(p.sent) >= self.resend_timeout(p, rto)
            }
        })?;
        let p = &self.on_air[i];
        let blind = self.blind(p);
        let timeout = self.resend_timeout(p, rto);
        if p.in_progress
            || p.attempts >= self.max_attempts
            || now.saturating_duration_since(p.first_sent) + timeout > window
        {
            let p = self.on_air.swap_remove(i);
            self.stats.given_up += 1;
            // The ground may still retry it (every 1.5 s by the protocol): a newer command
            // with the same id waits two maximum timeouts after the last copy, so that
            // retry comes first and takes the slot back.
            self.draining.push((p.id.slot(), p.sent + self.max_rto * 2));
            self.finish(p, false, now);
            return self.next_due(now);
        }
        // No exponential backoff (RFC 6298 5.5): on a radio a lost command is loss, not
        // congestion (the scheduler's byte budget already paces the link), and doubling the
        // timeout after a lost copy is what pushes the 99th percentile past 3 s.
        let p = &mut self.on_air[i];
        if blind {
            p.resend_blind(now);
            self.stats.blind += 1;
        } else {
            p.count_send(now);
        }
        let (id, generation, out) = (p.id, p.generation, p.copy(self.epoch, now));
        self.stats.retransmissions += 1;
        self.note_sent(id, generation, now);
        Some(out)
    }

    /// When `p`'s next redundant copy is due, if one is still to go.
    fn early_at(p: &Pending) -> Option<Instant> {
        p.planned.iter().flatten().min().copied()
    }

    /// When the relay next needs [`handle_timeout`](Self::handle_timeout).
    pub fn poll_timeout(&self) -> Option<Instant> {
        let early = self.on_air.iter().filter_map(Self::early_at).min();
        let rto = self.resend_after();
        let window = self.window;
        let waiting = (!self.waiting.is_empty())
            .then(|| self.draining.iter().map(|d| d.1).min())
            .flatten();
        let patience = self
            .waiting
            .iter()
            .map(|w| w.last_ground + self.max_rto * 2)
            .chain(
                self.on_air
                    .iter()
                    .filter(|p| self.waiting.iter().any(|w| w.id.slot() == p.id.slot()))
                    .map(|p| p.last_ground + GROUND_RETRY),
            );
        self.on_air
            .iter()
            .map(|p| {
                if p.in_progress {
                    p.first_sent + window
                } else {
                    // After its redundant copies, the timeout runs from the last.
                    Self::early_at(p).unwrap_or(p.sent + self.resend_timeout(p, rto))
                }
            })
            .chain(waiting)
            .chain(early)
            .chain(patience)
            .chain(self.wake)
            .min()
    }
}

#[cfg(test)]
mod tests;
