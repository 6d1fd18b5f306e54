//! The bridge state machine.

use std::collections::VecDeque;

use mavlink::{MavHeader, MavlinkVersion, Message as _};
use tracing::{debug, info};

use super::config::BridgeConfig;
use super::fc_watch::{FcEvent, FcWatch};
use super::gcs_heartbeat::GcsHeartbeat;
use super::param_answers::{Asked, ParamAnswers};
use crate::command::{ACK_HOLD, AckCache, AckCacheStats, CacheVerdict, link_loss};
use crate::compact::{self, CompactFrame, CompactStats, Compactor, REPLACED_IDS};
use crate::dialect::{
    MISSION_ACK_DATA, MavCmd, MavMessage, MavMissionResult, MavMissionType, MavResult, MavType,
    RADIO_STATUS_DATA,
};
use crate::filter::{
    FilterStats, RadioFilter, Unlisted, Verdict, request_data_stream_requests,
    set_message_interval_requests, state_interval_requests,
};
use crate::mission::{MissionRelay, MissionStats};
use crate::param::{ParamPackStats, ParamPacker, ParamValue};
use crate::quality::{LinkQuality, is_local_radio_status};
use crate::schedule::{Class, LinkScheduler, ScheduleError, SchedulerStats, TokenBucket};
use crate::signing::{RadioLeg, SigningStats, is_link_frame};
use crate::time::Instant;
use crate::wire::{
    FrameReader, MAX_FRAME_LEN, OwnedFrame, ReaderStats, Received, Sender, StreamId, encode, ids,
    to_v1,
};
use std::collections::BTreeMap;

/// Counters of one bridge, for the status line and tests.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BridgeStats {
    /// What the flight-controller side reader saw.
    pub fc_reader: ReaderStats,
    /// What the radio side reader saw.
    pub radio_reader: ReaderStats,
    /// Radio filter outcomes for flight-controller frames.
    pub filter: FilterStats,
    /// Radio budget scheduler.
    pub scheduler: SchedulerStats,
    /// Compact telemetry.
    pub compact: CompactStats,
    /// Mission relay.
    pub mission: MissionStats,
    /// Commands from the radio: forwarded, answered from the ack cache, dropped copies.
    pub commands: AckCacheStats,
    /// Radio link signing (all zero when signing is off).
    pub signing: SigningStats,
    /// Frames written to the flight controller.
    pub to_fc_frames: u64,
    /// Bytes written to the flight controller.
    pub to_fc_bytes: u64,
    /// `SET_MESSAGE_INTERVAL` / `REQUEST_DATA_STREAM` messages sent (retries included).
    pub config_commands: u64,
    /// Configurations done with `REQUEST_DATA_STREAM` (MAVLink 1 autopilot, or
    /// `SET_MESSAGE_INTERVAL` refused as unsupported).
    pub data_stream_fallbacks: u64,
    /// `COMMAND_ACK`s for them.
    pub config_acks: u64,
    /// Flight-controller reboots detected.
    pub fc_reboots: u64,
    /// Compact mode: frames the compact messages replace, dropped before the flight
    /// controller was identified.
    pub held_before_fc: u64,
    /// Commands the autopilot sent its own components (target: its own system), kept off
    /// the radio.
    pub fc_own_commands_dropped: u64,
    /// Ground heartbeats regenerated towards the flight controller.
    pub gcs_heartbeats_regenerated: u64,
    /// Compact frames folded into the one still waiting for the radio ([`crate::compact::merge`]).
    pub compact_merged: u64,
    /// Position samples those merges dropped (past a frame's limit, or under an altitude
    /// offset that moved).
    pub compact_samples_dropped: u64,
    /// `LINK_QUALITY` reports sent to the radio.
    pub link_quality_sent: u64,
    /// `LINK_QUALITY` reports received from the radio.
    pub link_quality_received: u64,
    /// Radio frames turned into MAVLink 1 for a MAVLink 1 flight controller.
    pub to_fc_downgraded: u64,
    /// Radio frames a MAVLink 1 flight controller could not be given (ids above 255).
    pub to_fc_not_v1: u64,
    /// Telemetry frames the profile does not name, dropped (`unlisted = "drop"`).
    pub unlisted_dropped: u64,
    /// Their bytes.
    pub unlisted_dropped_bytes: u64,
    /// Of those frames, per message id: the first [`UNLISTED_IDS_KEPT`] ids seen (the rest
    /// count in the totals only), so an operator sees what a profile keeps off the radio.
    pub unlisted_dropped_by_id: BTreeMap<u32, u64>,
    /// `PARAM_VALUE`s that answered the ground's own PARAM_SET or PARAM_REQUEST_READ, sent
    /// ahead of a parameter list in flight.
    pub param_answers: u64,
    /// Of those, answers to reads beyond their share of the budget
    /// ([`READ_ANSWER_SHARE_DIVISOR`]), sent with the parameter list's share instead (still
    /// ahead of the list, behind position telemetry).
    pub param_answers_paced: u64,
    /// Of those, dropped waiting (more than [`PACED_ANSWERS_KEPT`]; the ground reads again).
    pub param_answers_dropped: u64,
    /// The parameter list packed into `MAVLORA_PARAM_VALUES` frames.
    pub params: ParamPackStats,
    /// `MAVLORA_PARAM_VALUES` frames from the flight controller or the radio, dropped: only
    /// the bridge makes them.
    pub param_frames_refused: u64,
}

