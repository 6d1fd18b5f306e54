//! The router state machine.

use crate::command::ack_tag::Epoch;
use crate::time::Duration;
use std::collections::{HashMap, VecDeque};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};

use mavlink::{MavHeader, MavlinkVersion, Message};

use super::trust::{GroundInput, GroundPolicy, GroundRejection, TrustStats};
use crate::command::ack_tag::untag_ack;
use crate::command::{
    Admission, CommandRetransmitter, Redundancy, RetransmitStats, link_loss, random_epoch,
};
use crate::compact::Expander;
use crate::dialect::{
    MavMessage, MavSeverity, PARAM_REQUEST_READ_DATA, RADIO_STATUS_DATA, STATUSTEXT_DATA,
};
use crate::filter::{FilterStats, Profile, RadioFilter, Verdict};
use crate::mission::{MissionTerminator, TerminatorConfig, TerminatorStats};
use crate::param::{
    CacheRadio, HASH_CHECK_NAME, ParamCache, ParamCacheStats, ParamValue, ReadGate, ReadGateStats,
    pack as param_pack, param_value_frame,
};
use crate::quality::{
    LinkMonitor, LinkQuality, LinkQualityConfig, MonitorConfig, Notice, is_local_radio_status,
};
use crate::schedule::{
    Class, LinkScheduler, Origin, ScheduleError, SchedulerConfig, SchedulerStats,
};
use crate::signing::{LinkSigner, RadioLeg, SigningConfig, SigningStats, is_link_frame};
use crate::time::Instant;
use crate::wire::{
    FrameReader, Integrity, OwnedFrame, ReaderStats, Sender, StreamId, encode, ids, known,
};

/// Router settings.
#[derive(Debug, Clone)]
pub struct RouterConfig {
    /// The ground→air radio byte budget.
    pub scheduler: SchedulerConfig,
    /// The most the radio may hold unsent ([`LinkScheduler::with_radio_backlog`]); `None`:
    /// no limit but the budget's burst.
    pub radio_backlog: Option<Duration>,
    /// Link-quality reports.
    pub quality: LinkQualityConfig,
    /// What the ground station is told about the link (`RADIO_STATUS`, `STATUSTEXT`).
    pub monitor: MonitorConfig,
    /// Our system id (reports we originate).
    pub system_id: u8,
    /// Our component id.
    pub component_id: u8,
    /// Component id the expanded standard messages claim (the vehicle's autopilot).
    pub autopilot_component: u8,
    /// At most one ground heartbeat per sender per this period goes over the radio; the
    /// bridge regenerates them at 1 Hz for the flight controller until one period and a
    /// margin after the last it heard. Default: [`gcs_heartbeat_period_for`] the budget.
    pub gcs_heartbeat_period: Duration,
    /// Mission uploads: the ground's transfer ends here (keep-alive, radio polls).
    pub mission: TerminatorConfig,
    /// First timeout before a command is resent over the radio; later ones follow the
    /// measured command round trip.
    pub command_initial_rto: Duration,
    /// Sends of one command over the radio, the first included; 1 turns retransmission off.
    /// The default, 8, outlasts a ground station's 5 tries 1.5 s apart.
    pub command_attempts: u32,
    /// Redundant copies of each command on a lossy link, before any timeout, and the
    /// shortest resend timeout (see [`CommandRetransmitter::with_redundancy`]); the radio's
    /// timing (default: SiK 64k). `None`: only timeouts resend.
    pub command_redundancy: Option<Redundancy>,
    /// This run's mark on every command it sends on the radio, so the bridge never takes
    /// a command of this run for one of a previous run with the same generation (see
    /// [`CommandRetransmitter::with_epoch`]); drawn at random by [`RouterConfig::new`].
    pub command_epoch: Epoch,
    /// Sign radio frames and accept only signed, fresh ones; `None`: no signing.
    pub signing: Option<SigningConfig>,
    /// Who on the ground may reach the vehicle (addresses, system ids, command budget).
    pub ground: GroundPolicy,
    /// MAVLink 2 signing towards the ground stations with their own key (not the radio
    /// link's): frames from the ground must be signed with it (and fresh), frames to the
    /// ground are signed with it. `None`: the ground side is unsigned.
    pub ground_signing: Option<SigningConfig>,
    /// Answer a ground's `PARAM_REQUEST_LIST` from the parameter cache when the vehicle's
    /// `_HASH_CHECK` says its parameters are unchanged (see [`ParamCache`]); `false`: every
    /// list crosses the radio.
    pub param_cache: bool,
}

/// The share of the radio budget the ground's heartbeats may take by default.
pub const GCS_HEARTBEAT_SHARE: f64 = 0.025;
/// The longest default period of the ground's heartbeats over the radio (the bridge's
/// assumption until it has measured the router's).
pub const GCS_HEARTBEAT_LONGEST: Duration = Duration::from_secs(5);
/// A signed ground `HEARTBEAT` on the radio: 9 bytes of payload, 12 of framing, 13 of
/// signature.
const SIGNED_HEARTBEAT_BYTES: f64 = 34.0;