/// Share of the radio budget the answers to the ground's reads may take ahead of everything
/// else: one byte in four. A ground station reading many values (QGroundControl keeps 10 reads
/// in flight and asks again every second) would otherwise starve position telemetry: on LoRa
/// SF7 at 10 % loss, its answers alone wanted twice the budget and position at the ground
/// fell to 0.03 Hz. The echo of a `PARAM_SET` always goes first.
pub const READ_ANSWER_SHARE_DIVISOR: u32 = 4;

/// Answers to reads that wait for their turn with the packed list at most: a ground station
/// keeps ~10 reads in flight.
pub const PACED_ANSWERS_KEPT: usize = 32;

/// Message ids whose dropped unlisted frames [`BridgeStats::unlisted_dropped_by_id`] counts
/// one by one: an autopilot sends a few dozen types; the bound keeps a stream of made-up ids
/// from growing the map.
pub const UNLISTED_IDS_KEPT: usize = 32;

#[derive(Debug)]
struct ConfigState {
    pending: Vec<MavMessage>,
    /// `SET_MESSAGE_INTERVAL` is acknowledged; `REQUEST_DATA_STREAM` is not, so it is sent
    /// `config_attempts` times (harmless: the request is idempotent).
    acknowledged: bool,
    expected_acks: u64,
    acks: u64,
    attempts: u32,
    next_retry: Option<Instant>,
}

/// Sans-IO bridge engine. See the [module](super) doc for the call pattern.
#[derive(Debug)]
pub struct Bridge {
    config: BridgeConfig,
    fc_reader: FrameReader,
    radio_reader: FrameReader,
    filter: RadioFilter,
    scheduler: LinkScheduler,
    quality: LinkQuality,
    compactor: Option<Compactor>,
    mission: MissionRelay,
    commands: AckCache,
    watch: FcWatch,
    gcs_heartbeat: GcsHeartbeat,
    param_answers: ParamAnswers,
    /// The budget of answers to reads that go first ([`READ_ANSWER_SHARE_DIVISOR`]).
    read_answers: TokenBucket,
    /// The autopilot's parameter list, packed (`None`: it goes one value per frame).
    params: Option<ParamPacker>,
    /// Answers to reads beyond their share of the budget, waiting to take turns with the
    /// packed list's frames in the parameter queue.
    paced_answers: VecDeque<OwnedFrame>,
    /// Whether the parameter queue's last frame was such an answer.
    answer_had_turn: bool,
    /// Frames we originate on the radio link (reports, compact telemetry, mission).
    radio_sender: Sender,
    /// Frames we originate on the wire (configuration, mission upload).
    fc_sender: Sender,
    to_fc: VecDeque<OwnedFrame>,
    /// Renumbers what leaves on the radio, so the router counts radio loss only.
    /// Renumbers and signs what leaves on the radio, verifies what arrives.
    radio_leg: RadioLeg,
    config_state: ConfigState,
    stats: BridgeStats,
}

impl Bridge {
    /// A bridge started at `now`. Nothing is sent to the flight controller before its first
    /// heartbeat: the configuration needs its ids as target.
    pub fn new(config: BridgeConfig, now: Instant) -> Result<Self, ScheduleError> {
        let radio_leg = RadioLeg::new(config.signing.as_ref());
        let scheduler = LinkScheduler::new(config.scheduler, now)?
            .with_frame_extra(radio_leg.frame_extra())
            .with_radio_backlog(config.radio_backlog, now);
        let sys = config.system_id;
        let comp = config.component_id;
        Ok(Self {
            fc_reader: FrameReader::new(),
            radio_reader: RadioLeg::reader(config.signing.as_ref()),
            filter: RadioFilter::new(config.profile.clone()),
            scheduler,
            quality: LinkQuality::new(config.quality, now),
            compactor: config.compact.map(Compactor::new),
            mission: MissionRelay::new(config.mission),
            commands: {
                let c = AckCache::new(ACK_HOLD, now);
                match config.command_redundancy {
                    Some(r) => c.with_redundancy(r),
                    None => c,
                }
            },
            watch: FcWatch::new(config.fc_silence),
            gcs_heartbeat: GcsHeartbeat::new(
                config.gcs_heartbeat_period,
                config.gcs_heartbeat_margin,
                crate::router::GCS_HEARTBEAT_LONGEST,
            ),
            param_answers: ParamAnswers::default(),
            read_answers: TokenBucket::new(
                (config.scheduler.rate_bytes_per_s / READ_ANSWER_SHARE_DIVISOR).max(1),
                MAX_FRAME_LEN as u32,
                now,
            ),
            params: config.param_pack.map(ParamPacker::new),
            paced_answers: VecDeque::new(),
            answer_had_turn: false,
            radio_sender: Sender::new(sys, comp, MavlinkVersion::V2),
            fc_sender: Sender::new(sys, comp, MavlinkVersion::V2),
            to_fc: VecDeque::new(),
            radio_leg,
            config_state: ConfigState {
                pending: Vec::new(),
                acknowledged: true,
                expected_acks: 0,
                acks: 0,
                attempts: 0,
                next_retry: None,
            },
            stats: BridgeStats::default(),
            config,
        })
    }

    /// Counters as of now.
    pub fn stats(&self) -> BridgeStats {
        BridgeStats {
            fc_reader: self.fc_reader.stats().clone(),
            radio_reader: self.radio_reader.stats().clone(),
            filter: self.filter.stats(),
            scheduler: self.scheduler.stats(),
            compact: self
                .compactor
                .as_ref()
                .map(|c| c.stats())
                .unwrap_or_default(),
            mission: self.mission.stats(),
            commands: self.commands.stats(),
            signing: self.radio_leg.stats(),
            params: self
                .params
                .as_ref()
                .map(ParamPacker::stats)
                .unwrap_or_default(),
            ..self.stats.clone()
        }
    }

    /// Whether radio frames are signed.
    pub fn radio_signed(&self) -> bool {
        self.radio_leg.signed()
    }

    /// The radio signer's state to store at `now` (`None`: signing off).
    pub fn signing_state(&self, now: Instant) -> Option<crate::signing::SigningState> {
        self.radio_leg.signing_state(now)
    }

    /// The link-quality engine (the peer's latest report, its state).
    pub fn quality(&self) -> &LinkQuality {
        &self.quality
    }

    /// The mission relay's radio round-trip estimate.
    pub fn mission_rtt(&self) -> &crate::mission::RttEstimator {
        self.mission.rtt()
    }

    /// The flight controller's (system, component), once its heartbeat was seen.
    pub fn fc(&self) -> Option<(u8, u8)> {
        self.watch.fc()
    }

    /// Bytes read from the flight controller's serial port.
    pub fn handle_fc_bytes(&mut self, now: Instant, bytes: &[u8]) {
        self.fc_reader.push(bytes);
        while let Some(rx) = self.fc_reader.next_frame() {
            self.fc_frame(rx.frame, now);
        }
        self.refill_params(now);
    }

    /// No byte came from the flight controller for longer than a frame takes: a partial
    /// frame still buffered lost its tail; it is dropped and frames behind it are handled.
    pub fn handle_fc_idle(&mut self, now: Instant) {
        if self.fc_reader.flush_partial() {
            self.handle_fc_bytes(now, &[]);
        }
    }

    /// The flight controller's port was closed (a reopened one starts a new byte stream).
    pub fn fc_port_closed(&mut self) {
        self.fc_reader.finish();
        while let Some(rx) = self.fc_reader.next_frame() {
            debug!(msgid = rx.frame.message_id(), "frame completed at close");
        }
    }