/// The ground's heartbeats over a radio of `rate` bytes/s: each of the ground's own (1 Hz)
/// when [`GCS_HEARTBEAT_SHARE`] of the budget carries that (SiK 64k: the flight controller
/// hears of a link loss at most 3 s late), else as often as the share allows, at most
/// [`GCS_HEARTBEAT_LONGEST`] apart (LoRa SF7: 5 s, and up to 7 s late).
pub fn gcs_heartbeat_period_for(rate_bytes_per_s: u32) -> Duration {
    let secs = SIGNED_HEARTBEAT_BYTES / (GCS_HEARTBEAT_SHARE * f64::from(rate_bytes_per_s.max(1)));
    Duration::from_secs_f64(secs.clamp(1.0, GCS_HEARTBEAT_LONGEST.as_secs_f64()))
}

impl RouterConfig {
    /// Defaults around a radio budget.
    pub fn new(scheduler: SchedulerConfig) -> Self {
        Self {
            scheduler,
            radio_backlog: None,
            quality: LinkQualityConfig::for_budget(scheduler.rate_bytes_per_s, false),
            monitor: MonitorConfig::default(),
            system_id: 255,
            component_id: 191,
            autopilot_component: 1,
            gcs_heartbeat_period: gcs_heartbeat_period_for(scheduler.rate_bytes_per_s),
            mission: TerminatorConfig::default(),
            command_initial_rto: Duration::from_millis(1000),
            command_attempts: 8,
            command_redundancy: Some(Redundancy::SIK_64K),
            command_epoch: random_epoch(),
            signing: None,
            ground: GroundPolicy::default(),
            ground_signing: None,
            param_cache: true,
        }
    }
}

/// Router counters.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RouterStats {
    /// What the radio side reader saw.
    pub radio_reader: ReaderStats,
    /// What the ground-station side reader saw.
    pub gcs_reader: ReaderStats,
    /// Ground→radio filter (heartbeat thinning).
    pub filter: FilterStats,
    /// Radio budget scheduler.
    pub scheduler: SchedulerStats,
    /// Compact frames expanded.
    pub expanded_frames: u64,
    /// Compact frames that could not be decoded (a bridge of another version).
    pub compact_undecodable: u64,
    /// Standard messages produced by expansion.
    pub expanded_messages: u64,
    /// `MAVLORA_PARAM_VALUES` frames given to the ground as their `PARAM_VALUE`s.
    pub param_frames_expanded: u64,
    /// `PARAM_VALUE`s they gave.
    pub param_values_expanded: u64,
    /// `MAVLORA_PARAM_VALUES` frames refused as malformed (a bridge of another version):
    /// nothing of them reaches the ground.
    pub param_frames_undecodable: u64,
    /// The ground's reads by index: forwarded, and held (the list in flight brings the value,
    /// or the same read is in flight).
    pub param_reads: ReadGateStats,
    /// The parameter cache: lists served from it, checks, misses.
    pub param_cache: ParamCacheStats,
    /// Frames sent to the ground station.
    pub to_gcs_frames: u64,
    /// Bytes sent to the ground station.
    pub to_gcs_bytes: u64,
    /// Mission uploads terminated here: started, accepted, failed, repairs, keep-alives.
    pub mission: TerminatorStats,
    /// The command relay's resends and dropped ground retries.
    pub commands: RetransmitStats,
    /// `LINK_QUALITY` reports sent to the radio.
    pub link_quality_sent: u64,
    /// `STATUSTEXT` link announcements sent to the ground.
    pub link_notices: u64,
    /// `RADIO_STATUS` sent to the ground.
    pub radio_status_sent: u64,
    /// `LINK_QUALITY` frames from the ground, dropped: only the router speaks for the
    /// ground end of the link.
    pub ground_link_quality_dropped: u64,
    /// Radio link signing (all zero when signing is off).
    pub signing: SigningStats,
    /// What the ground-side gate rejected.
    pub ground: TrustStats,
    /// Ground-side signing (all zero when it is off).
    pub ground_signing: SigningStats,
}

/// Sans-IO router engine.
#[derive(Debug)]
pub struct Router {
    config: RouterConfig,
    radio_reader: FrameReader,
    gcs_reader: FrameReader,
    quality: LinkQuality,
    monitor: LinkMonitor,
    /// The vehicle's system id, from its link-quality reports (or its first frame).
    vehicle: Option<u8>,
    scheduler: LinkScheduler,
    heartbeat_filter: RadioFilter,
    expander: Expander,
    /// The ground's reads of values a list in flight brings wait here.
    param_reads: ReadGate,
    /// Lists delivered, given again from here while the vehicle's hash says unchanged; a
    /// held request keeps its frame and the scheduler origin of its sender.
    param_cache: ParamCache<(OwnedFrame, Origin)>,
    mission: MissionTerminator,
    commands: CommandRetransmitter,
    sender: Sender,
    /// Streams towards the ground station that we renumber, by (system, component).
    resequenced: HashMap<(u8, u8), u8>,
    to_gcs: VecDeque<OwnedFrame>,
    /// Renumbers and signs what leaves on the radio, verifies what arrives.
    radio_leg: RadioLeg,
    /// Verifies what the ground sends and signs what it gets, with the ground key.
    ground_signer: Option<LinkSigner>,
    /// When each (source, reason) rejection was last reported.
    reported: HashMap<(IpAddr, GroundRejection), Instant>,
    /// Link announcements sent to the ground, for [`Router::poll_link_notice`].
    sent_notices: VecDeque<Notice>,
    stats: RouterStats,
}