    fn fc_frame(&mut self, frame: OwnedFrame, now: Instant) {
        let id = frame.message_id();
        if id == ids::MAVLORA_PARAM_VALUES {
            // Ours: the router would speak for the autopilot from whatever it says.
            self.stats.param_frames_refused += 1;
            return;
        }
        let wants_decode = self.watch.wants(&frame)
            || (self.compactor.is_some() && REPLACED_IDS.contains(&id))
            || (id == ids::PARAM_VALUE && self.param_answers.waiting())
            || matches!(
                id,
                ids::MISSION_REQUEST
                    | ids::MISSION_ACK
                    | ids::MISSION_REQUEST_INT
                    | ids::COMMAND_ACK
                    | ids::COMMAND_LONG
                    | ids::COMMAND_INT
            );
        let msg = if wants_decode {
            frame.decode::<MavMessage>().ok()
        } else {
            None
        };
        match self.watch.observe(&frame, msg.as_ref(), now) {
            Some(FcEvent::Appeared) => {
                info!(
                    system = frame.system_id(),
                    component = frame.component_id(),
                    "flight controller found, configuring stream rates"
                );
                self.radio_sender.set_system(frame.system_id());
                self.fc_sender.set_system(frame.system_id());
                self.fc_sender.set_version(frame.version());
                self.start_config(now);
            }
            Some(FcEvent::Rebooted) => {
                info!("flight controller rebooted, configuring stream rates again");
                self.stats.fc_reboots += 1;
                self.start_config(now);
                self.mission.fc_rebooted(now);
            }
            None => {}
        }
        // What its link can carry: MAVLink 1 has no `mission_type`.
        self.mission
            .set_fc_mavlink1(self.watch.version() == Some(MavlinkVersion::V1));
        // A command the autopilot sends its own components: PX4 tells its camera and gimbal
        // of each mode change (target: its own system, component 0) and repeats it while
        // unanswered. No component of the vehicle's system is beyond the radio, and on LoRa
        // SF7 these held position and the new mode back for 2.6 s at PX4's RTL.
        if let Some(msg @ (MavMessage::COMMAND_LONG(_) | MavMessage::COMMAND_INT(_))) = &msg
            && self.watch.is_fc(&frame)
            && msg.target_system_id() == Some(frame.system_id())
        {
            self.stats.fc_own_commands_dropped += 1;
            return;
        }
        if let Some(msg) = &msg {
            if self.addressed_to_us(msg) {
                if let MavMessage::COMMAND_ACK(ack) = msg
                    && ack.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL
                {
                    self.config_ack(ack.result, now);
                    return;
                }
                if self.mission.handle_fc(now, msg) {
                    return;
                }
            }
            // Many autopilots leave COMMAND_ACK's target (an extension field) at 0: acks
            // for SET_MESSAGE_INTERVAL are ours while we wait for some.
            if let MavMessage::COMMAND_ACK(ack) = msg
                && ack.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL
                && self.config_state.acks < self.config_state.expected_acks
            {
                self.config_ack(ack.result, now);
                return;
            }
            if id == ids::COMMAND_ACK {
                self.commands.set_link_loss(now, self.link_loss(now));
            }
            if id == ids::COMMAND_ACK
                && let Some(tagged) =
                    self.commands
                        .ack(now, frame.system_id(), frame.component_id(), &frame, msg)
            {
                // The ack of a command from the radio, tagged with the command it answers.
                if self.filter.check(&tagged, now) == Verdict::Pass {
                    self.scheduler.push(tagged, Class::of(id), now);
                }
                return;
            }
            if id == ids::PARAM_VALUE
                && let Some(asked) = self.param_answers.answers(now, msg)
            {
                // The answer to the ground's own question overtakes a list in flight, and the
                // list's copies still waiting must not follow it with an older value.
                if let (Some(packer), Some(value)) =
                    (&mut self.params, ParamValue::from_payload(frame.payload()))
                {
                    packer.answered(frame.system_id(), frame.component_id(), &value);
                }
                if self.filter.check(&frame, now) == Verdict::Pass
                    && let Some(frame) = self.radio_leg.admit(frame)
                {
                    self.stats.param_answers += 1;
                    // A set's echo goes first; reads' answers within their share of the
                    // budget, the rest with the list's share (before the list's next frame:
                    // the packer waits for the parameter queue to empty).
                    let cost = frame.as_bytes().len() + self.radio_leg.frame_extra();
                    if asked == Asked::Set {
                        // a set's echo is its ack
                        self.scheduler.push(frame, Class::Command, now);
                    } else if self.read_answers.try_take(cost, now) {
                        self.scheduler.push(frame, Class::Protocol, now);
                    } else if self.params.is_some() {
                        // Turn about with the list's frames: neither starves the other.
                        self.stats.param_answers_paced += 1;
                        if self.paced_answers.len() == PACED_ANSWERS_KEPT {
                            self.paced_answers.pop_front();
                            self.stats.param_answers_dropped += 1;
                        }
                        self.paced_answers.push_back(frame);
                    } else {
                        self.stats.param_answers_paced += 1;
                        self.scheduler.push(frame, Class::Param, now);
                    }
                }
                return;
            }
            if let Some(compactor) = &mut self.compactor
                && self.watch.is_fc(&frame)
                && compactor.observe(msg, now)
            {
                return;
            }
        }
        // Compact mode: until the autopilot's first heartbeat names it, what the compact frames
        // will carry does not go raw (a few hundred bytes at start otherwise).
        if self.compactor.is_some() && self.watch.fc().is_none() && REPLACED_IDS.contains(&id) {
            self.stats.held_before_fc += 1;
            return;
        }
        if self.filter.check(&frame, now) != Verdict::Pass {
            return;
        }
        // Telemetry the profile does not name only gets what the named leaves, or nothing.
        let class = match Class::of(id) {
            Class::Periodic if !self.filter.profile().names(id) => {
                if self.filter.profile().unlisted() == Unlisted::Drop {
                    let s = &mut self.stats;
                    s.unlisted_dropped += 1;
                    s.unlisted_dropped_bytes += frame.as_bytes().len() as u64;
                    let kept = s.unlisted_dropped_by_id.len() < UNLISTED_IDS_KEPT;
                    if kept || s.unlisted_dropped_by_id.contains_key(&id) {
                        *s.unlisted_dropped_by_id.entry(id).or_default() += 1;
                    }
                    return;
                }
                Class::Unlisted
            }
            class => class,
        };
        // A parameter list goes packed: several values to a frame.
        if id == ids::PARAM_VALUE
            && let Some(packer) = &mut self.params
            && let Some(value) = ParamValue::from_payload(frame.payload())
            && packer.push(now, frame.system_id(), frame.component_id(), value)
        {
            return;
        }
        // a MAVLink 1 autopilot's frames go as MAVLink 2 (so they can be signed): the budget
        // counts the bytes that are sent
        if let Some(frame) = self.radio_leg.admit(frame) {
            self.scheduler.push(frame, class, now);
        }
    }

    fn addressed_to_us(&self, msg: &MavMessage) -> bool {
        let us = (self.radio_sender.system(), self.config.component_id);
        msg.target_system_id().is_some_and(|s| s == us.0)
            && msg.target_component_id().is_some_and(|c| c == us.1)
    }

    fn start_config(&mut self, now: Instant) {
        let Some((sys, comp)) = self.watch.fc() else {
            return;
        };
        // MAVLink 1 autopilots predate SET_MESSAGE_INTERVAL (ArduPilot < 4.0, APM). A profile
        // that names its streams only by group asks by group whatever the version: ArduPilot
        // 4.x takes REQUEST_DATA_STREAM over MAVLink 2 too, and would otherwise get nothing.
        let groups_only = self
            .config
            .profile
            .rules()
            .all(|(_, rule)| rule.stream_hz.is_none());
        if (self.watch.version() == Some(MavlinkVersion::V1) || groups_only)
            && !self.config.profile.data_streams().is_empty()
        {
            self.start_data_streams(now);
            return;
        }
        let mut pending = set_message_interval_requests(&self.config.profile, sys, comp);
        pending.extend(self.state_requests(sys, comp));
        self.config_state = ConfigState {
            expected_acks: pending.len() as u64,
            acknowledged: true,
            pending,
            acks: 0,
            attempts: 0,
            next_retry: Some(now),
        };
        self.config_tick(now);
    }

    fn start_data_streams(&mut self, now: Instant) {
        let Some((sys, comp)) = self.watch.fc() else {
            return;
        };
        info!(
            streams = self.config.profile.data_streams().len(),
            "configuring the flight controller with REQUEST_DATA_STREAM"
        );
        self.stats.data_stream_fallbacks += 1;
        let mut pending = request_data_stream_requests(&self.config.profile, sys, comp);
        let state = self.state_requests(sys, comp);
        // REQUEST_DATA_STREAM is not acked; the state requests are, and their acks are ours
        // (not the ground's: they would take the radio).
        let expected_acks = state.len() as u64;
        pending.extend(state);
        self.config_state = ConfigState {
            pending,
            acknowledged: false,
            expected_acks,
            acks: 0,
            attempts: 0,
            next_retry: Some(now),
        };
        self.config_tick(now);
    }

    /// Compact mode: the mode and arming faster than the autopilot's 1 Hz HEARTBEAT (the
    /// compact status reports a change at once, but only once the bridge has seen it).
    fn state_requests(&self, sys: u8, comp: u8) -> Vec<MavMessage> {
        let autopilot = self.watch.autopilot();
        self.compactor.as_ref().map_or_else(Vec::new, |c| {
            state_interval_requests(c.config().state_hz, autopilot, sys, comp)
        })
    }

    fn config_ack(&mut self, result: MavResult, now: Instant) {
        self.stats.config_acks += 1;
        self.config_state.acks += 1;
        // An autopilot without SET_MESSAGE_INTERVAL says so once per request; the first
        // refusal switches to the MAVLink 1 way if the profile has one.
        if result == MavResult::MAV_RESULT_UNSUPPORTED
            && self.config_state.acknowledged
            && !self.config.profile.data_streams().is_empty()
        {
            self.start_data_streams(now);
        }
    }

    fn config_tick(&mut self, now: Instant) {
        let st = &mut self.config_state;
        let Some(due) = st.next_retry else {
            return;
        };
        if now < due {
            return;
        }
        let done = st.acknowledged && st.acks >= st.expected_acks;
        if done || st.attempts >= self.config.config_attempts {
            st.next_retry = None;
            return;
        }
        st.attempts += 1;
        // Acks do not say which message they answer: a retry resends all and recounts.
        st.acks = 0;
        st.next_retry = Some(now + self.config.config_retry);
        for msg in st.pending.clone() {
            let frame = self.fc_sender.frame(&msg);
            self.stats.config_commands += 1;
            self.to_fc.push_back(frame);
        }
    }

    /// The radio's port was closed (a reopened one starts a new byte stream).
    pub fn radio_port_closed(&mut self) {
        self.radio_reader.finish();
        while let Some(rx) = self.radio_reader.next_frame() {
            debug!(msgid = rx.frame.message_id(), "frame completed at close");
        }
    }

    /// No byte came from the radio for longer than a frame takes: a partial frame still
    /// buffered lost its tail; it is dropped and frames behind it are handled.
    pub fn handle_radio_idle(&mut self, now: Instant) {
        if self.radio_reader.flush_partial() {
            self.handle_radio_bytes(now, &[]);
        }
    }

    /// The local radio's status read out of band (a modem's registers; a SiK radio's comes
    /// in the byte stream by itself).
    pub fn handle_radio_status(&mut self, status: RADIO_STATUS_DATA) {
        let txbuf = status.txbuf;
        self.quality.handle_radio_status(status);
        // The radio's free buffer paces the budget, when this link reads its radio's reports.
        if self.quality.local_radio().is_some() {
            self.scheduler.handle_txbuf(txbuf);
        }
    }

    /// The local radio's own `RADIO_STATUS` frame from its byte stream.
    fn local_radio_frame<T: AsRef<[u8]>>(&mut self, frame: &crate::wire::Frame<T>) {
        if let Ok(MavMessage::RADIO_STATUS(status)) = frame.decode::<MavMessage>() {
            self.handle_radio_status(status);
        }
    }

    /// Bytes read from the radio's serial port.
    pub fn handle_radio_bytes(&mut self, now: Instant, bytes: &[u8]) {
        self.radio_reader.push(bytes);
        while let Some(rx) = self.radio_reader.next_frame() {
            self.radio_frame(rx, now);
        }
        self.quality.observe(now, self.radio_reader.stats());
    }