/// Announcements kept for [`Router::poll_link_notice`]; an engine nobody polls (in-process
/// runs) keeps the latest ones only.
const SENT_NOTICES_KEPT: usize = 32;

/// Where a router's mission transfers start numbering: from its radio signing clock (the
/// wall clock or the persisted timestamp, in 10 µs units, so it differs from one start to
/// the next), else from `now`. A restarted router that numbered from 0 again gave the same
/// plan the same transfer id as before the restart, which the bridge may still hold as
/// finished and accepted.
fn first_generation(radio_leg: &RadioLeg, now: Instant) -> u8 {
    let clock = radio_leg
        .signing_state(now)
        .map_or(now.as_micros(), |s| s.timestamp);
    clock.to_le_bytes().iter().fold(0, |a, b| a ^ b)
}

/// Ground sources (address and reason) whose rejections are logged individually within one
/// `log_every`; beyond that they are only counted (`ground_rejected`).
pub(crate) const REPORTED_SOURCES: usize = 1024;

/// The source [`Router::handle_gcs_bytes`] stands for: an in-process ground station.
const IN_PROCESS: SocketAddr = SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 0);

impl Router {
    /// A router started at `now`.
    pub fn new(config: RouterConfig, now: Instant) -> Result<Self, ScheduleError> {
        let hz = 1.0 / config.gcs_heartbeat_period.as_secs_f64().max(1e-3);
        let radio_leg = RadioLeg::new(config.signing.as_ref());
        let profile = Profile::parse(&format!("[messages.HEARTBEAT]\nradio = {hz}\n"), "router")
            .expect("a positive rate is a valid profile");
        Ok(Self {
            radio_reader: RadioLeg::reader(config.signing.as_ref()),
            gcs_reader: FrameReader::new(),
            quality: LinkQuality::new(config.quality, now),
            monitor: LinkMonitor::new(config.monitor),
            vehicle: None,
            scheduler: LinkScheduler::new(config.scheduler, now)?
                .with_frame_extra(radio_leg.frame_extra())
                .with_radio_backlog(config.radio_backlog, now),
            heartbeat_filter: RadioFilter::new(profile),
            expander: Expander::new(),
            param_reads: ReadGate::default(),
            param_cache: ParamCache::default(),
            mission: MissionTerminator::new(TerminatorConfig {
                pace_bytes_per_s: config
                    .mission
                    .pace_bytes_per_s
                    .or(Some(config.scheduler.rate_bytes_per_s)),
                // Pacing counts each frame as long as it is on the radio.
                frame_extra_bytes: radio_leg.frame_extra() as u32,
                ..config.mission
            })
            .with_generation(first_generation(&radio_leg, now)),
            // Never slower than a ground station's own 1.5 s retry: loss on a radio is not
            // congestion, so doubling the timeout past it only adds latency.
            commands: {
                let c = CommandRetransmitter::new(
                    config.command_initial_rto,
                    Duration::from_millis(200),
                    Duration::from_millis(1500),
                    config.command_attempts,
                )
                .with_source_limit(config.ground.commands_in_flight)
                .with_budget(config.scheduler.rate_bytes_per_s)
                .with_epoch(config.command_epoch, now);
                match config.command_redundancy {
                    Some(r) => c.with_redundancy(r),
                    None => c,
                }
            },
            sender: Sender::new(config.system_id, config.component_id, MavlinkVersion::V2),
            resequenced: HashMap::new(),
            to_gcs: VecDeque::new(),
            radio_leg,
            reported: HashMap::new(),
            sent_notices: VecDeque::new(),
            ground_signer: config.ground_signing.as_ref().map(SigningConfig::signer),
            stats: RouterStats::default(),
            config,
        })
    }

    /// Whether radio frames are signed.
    pub fn radio_signed(&self) -> bool {
        self.radio_leg.signed()
    }

    /// The radio signer's state to store at `now` (`None`: signing off).
    pub fn signing_state(&self, now: Instant) -> Option<crate::signing::SigningState> {
        self.radio_leg.signing_state(now)
    }

    /// The ground signer's state to store at `now` (`None`: ground signing off): its
    /// timestamp and the ground stations' streams it accepted, so that a restarted router
    /// still refuses a ground frame captured before the restart.
    pub fn ground_signing_state(&self, now: Instant) -> Option<crate::signing::SigningState> {
        self.ground_signer.as_ref().map(|s| s.state(now))
    }