    fn radio_frame(&mut self, rx: Received, now: Instant) {
        // The local radio's own report (SiK injects it into its serial output): never signed,
        // for the link-quality engine only, and not a frame of the peer's.
        if is_local_radio_status(&rx.frame) {
            self.local_radio_frame(&rx.frame);
            return;
        }
        // Only frames the peer signed count as received: loss is the peer's frames lost.
        let Some(frame) = self.radio_leg.incoming(rx.frame, now) else {
            return;
        };
        // Nothing counts while the peer is still to prove it is live (a fresh signing state):
        // its frames refused meanwhile would read as lost.
        if !self.radio_leg.awaiting_proof() {
            self.radio_reader.accept(&frame, rx.integrity);
        }
        self.quality.handle_frame(now, &frame);
        if self.quality.take_peer_restart() {
            self.radio_reader.expect_restart(StreamId {
                system: frame.system_id(),
                component: frame.component_id(),
            });
            // The router numbers its mission transfers afresh.
            self.mission.router_restarted();
        }
        let id = frame.message_id();
        match id {
            // The ground's radio reports to the router, never to this flight controller (whose
            // flow control follows its own radio's).
            ids::RADIO_STATUS => return,
            // The signing handshake is the radio leg's (done in `incoming`).
            ids::TIMESYNC if is_link_frame(&frame) => return,
            // LINK_QUALITY is for us; the flight controller does not know it.
            ids::LINK_QUALITY => {
                self.stats.link_quality_received += 1;
                return;
            }
            // Packed values go to the router only.
            ids::MAVLORA_PARAM_VALUES => {
                self.stats.param_frames_refused += 1;
                return;
            }
            ids::HEARTBEAT
            | ids::MISSION_COUNT
            | ids::MISSION_ITEM_INT
            | ids::MAVLORA_MISSION_ITEMS
            | ids::MISSION_WRITE_PARTIAL_LIST
            | ids::MISSION_ACK => {
                let Ok(msg) = frame.decode::<MavMessage>() else {
                    self.forward_to_fc(frame);
                    return;
                };
                if let MavMessage::HEARTBEAT(hb) = &msg
                    && hb.mavtype == MavType::MAV_TYPE_GCS
                {
                    self.gcs_heartbeat.heard(&frame, hb.clone(), now);
                }
                let from = (frame.system_id(), frame.component_id());
                // Uploads addressed to this vehicle are relayed (and the router's cancel of
                // one); others pass through.
                let for_vehicle = msg.target_system_id() == Some(self.radio_sender.system());
                if id != ids::HEARTBEAT && for_vehicle && self.mission.handle_radio(now, from, &msg)
                {
                    return;
                }
            }
            // Questions whose answers go ahead of a parameter list in flight.
            ids::PARAM_SET | ids::PARAM_REQUEST_READ => {
                if let Ok(msg) = frame.decode::<MavMessage>() {
                    self.param_answers.asked(now, &msg);
                }
            }
            // Commands the router may have resent: each reaches the FC once.
            ids::COMMAND_INT | ids::COMMAND_LONG => {
                if let Ok(msg) = frame.decode::<MavMessage>() {
                    self.commands.set_link_loss(now, self.link_loss(now));
                    match self.commands.command(&frame, &msg, now) {
                        CacheVerdict::Forward(f) => return self.forward_to_fc(f),
                        CacheVerdict::Replay(ack) => {
                            self.scheduler.push(ack, Class::Command, now);
                            return;
                        }
                        CacheVerdict::Drop => return,
                    }
                }
            }
            _ => {}
        }
        if self.watch.version() == Some(MavlinkVersion::V1) && self.refused_untyped(&frame, now) {
            return;
        }
        self.forward_to_fc(frame);
    }

    /// A ground station's mission operation on fences or rally points for a MAVLink 1
    /// flight controller: converted to MAVLink 1 it would lose its `mission_type` and act on
    /// the mission (a fence `MISSION_CLEAR_ALL` deletes the flight plan). Refused as the
    /// protocol says, `MAV_MISSION_UNSUPPORTED` from the vehicle, an ack dropped; whether it
    /// was.
    fn refused_untyped(&mut self, frame: &OwnedFrame, now: Instant) -> bool {
        if !matches!(
            frame.message_id(),
            ids::MISSION_CLEAR_ALL
                | ids::MISSION_COUNT
                | ids::MISSION_WRITE_PARTIAL_LIST
                | ids::MISSION_REQUEST_LIST
                | ids::MISSION_REQUEST_PARTIAL_LIST
                | ids::MISSION_REQUEST
                | ids::MISSION_REQUEST_INT
                | ids::MISSION_ITEM
                | ids::MISSION_ITEM_INT
                | ids::MISSION_ACK
        ) {
            return false;
        }
        let Ok(msg) = frame.decode::<MavMessage>() else {
            return false;
        };
        let Some(t) = mission_type(&msg) else {
            return false;
        };
        if t == MavMissionType::MAV_MISSION_TYPE_MISSION {
            return false;
        }
        self.mission.count_unsupported();
        info!(
            ?t,
            msgid = frame.message_id(),
            "a MAVLink 1 flight controller cannot tell fences and rally points from the mission: refused"
        );
        if matches!(msg, MavMessage::MISSION_ACK(_)) {
            return true;
        }
        let (sys, comp) = self.watch.fc().unwrap_or((self.radio_sender.system(), 1));
        let refusal = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: frame.system_id(),
            target_component: frame.component_id(),
            mavtype: MavMissionResult::MAV_MISSION_UNSUPPORTED,
            mission_type: t,
            ..Default::default()
        });
        let header = MavHeader {
            system_id: sys.into(),
            component_id: comp,
            sequence: 0,
        };
        let ack = encode(MavlinkVersion::V2, header, &refusal);
        self.scheduler.push(ack, Class::Protocol, now);
        true
    }

    /// Queues a radio frame for the flight controller, in MAVLink 1 if that is what it
    /// speaks (the radio carries only MAVLink 2); what MAVLink 1 cannot carry (ids above
    /// 255) is dropped and counted.
    fn forward_to_fc(&mut self, frame: OwnedFrame) {
        if self.watch.version() != Some(MavlinkVersion::V1) {
            self.to_fc.push_back(frame);
            return;
        }
        match to_v1(frame) {
            Some(v1) => {
                self.stats.to_fc_downgraded += 1;
                self.to_fc.push_back(v1);
            }
            None => self.stats.to_fc_not_v1 += 1,
        }
    }

    /// Does what is due at `now`: link-quality reports, compact telemetry, regenerated ground
    /// heartbeats, configuration retries, mission timeouts.
    pub fn handle_timeout(&mut self, now: Instant) {
        // The signing handshake's challenge or answer: small, and nothing else of the peer's
        // is taken before it, so with the commands.
        while let Some(msg) = self.radio_leg.poll_handshake(now) {
            let frame = self.radio_sender.frame(&msg);
            self.scheduler.push(frame, Class::Command, now);
        }
        self.quality.handle_timeout(now, self.radio_reader.stats());
        if let Some(report) = self.quality.poll_report() {
            self.stats.link_quality_sent += 1;
            match &mut self.compactor {
                // Compact telemetry: the report rides in the next compact frame instead of
                // paying 25 bytes of framing and signature of its own.
                Some(compactor) => compactor.link_report(report, now),
                None => {
                    let frame = self.radio_sender.frame(&MavMessage::LINK_QUALITY(report));
                    self.scheduler.push(frame, Class::Periodic, now);
                }
            }
        }
        if let Some(coalescing) = self.compactor.as_ref().map(Compactor::coalescing) {
            // A coalesced group must leave whole (one radio packet): with the commands, so no
            // other class's frame goes between its frames.
            let class = if coalescing {
                Class::Command
            } else {
                Class::Periodic
            };
            while let Some((msg, urgent)) =
                self.compactor.as_mut().and_then(|c| c.poll_urgency(now))
            {
                self.push_compact(msg, urgent, class, now);
            }
        }
        while let Some(frame) = self.gcs_heartbeat.poll(now) {
            self.stats.gcs_heartbeats_regenerated += 1;
            self.to_fc.push_back(frame);
        }
        self.config_tick(now);
        self.mission.handle_timeout(now);
        self.drain_mission(now);
        self.refill_params(now);
        self.commands.set_link_loss(now, self.link_loss(now));
        while let Some(ack) = self.commands.poll_repeat(now) {
            self.scheduler.push(ack, Class::Command, now);
        }
    }

    /// Queues a compact frame for the radio. At most one waits at a time: while the one
    /// before it still waits (the radio is behind), the two go as one in the older one's
    /// place, so the next frame out carries the newest status and positions instead of what
    /// the vehicle said seconds ago. A copy of a change made at once (`urgent`) goes with the
    /// commands, what waited folded into it: a mode change is a command's visible effect, and
    /// must not wait behind telemetry, nor behind an older copy saying the mode before (on
    /// LoRa SF7 with real PX4, 1.2 s late at the ground).
    fn push_compact(&mut self, msg: MavMessage, urgent: bool, class: Class, now: Instant) {
        let newer = match &msg {
            MavMessage::MAVLORA_COMPACT(data) if class == Class::Periodic => {
                CompactFrame::decode(data).ok()
            }
            _ => None,
        };
        let Some(newer) = newer else {
            let frame = self.radio_sender.frame(&msg);
            self.scheduler.push(frame, class, now);
            return;
        };
        let (system, component) = (self.radio_sender.system(), self.radio_sender.component());
        let id = ids::MAVLORA_COMPACT;
        let older = self
            .scheduler
            .waiting_frame(system, component, id)
            .and_then(|(waiting, f)| match f.decode::<MavMessage>() {
                Ok(MavMessage::MAVLORA_COMPACT(d)) => {
                    Some((waiting, CompactFrame::decode(&d).ok()?))
                }
                _ => None,
            });
        let waiting = older.as_ref().map(|(waiting, _)| *waiting);
        let merged = older.map(|(_, older)| compact::merge(&older, &newer));
        // Nothing waits (or, never: ten samples at most always encode, the merge did not):
        // the new frame goes on its own.
        let encoded = merged.and_then(|(m, loss)| m.encode().ok().map(|data| (data, loss)));
        let Some((data, loss)) = encoded else {
            let frame = self.radio_sender.frame(&msg);
            let class = if urgent { Class::Command } else { class };
            self.scheduler.push(frame, class, now);
            return;
        };
        self.stats.compact_merged += 1;
        self.stats.compact_samples_dropped += loss.samples as u64;
        let frame = self.radio_sender.frame(&MavMessage::MAVLORA_COMPACT(data));
        if urgent && waiting == Some(Class::Periodic) {
            // to the commands' queue, and nothing older left behind to arrive after it
            self.scheduler.take_telemetry(system, component, id);
            self.scheduler.push(frame, Class::Command, now);
        } else if let Err(frame) = self.scheduler.replace_waiting(frame) {
            // cannot happen: it waited a moment ago
            self.scheduler.push(frame, class, now);
        }
    }

    /// The loss a command's ack meets on the radio: the worse direction.
    fn link_loss(&self, now: Instant) -> Option<f64> {
        link_loss(self.quality.own_loss(now), self.quality.peer_loss(now))
    }

    fn drain_mission(&mut self, now: Instant) {
        while let Some(msg) = self.mission.poll_radio() {
            let frame = self.radio_sender.frame(&msg);
            self.scheduler.push(frame, Class::Protocol, now);
        }
        let fc = self.watch.fc().unwrap_or((self.radio_sender.system(), 1));
        while let Some(msg) = self.mission.poll_fc(fc) {
            let frame = self.fc_sender.frame(&msg);
            self.to_fc.push_back(frame);
        }
    }

    /// Hands the scheduler the parameter list's next packed frame once the one before has
    /// left: the values wait in the packer meanwhile, so each frame is as full as the radio's
    /// pace lets it be. Answers to reads beyond their share take turns with the list's frames.
    fn refill_params(&mut self, now: Instant) {
        let Some(packer) = &mut self.params else {
            return;
        };
        while self.scheduler.queued_params() == 0 {
            if !self.answer_had_turn
                && let Some(answer) = self.paced_answers.pop_front()
            {
                self.answer_had_turn = true;
                self.scheduler.push(answer, Class::Param, now);
                continue;
            }
            let Some((system, packed)) = packer.poll(now) else {
                match self.paced_answers.pop_front() {
                    Some(answer) => {
                        self.answer_had_turn = true;
                        self.scheduler.push(answer, Class::Param, now);
                        continue;
                    }
                    None => break,
                }
            };
            self.answer_had_turn = false;
            let header = MavHeader {
                system_id: system.into(),
                component_id: self.config.component_id,
                // the radio leg numbers what leaves
                sequence: 0,
            };
            let frame = encode(
                MavlinkVersion::V2,
                header,
                &MavMessage::MAVLORA_PARAM_VALUES(packed),
            );
            packer.charge(now, frame.as_bytes().len() + self.radio_leg.frame_extra());
            self.scheduler.push(frame, Class::Param, now);
        }
    }

    /// The next frame for the flight controller (the wire is not budgeted).
    pub fn poll_fc_transmit(&mut self, now: Instant) -> Option<OwnedFrame> {
        self.drain_mission(now);
        let frame = self.to_fc.pop_front()?;
        self.stats.to_fc_frames += 1;
        self.stats.to_fc_bytes += frame.as_bytes().len() as u64;
        Some(frame)
    }

    /// The next frame for the radio if the budget allows at `now` and it fits `room` bytes.
    pub fn poll_radio_transmit(&mut self, now: Instant, room: usize) -> Option<OwnedFrame> {
        self.drain_mission(now);
        loop {
            self.refill_params(now);
            let frame = self.scheduler.poll_transmit(now, room)?;
            if let Some(frame) = self.radio_leg.outgoing(frame, now) {
                self.quality.sent_frame(now);
                return Some(frame);
            }
        }
    }

    /// When the engine next needs [`handle_timeout`](Self::handle_timeout) or can send; a time
    /// already past means at once.
    pub fn poll_timeout(&self) -> Option<Instant> {
        [
            self.quality.poll_timeout(),
            self.scheduler.poll_timeout(),
            self.radio_leg.poll_timeout(),
            self.compactor.as_ref().and_then(|c| c.poll_timeout()),
            self.gcs_heartbeat.poll_timeout(),
            self.config_state.next_retry,
            self.mission.poll_timeout(),
            self.commands.poll_timeout(),
            // The next packed frame (or an answer waiting its turn), once the one before has
            // left.
            self.params
                .as_ref()
                .filter(|_| self.scheduler.queued_params() == 0)
                .and_then(|p| {
                    if self.paced_answers.is_empty() {
                        p.poll_timeout()
                    } else {
                        Some(Instant::ZERO)
                    }
                }),
            // Frames (mission replies) waiting for the flight controller: due at once.
            (!self.to_fc.is_empty()).then_some(Instant::ZERO),
        ]
        .into_iter()
        .flatten()
        .min()
    }
}

/// The `mission_type` of a mission-protocol message (`None`: not one, or none carried).
// MISSION_ITEM and MISSION_REQUEST are deprecated but older ground stations still send them.
#[allow(deprecated)]
fn mission_type(msg: &MavMessage) -> Option<MavMissionType> {
    Some(match msg {
        MavMessage::MISSION_CLEAR_ALL(m) => m.mission_type,
        MavMessage::MISSION_COUNT(m) => m.mission_type,
        MavMessage::MISSION_WRITE_PARTIAL_LIST(m) => m.mission_type,
        MavMessage::MISSION_REQUEST_LIST(m) => m.mission_type,
        MavMessage::MISSION_REQUEST_PARTIAL_LIST(m) => m.mission_type,
        MavMessage::MISSION_REQUEST(m) => m.mission_type,
        MavMessage::MISSION_REQUEST_INT(m) => m.mission_type,
        MavMessage::MISSION_ITEM(m) => m.mission_type,
        MavMessage::MISSION_ITEM_INT(m) => m.mission_type,
        MavMessage::MISSION_ACK(m) => m.mission_type,
        _ => return None,
    })
}