    /// Counters as of now.
    pub fn stats(&self) -> RouterStats {
        RouterStats {
            radio_reader: self.radio_reader.stats().clone(),
            gcs_reader: self.gcs_reader.stats().clone(),
            filter: self.heartbeat_filter.stats(),
            scheduler: self.scheduler.stats(),
            mission: self.mission.stats(),
            commands: self.commands.stats(),
            signing: self.radio_leg.stats(),
            compact_undecodable: self.expander.undecodable(),
            param_reads: self.param_reads.stats(),
            param_cache: self.param_cache.stats(),
            ground_signing: self
                .ground_signer
                .as_ref()
                .map(LinkSigner::stats)
                .unwrap_or_default(),
            ..self.stats.clone()
        }
    }

    /// The link-quality engine.
    pub fn quality(&self) -> &LinkQuality {
        &self.quality
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

    /// What the ground station is told about the link.
    pub fn monitor(&self) -> &LinkMonitor {
        &self.monitor
    }

    /// The radio's serial port was closed.
    pub fn radio_port_closed(&mut self) {
        self.radio_reader.finish();
        while self.radio_reader.next_frame().is_some() {}
    }

    /// No byte came from the radio for longer than a frame takes: a partial frame still
    /// buffered lost its tail; it is dropped and frames behind it are handled.
    pub fn handle_radio_idle(&mut self, now: Instant) {
        if self.radio_reader.flush_partial() {
            self.handle_radio_bytes(now, &[]);
        }
    }

    /// Whole frames from an in-process ground station (tests, the simulated world): as
    /// from `127.0.0.1`, see [`handle_gcs_input`](Self::handle_gcs_input).
    pub fn handle_gcs_bytes(&mut self, now: Instant, bytes: &[u8]) -> GroundInput {
        self.handle_gcs_input(now, IN_PROCESS, bytes)
    }

    /// Whole frames (one, in the binary: the UDP thread frames each datagram and drops its
    /// partial tail, the TCP thread frames each client's stream) from the ground station at
    /// `from`. Frames go to the radio only if the ground policy allows the address and the
    /// frame's system id and the source's command budget has room; the answer says whether
    /// `from` may become the UDP peer and what to report.
    pub fn handle_gcs_input(
        &mut self,
        now: Instant,
        from: SocketAddr,
        bytes: &[u8],
    ) -> GroundInput {
        let mut input = GroundInput::default();
        if !self.config.ground.allows_address(from.ip()) {
            input.rejected = 1;
            self.reject(now, from, GroundRejection::Address, &mut input);
            return input;
        }
        self.gcs_reader.push(bytes);
        while let Some(rx) = self.gcs_reader.next_frame() {
            let mut frame = rx.frame;
            if let Some(signer) = &mut self.ground_signer {
                match signer.verify(&frame, now) {
                    Ok(plain) => frame = plain,
                    Err(_) => {
                        input.rejected += 1;
                        self.reject(now, from, GroundRejection::Signature, &mut input);
                        continue;
                    }
                }
            }
            if !self.config.ground.allows_system(frame.system_id()) {
                input.rejected += 1;
                self.reject(
                    now,
                    from,
                    GroundRejection::SystemId(frame.system_id()),
                    &mut input,
                );
                continue;
            }
            // The radio carries MAVLink 2 only. Frames for the ground leave as MAVLink 2; the
            // endpoints give a station that speaks MAVLink 1 its own copy in MAVLink 1.
            let Some(frame) = self.radio_leg.admit(frame) else {
                continue;
            };
            let id = frame.message_id();
            if matches!(id, ids::COMMAND_INT | ids::COMMAND_LONG)
                && let Ok(msg) = frame.decode::<MavMessage>()
            {
                self.commands.set_link_loss(now, self.link_loss(now));
                match self.commands.from_ground(now, from, &frame, &msg) {
                    Admission::Forward(f) => {
                        input.accepted += usize::from(rx.integrity == Integrity::Checked);
                        let origin = Origin::tagged(&f, from);
                        self.scheduler.push_from(f, Class::Command, origin, now);
                        continue;
                    }
                    Admission::Hold | Admission::Retry => {
                        input.accepted += 1;
                        continue;
                    }
                    Admission::OverBudget => {
                        input.rejected += 1;
                        self.reject(now, from, GroundRejection::CommandBudget, &mut input);
                        continue;
                    }
                }
            }
            if rx.integrity == Integrity::Checked {
                input.accepted += 1;
            }
            if id == ids::LINK_QUALITY {
                self.stats.ground_link_quality_dropped += 1;
                continue;
            }
            // Packed mission items and parameter values exist on the radio leg only (the
            // router's own, the bridge's).
            if matches!(id, ids::MAVLORA_MISSION_ITEMS | ids::MAVLORA_PARAM_VALUES) {
                continue;
            }
            // A read of what the list in flight brings, or of a value already asked for, waits.
            if id == ids::PARAM_REQUEST_READ
                && let Ok(MavMessage::PARAM_REQUEST_READ(r)) = frame.decode::<MavMessage>()
                && !self.param_reads.read(now, &r)
            {
                continue;
            }
            // A list the cache may answer waits for the vehicle's hash.
            if id == ids::PARAM_REQUEST_LIST
                && self.config.param_cache
                && let Ok(MavMessage::PARAM_REQUEST_LIST(r)) = frame.decode::<MavMessage>()
            {
                let origin = Origin::tagged(&frame, from);
                let back = self.param_cache.request_list(
                    now,
                    r.target_system,
                    r.target_component,
                    (frame, origin),
                );
                self.drain_param_cache(now);
                if let Some((frame, origin)) = back {
                    self.scheduler.push_from(frame, Class::of(id), origin, now);
                }
                continue;
            }
            if id == ids::HEARTBEAT {
                if self.heartbeat_filter.check(&frame, now) != Verdict::Pass {
                    continue;
                }
            } else if matches!(
                id,
                ids::MISSION_COUNT
                    | ids::MISSION_ITEM_INT
                    | ids::MISSION_ITEM
                    | ids::MISSION_ACK
                    | ids::MISSION_CLEAR_ALL
                    | ids::MISSION_WRITE_PARTIAL_LIST
                    | ids::MISSION_REQUEST_LIST
                    | ids::MISSION_REQUEST_PARTIAL_LIST
                    | ids::MISSION_REQUEST_INT
                    | ids::MISSION_REQUEST
            ) && let Ok(msg) = frame.decode::<MavMessage>()
                && self.mission.from_ground(
                    now,
                    (frame.system_id(), frame.component_id()),
                    self.config.autopilot_component,
                    &msg,
                )
            {
                // The ground's upload ends here (see `mission`).
                self.drain_mission(now);
                continue;
            }
            // each ground station takes its turn: one that floods waits behind itself
            let origin = Origin::tagged(&frame, from);
            self.scheduler.push_from(frame, Class::of(id), origin, now);
        }
        input
    }

    /// Counts a rejection; sets `input.report` when none was reported for this source and
    /// reason within the policy's `log_every`.
    fn reject(
        &mut self,
        now: Instant,
        from: SocketAddr,
        why: GroundRejection,
        input: &mut GroundInput,
    ) {
        // Reported per address: a host's applications are one source to the log.
        let from = from.ip();
        self.stats.ground.count(why);
        let every = self.config.ground.log_every;
        if self.reported.len() >= REPORTED_SOURCES {
            self.reported
                .retain(|_, at| now.saturating_duration_since(*at) < every);
        }
        let due = match self.reported.get(&(from, why)) {
            Some(at) => now.saturating_duration_since(*at) >= every,
            // More sources than that within one period (60,000 addresses took 9.3 MB and
            // wrote 7.9 MB of log): the rest are counted, not remembered or logged each.
            None => self.reported.len() < REPORTED_SOURCES,
        };
        if due {
            self.reported.insert((from, why), now);
            input.report.get_or_insert(why);
            // A station we let in by address but refuse a frame of is ours to help: MAVSDK
            // timing out at id 245 had no word of why (issue 22 item 11). With ground
            // signing, a sender without the key is the stranger that policy is for: told
            // nothing, as a stranger by address.
            if matches!(
                why,
                GroundRejection::SystemId(_) | GroundRejection::CommandBudget
            ) && input.reply.is_none()
            {
                input.reply = Some(self.refusal_text(why));
            }
        }
    }

    /// The `STATUSTEXT` a refused ground station gets: why, in the 50 characters it holds.
    fn refusal_text(&mut self, why: GroundRejection) -> OwnedFrame {
        let mut text = format!("MavLora router refused: {why}");
        if text.len() > 50 {
            let mut end = 50;
            while !text.is_char_boundary(end) {
                end -= 1;
            }
            text.truncate(end);
        }
        self.sender.frame(&MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            severity: MavSeverity::MAV_SEVERITY_WARNING,
            text: text.as_str().into(),
            ..Default::default()
        }))
    }

    /// Bytes from the radio's serial port.
    pub fn handle_radio_bytes(&mut self, now: Instant, bytes: &[u8]) {
        self.radio_reader.push(bytes);
        while let Some(rx) = self.radio_reader.next_frame() {
            // The local radio's own report (SiK injects it into its serial output): never
            // signed, never the vehicle, folded into ours for the ground.
            if is_local_radio_status(&rx.frame) {
                self.local_radio_frame(&rx.frame);
                continue;
            }
            // Only frames the peer signed count as received: loss is the peer's frames lost.
            let Some(frame) = self.radio_leg.incoming(rx.frame, now) else {
                continue;
            };
            // Nothing counts while the peer is still to prove it is live (a fresh signing
            // state): its frames refused meanwhile would read as lost.
            if !self.radio_leg.awaiting_proof() {
                self.radio_reader.accept(&frame, rx.integrity);
            }
            // The link carries something: a command's timeout means loss again, not silence.
            self.commands.heard_radio(now);
            self.quality.handle_frame(now, &frame);
            if self.quality.take_peer_restart() {
                self.radio_reader.expect_restart(StreamId {
                    system: frame.system_id(),
                    component: frame.component_id(),
                });
            }
            if self.vehicle.is_none() || frame.message_id() == ids::LINK_QUALITY {
                self.vehicle = Some(frame.system_id());
            }
            match frame.message_id() {
                // The ground's RADIO_STATUS is ours (the link monitor's), built from both
                // radios' reports; the far end has none to send.
                ids::RADIO_STATUS => {}
                // The signing handshake is the radio leg's (done in `incoming`).
                ids::TIMESYNC if is_link_frame(&frame) => {}
                ids::MAVLORA_COMPACT => {
                    if let Ok(msg) = frame.decode::<MavMessage>() {
                        self.expand(now, frame.system_id(), frame.component_id(), &msg);
                    }
                }
                ids::MAVLORA_PARAM_VALUES => self.expand_params(now, &frame),
                ids::PARAM_VALUE => {
                    let value = ParamValue::from_payload(frame.payload());
                    let from = (frame.system_id(), frame.component_id());
                    if let Some(v) = &value {
                        self.param_reads.answered(now, from.0, from.1, v.index);
                    }
                    self.push_gcs(now, frame);
                    // after the frame: the vehicle's hash goes first, as on a list of its own
                    if let Some(v) = value {
                        self.param_cache.value(now, from.0, from.1, &v);
                        self.drain_param_cache(now);
                    }
                }
                ids::MISSION_REQUEST
                | ids::MISSION_REQUEST_INT
                | ids::MISSION_REQUEST_PARTIAL_LIST
                | ids::MISSION_ACK => {
                    let Ok(msg) = frame.decode::<MavMessage>() else {
                        // An ack nobody can read answers nothing a ground is waiting on.
                        if frame.message_id() != ids::MISSION_ACK {
                            self.push_gcs(now, frame);
                        }
                        continue;
                    };
                    // The bridge addresses its side of the radio leg to us; the autopilot
                    // addresses the ground stations (requests of their partial writes, acks
                    // of their clear-alls: ArduPilot's with `opaque_id` 0, PX4's with one).
                    let to_us = msg.target_system_id() == Some(self.config.system_id)
                        && msg.target_component_id() == Some(self.config.component_id);
                    if to_us {
                        if self.mission.from_radio(now, &msg) {
                            self.drain_mission(now);
                        }
                        continue;
                    }
                    if self.mission.from_vehicle(now, &msg) {
                        self.push_gcs(now, frame);
                    }
                }
                ids::COMMAND_ACK => {
                    let Ok(MavMessage::COMMAND_ACK(ack)) = frame.decode::<MavMessage>() else {
                        self.push_gcs(now, frame);
                        continue;
                    };
                    // The bridge's tag names the command answered; the ground gets the ack
                    // as the autopilot sent it.
                    let (tag, frame, ack) = match untag_ack(&frame, &ack) {
                        Some((tag, plain, ack)) => (Some(tag), plain, ack),
                        None => (None, frame, ack),
                    };
                    let (system, component) = (frame.system_id(), frame.component_id());
                    let msg = MavMessage::COMMAND_ACK(ack);
                    if self
                        .commands
                        .from_radio_tagged(now, system, component, &msg, tag)
                    {
                        self.push_gcs(now, frame);
                    }
                }
                _ => self.push_gcs(now, frame),
            }
        }
        self.quality.observe(now, self.radio_reader.stats());
    }

    fn expand(&mut self, now: Instant, system: u8, component: u8, msg: &MavMessage) {
        self.stats.expanded_frames += 1;
        let expanded = self.expander.expand(now, system, msg);
        for out in &expanded.messages {
            self.enqueue_expanded(now, system, out);
        }
        // The bridge's link report rode in the frame: for the link monitor as if its own
        // LINK_QUALITY had come, and to the ground as that LINK_QUALITY (its sender's ids).
        if let Some(report) = expanded.link {
            self.vehicle = Some(system);
            self.quality.handle_report(now, report.clone());
            let header = MavHeader {
                system_id: system.into(),
                component_id: component,
                sequence: self.next_sequence((system, component)),
            };
            self.enqueue_gcs(
                now,
                encode(
                    MavlinkVersion::V2,
                    header,
                    &MavMessage::LINK_QUALITY(report),
                ),
            );
        }
    }

    /// A packed parameter frame: its values to the ground as the standard `PARAM_VALUE`s of
    /// the component that sent them, in that stream's numbering, byte for byte; a malformed
    /// frame gives nothing and is counted.
    fn expand_params(&mut self, now: Instant, frame: &OwnedFrame) {
        let read = match frame.decode::<MavMessage>() {
            Ok(MavMessage::MAVLORA_PARAM_VALUES(p)) => {
                param_pack::unpack(&p).map(|v| (p.component, v)).ok()
            }
            _ => None,
        };
        let Some((component, values)) = read else {
            self.stats.param_frames_undecodable += 1;
            let n = self.stats.param_frames_undecodable;
            if n.is_power_of_two() {
                tracing::warn!(%now, refused = n, "malformed MAVLORA_PARAM_VALUES refused (a bridge of another version?) (logged at the 1st, 2nd, 4th... one)");
            }
            return;
        };
        self.stats.param_frames_expanded += 1;
        let system = frame.system_id();
        self.param_reads
            .list_values(now, system, component, &values);
        for value in &values {
            self.stats.param_values_expanded += 1;
            let sequence = self.next_sequence((system, component));
            self.enqueue_gcs(now, param_value_frame(system, component, sequence, value));
            self.param_cache.value(now, system, component, value);
        }
        self.drain_param_cache(now);
    }

    /// The parameter cache's checks and the requests it gives back to the radio; the lists
    /// it serves to the ground, each value as the component that sent it, in that stream's
    /// numbering.
    fn drain_param_cache(&mut self, now: Instant) {
        while let Some(out) = self.param_cache.poll_radio() {
            match out {
                CacheRadio::HashCheck { system, component } => {
                    tracing::debug!(%now, system, component, "asking the vehicle for its _HASH_CHECK");
                    let read = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                        target_system: system,
                        target_component: component,
                        param_id: HASH_CHECK_NAME.into(),
                        param_index: -1,
                    });
                    let frame = self.sender.frame(&read);
                    self.scheduler.push(frame, Class::Command, now);
                }
                CacheRadio::Forward((frame, origin)) => {
                    let class = Class::of(frame.message_id());
                    self.scheduler.push_from(frame, class, origin, now);
                }
            }
        }
        while let Some((system, component, values)) = self.param_cache.poll_served() {
            tracing::info!(%now, system, component, values = values.len(), "parameter list given from the cache: the vehicle's hash says unchanged");
            for value in &values {
                let sequence = self.next_sequence((system, component));
                self.enqueue_gcs(now, param_value_frame(system, component, sequence, value));
            }
        }
    }

    /// A standard message standing for compact frames, to the ground as the vehicle's
    /// autopilot in that stream's numbering.
    fn enqueue_expanded(&mut self, now: Instant, system: u8, msg: &MavMessage) {
        let component = self.config.autopilot_component;
        let header = MavHeader {
            system_id: system.into(),
            component_id: component,
            sequence: self.next_sequence((system, component)),
        };
        self.stats.expanded_messages += 1;
        self.enqueue_gcs(now, encode(MavlinkVersion::V2, header, msg));
    }

    fn next_sequence(&mut self, stream: (u8, u8)) -> u8 {
        let seq = self.resequenced.entry(stream).or_insert(0);
        let now = *seq;
        *seq = seq.wrapping_add(1);
        now
    }

    /// Forwards a radio frame, renumbering it if its stream is one we also synthesise into.
    fn push_gcs(&mut self, now: Instant, mut frame: OwnedFrame) {
        let stream = (frame.system_id(), frame.component_id());
        if self.resequenced.contains_key(&stream)
            && !frame.is_signed()
            && let Some(extra) = known::checkable_crc_extra(frame.message_id())
        {
            let seq = self.next_sequence(stream);
            frame.set_sequence(seq);
            frame.fill_checksum(extra);
        }
        self.enqueue_gcs(now, frame);
    }

    /// Queues a frame for the ground stations, signed at `now` with the ground key when
    /// ground signing is on (frames that cannot be signed, MAVLink 1 or unknown ids, are
    /// dropped: a station that signs would reject them).
    fn enqueue_gcs(&mut self, now: Instant, frame: OwnedFrame) {
        let frame = match &mut self.ground_signer {
            None => frame,
            Some(signer) => match signer.sign(&frame, now) {
                Some(signed) => signed,
                None => return,
            },
        };
        self.stats.to_gcs_frames += 1;
        self.stats.to_gcs_bytes += frame.as_bytes().len() as u64;
        self.to_gcs.push_back(frame);
    }

    /// Mission frames for the radio (transfers, in order: the radio leg relies on it) and for
    /// the ground (as the vehicle it addressed, in that stream's numbering).
    fn drain_mission(&mut self, now: Instant) {
        while let Some(msg) = self.mission.poll_radio(now) {
            let frame = self.sender.frame(&msg);
            self.scheduler.push(frame, Class::Protocol, now);
        }
        while let Some(((system, component), msg)) = self.mission.poll_ground() {
            let header = MavHeader {
                system_id: system.into(),
                component_id: component,
                sequence: self.next_sequence((system, component)),
            };
            self.enqueue_gcs(now, encode(MavlinkVersion::V2, header, &msg));
        }
    }

    /// Does what is due at `now`: our link-quality report (also shown to the ground
    /// station), command retransmissions, mission keep-alives and polls.
    pub fn handle_timeout(&mut self, now: Instant) {
        // The signing handshake's challenge or answer: small, and nothing else of the peer's
        // is taken before it, so with the commands.
        while let Some(msg) = self.radio_leg.poll_handshake(now) {
            let frame = self.sender.frame(&msg);
            self.scheduler.push(frame, Class::Command, now);
        }
        self.mission.handle_timeout(now);
        self.drain_mission(now);
        self.param_cache.handle_timeout(now);
        self.drain_param_cache(now);
        self.commands.set_link_loss(now, self.link_loss(now));
        self.commands.handle_timeout(now);
        while let Some(frame) = self.commands.poll_retransmit() {
            self.scheduler.push(frame, Class::Command, now);
        }
        self.quality.handle_timeout(now, self.radio_reader.stats());
        if let Some(report) = self.quality.poll_report() {
            let msg = MavMessage::LINK_QUALITY(report);
            self.stats.link_quality_sent += 1;
            self.scheduler
                .push(self.sender.frame(&msg), Class::Periodic, now);
            // The ground station's copy speaks for the vehicle's radio, as the link
            // announcements do: the router's own ids (system 0 until configured) name no
            // vehicle a ground station shows.
            self.send_as_radio(now, &[msg]);
        }
        self.link_monitor(now);
        while let Some((system, heartbeat)) = self.expander.poll_heartbeat(now) {
            self.enqueue_expanded(now, system, &heartbeat);
        }
    }

    /// The loss a command meets on the radio: the worse direction.
    fn link_loss(&self, now: Instant) -> Option<f64> {
        link_loss(self.quality.own_loss(now), self.quality.peer_loss(now))
    }

    /// `STATUSTEXT` announcements and `RADIO_STATUS` for the ground, as the vehicle's
    /// telemetry radio (component 68, as a SiK radio would), so ground stations that show
    /// only their vehicle's messages show these.
    fn link_monitor(&mut self, now: Instant) {
        self.monitor.handle_timeout(now, &self.quality);
        if self.vehicle.is_none() {
            return;
        }
        let mut out = Vec::new();
        while let Some(notice) = self.monitor.poll_notice() {
            self.stats.link_notices += 1;
            out.push(MavMessage::STATUSTEXT(notice.statustext()));
            if self.sent_notices.len() == SENT_NOTICES_KEPT {
                self.sent_notices.pop_front();
            }
            self.sent_notices.push_back(notice);
        }
        if let Some(status) = self.monitor.poll_radio_status(&self.quality) {
            self.stats.radio_status_sent += 1;
            out.push(MavMessage::RADIO_STATUS(status));
        }
        self.send_as_radio(now, &out);
    }

    /// Sends `messages` to the ground stations as the vehicle's telemetry radio (component
    /// 68, as a SiK radio would), so ground stations that show only their vehicle's messages
    /// show these; nothing before the vehicle is known.
    fn send_as_radio(&mut self, now: Instant, messages: &[MavMessage]) {
        const RADIO_COMPONENT: u8 = 68; // MAV_COMP_ID_TELEMETRY_RADIO
        let Some(system) = self.vehicle else {
            return;
        };
        for msg in messages {
            let header = MavHeader {
                system_id: system.into(),
                component_id: RADIO_COMPONENT,
                sequence: self.next_sequence((system, RADIO_COMPONENT)),
            };
            self.enqueue_gcs(now, encode(MavlinkVersion::V2, header, msg));
        }
    }

    /// The next frame for the ground station (already signed with the ground key when
    /// ground signing is on).
    pub fn poll_gcs_transmit(&mut self) -> Option<OwnedFrame> {
        self.to_gcs.pop_front()
    }

    /// The next frame for the radio if the budget allows at `now` and it fits `room` bytes.
    pub fn poll_radio_transmit(&mut self, now: Instant, room: usize) -> Option<OwnedFrame> {
        loop {
            let frame = self.scheduler.poll_transmit(now, room)?;
            if (frame.system_id(), frame.component_id())
                == (self.config.system_id, self.config.component_id)
                && matches!(
                    frame.message_id(),
                    ids::MISSION_COUNT | ids::MISSION_ITEM_INT | ids::MAVLORA_MISSION_ITEMS
                )
            {
                // The stream's window moves on.
                self.mission.radio_frame_left(now);
                self.drain_mission(now);
            }
            if let Some(frame) = self.radio_leg.outgoing(frame, now) {
                self.quality.sent_frame(now);
                return Some(frame);
            }
        }
    }

    /// The next link announcement sent to the ground (`STATUSTEXT`), oldest first: for the
    /// program's status file, where a test or an operator reads the link's history as data.
    pub fn poll_link_notice(&mut self) -> Option<Notice> {
        self.sent_notices.pop_front()
    }

    /// When the engine next needs attention; a time already past means at once.
    pub fn poll_timeout(&self) -> Option<Instant> {
        [
            self.quality.poll_timeout(),
            self.monitor.poll_timeout(),
            self.scheduler.poll_timeout(),
            self.radio_leg.poll_timeout(),
            self.commands.poll_timeout(),
            self.mission.poll_timeout(),
            self.expander.poll_timeout(),
            self.param_cache.poll_timeout(),
            // Frames waiting for the ground stations: due at once.
            (!self.to_gcs.is_empty()).then_some(Instant::ZERO),
        ]
        .into_iter()
        .flatten()
        .min()
    }
}
