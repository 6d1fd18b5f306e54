//! A ground station as the MAVLink mission protocol specifies it: heartbeats at 1 Hz, upload
//! with a per-step timeout (1500 ms by default, the spec's; SDKs often use 0.5 s) and a few
//! retries of the last message sent (5 by default; see [`GcsMock::with_mission_timeouts`]).

use mavlora::Duration;
use std::collections::VecDeque;

use mavlink::MavlinkVersion;

use mavlora::Instant;
use mavlora::dialect::{
    COMMAND_LONG_DATA, HEARTBEAT_DATA, MISSION_ACK_DATA, MISSION_CLEAR_ALL_DATA,
    MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA,
    MavAutopilot, MavCmd, MavFrame, MavMessage, MavMissionResult, MavMissionType, MavType,
};
use mavlora::wire::{FrameReader, OwnedFrame, Sender, ids};

use crate::gcs_params::{GcsParams, ParamDownload, ParamSet};

/// A mission download in progress.
#[derive(Debug)]
struct Download {
    count: Option<u16>,
    items: Vec<MISSION_ITEM_INT_DATA>,
    at: Instant,
    retries: u32,
}

#[derive(Debug)]
struct Upload {
    mission_type: MavMissionType,
    items: Vec<MISSION_ITEM_INT_DATA>,
    /// `None`: MISSION_COUNT was the last thing sent.
    last: Option<u16>,
    at: Instant,
    retries: u32,
}

/// Commands sent one at a time, as an operator's ground station does: a `COMMAND_LONG`, then
/// the same again every `retry` until a `COMMAND_ACK` for it arrives (QGroundControl and
/// MAVSDK resend unacknowledged commands), at most `attempts` copies; the next command
/// `period` after the last one finished. Commands alternate between
/// `MAV_CMD_DO_SET_MODE` (AUTO.MISSION, the mode the vehicle is already in) and
/// `MAV_CMD_DO_CHANGE_SPEED` (the cruise speed): harmless, and acks of consecutive commands
/// are told apart by their command id (`COMMAND_ACK` carries no sequence).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandPlan {
    /// Pause between the end of one command and the next.
    pub period: Duration,
    /// Resend after this long without an ack.
    pub retry: Duration,
    /// Copies sent at most before the command counts as failed.
    pub attempts: u32,
    /// A mix instead of the alternation: `DO_CHANGE_SPEED` with a new speed each time (same
    /// id, new parameters) and `DO_SET_MODE`, every third addressed to component 0 (all)
    /// instead of 1, and each carrying its serial number in `param7` (unused by both), so the
    /// autopilot's log tells which command ran how often.
    pub mix: bool,
}

impl Default for CommandPlan {
    /// A command every 2 s, resent after 1.5 s (the MAVLink command protocol's default
    /// timeout, as for missions), 5 copies at most.
    fn default() -> Self {
        Self {
            period: Duration::from_secs(2),
            retry: Duration::from_millis(1500),
            attempts: 5,
            mix: false,
        }
    }
}

/// What the command loop did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CommandStats {
    /// Commands started.
    pub started: u64,
    /// Copies sent, first ones and retries.
    pub copies: u64,
    /// Commands acknowledged.
    pub acked: u64,
    /// Commands given up after `attempts` copies without an ack.
    pub failed: u64,
    /// First copy sent → first matching ack, per acknowledged command, in order.
    pub latencies: Vec<Duration>,
    /// Serial numbers (see [`GcsMock::planned_command`]) of the commands given up.
    pub given_up: Vec<u64>,
}

#[derive(Debug)]
struct Pending {
    command: MavCmd,
    msg: COMMAND_LONG_DATA,
    first_sent: Instant,
    last_sent: Instant,
    copies: u32,
}

#[derive(Debug)]
struct Commands {
    plan: CommandPlan,
    next_at: Instant,
    pending: Option<Pending>,
    stats: CommandStats,
}

/// Simulated ground station (system 255, component 190) talking to vehicle 1/1.
#[derive(Debug)]
pub struct GcsMock {
    sender: Sender,
    reader: FrameReader,
    out: VecDeque<OwnedFrame>,
    next_heartbeat: Instant,
    upload: Option<Upload>,
    download: Option<Download>,
    timeout: Duration,
    retries: u32,
    /// Each repeated item request counts against `retries`, as a timeout does (MAVSDK).
    mavsdk_retries: bool,
    /// The last plan it started uploading, by type (what the vehicle should end up with).
    pub last_upload: Option<(MavMissionType, Vec<MISSION_ITEM_INT_DATA>)>,
    /// Uploads it cancelled itself.
    pub cancels: u64,
    /// Result of the last upload or clear, once finished.
    pub result: Option<(MavMissionResult, Instant)>,
    /// The last mission downloaded completely.
    pub downloaded: Option<Vec<MISSION_ITEM_INT_DATA>>,
    /// Items sent, retries included.
    pub items_sent: u64,
    /// Messages of each id received.
    pub received: std::collections::BTreeMap<u32, u64>,
    /// Each `GLOBAL_POSITION_INT` received: when, and its `time_boot_ms` (the autopilot's
    /// clock, which in the world starts with the world's): the position lag is the difference.
    pub positions: Vec<(Instant, u32)>,
    /// Each change of the vehicle's mode as its HEARTBEATs show it: when the first HEARTBEAT
    /// with a new (`custom_mode`, armed) arrived.
    pub modes: Vec<(Instant, u32, bool)>,
    commands: Option<Commands>,
    params: GcsParams,
}

impl GcsMock {
    /// A ground station started at `now`.
    pub fn new(now: Instant) -> Self {
        Self {
            sender: Sender::new(255, 190, MavlinkVersion::V2),
            reader: FrameReader::new(),
            out: VecDeque::new(),
            next_heartbeat: now,
            upload: None,
            download: None,
            timeout: Duration::from_millis(1500),
            retries: 5,
            mavsdk_retries: false,
            last_upload: None,
            cancels: 0,
            result: None,
            downloaded: None,
            items_sent: 0,
            received: Default::default(),
            positions: Vec::new(),
            modes: Vec::new(),
            commands: None,
            params: GcsParams::default(),
        }
    }

    /// Starts downloading the vehicle's parameters at `now`, as QGroundControl does (see
    /// [`crate::gcs_params`]).
    pub fn download_params(&mut self, now: Instant) {
        for msg in self.params.start(now) {
            self.send(&msg);
        }
    }

    /// Sends a `PARAM_SET` of `name` to `value` (its payload bytes: PX4's integers byte-wise)
    /// at `now`; sent again after 1 s until its echo comes, 5 sends at most.
    pub fn set_param(
        &mut self,
        now: Instant,
        name: &str,
        value: [u8; 4],
        param_type: mavlora::dialect::MavParamType,
    ) {
        for msg in self.params.set(now, name, value, param_type) {
            self.send(&msg);
        }
    }

    /// The parameter download, once started.
    pub fn param_download(&self) -> Option<&ParamDownload> {
        self.params.download.as_ref()
    }

    /// Every `PARAM_SET` sent, with its echo.
    pub fn param_sets(&self) -> &[ParamSet] {
        &self.params.sets
    }

    /// The same ground station counting retries as MAVSDK's mission transfer
    /// (`MavlinkMissionTransferClient::UploadWorkItem`) does: the count and each item sent
    /// count as one of its `retries`, a request for a new item starts them again, a request
    /// for an item it already sent is one more, and a timeout while it waits for a request or
    /// the ack is one more without sending anything (only the count is repeated). With 5
    /// retries of 0.5 s it gives up 2.5 s after its last send, without telling the vehicle.
    pub fn with_mavsdk_retry_counting(mut self) -> Self {
        self.mavsdk_retries = true;
        self
    }

    /// The same ground station with the mission protocol's per-step `timeout` and `retries`
    /// (the spec: 1.5 s and 5; SDKs: 0.5 s and 3).
    pub fn with_mission_timeouts(mut self, timeout: Duration, retries: u32) -> Self {
        self.timeout = timeout;
        self.retries = retries;
        self
    }

    /// Starts sending commands at `now` (see [`CommandPlan`]).
    pub fn start_commands(&mut self, plan: CommandPlan, now: Instant) {
        self.commands = Some(Commands {
            plan,
            next_at: now,
            pending: None,
            stats: CommandStats::default(),
        });
    }

    /// Makes room up front for `n` commands in the command loop's records (latencies, given
    /// up), so a long run's records do not grow the heap while it is measured (a soak).
    pub fn reserve_command_records(&mut self, n: usize) {
        if let Some(c) = &mut self.commands {
            c.stats.latencies.reserve(n);
            c.stats.given_up.reserve(n);
        }
    }

    /// Stops starting new commands; one in flight still waits for its ack.
    pub fn stop_commands(&mut self) {
        if let Some(c) = &mut self.commands {
            c.next_at = Instant::from_micros(u64::MAX);
        }
    }

    /// The command loop's counters (empty if never started).
    pub fn command_stats(&self) -> CommandStats {
        self.commands
            .as_ref()
            .map(|c| c.stats.clone())
            .unwrap_or_default()
    }

    /// The `serial`-th command of the plan (see [`CommandPlan`]).
    pub fn planned_command(serial: u64, mix: bool) -> COMMAND_LONG_DATA {
        let set_mode = if mix {
            serial % 3 == 1
        } else {
            serial.is_multiple_of(2)
        };
        let (command, param1, param2, param3) = if set_mode {
            // base mode: custom mode enabled; PX4 main mode AUTO (4), sub mode MISSION (4)
            (MavCmd::MAV_CMD_DO_SET_MODE, 1.0, 4.0, 4.0)
        } else if mix {
            // ground speed, 8 to 12 m/s: same id, new parameters
            (
                MavCmd::MAV_CMD_DO_CHANGE_SPEED,
                1.0,
                8.0 + (serial % 5) as f32,
                -1.0,
            )
        } else {
            // ground speed, 10 m/s, no throttle change
            (MavCmd::MAV_CMD_DO_CHANGE_SPEED, 1.0, 10.0, -1.0)
        };
        COMMAND_LONG_DATA {
            param1,
            param2,
            param3,
            param7: if mix { serial as f32 } else { 0.0 },
            command,
            target_system: 1,
            target_component: if mix && serial % 3 == 2 { 0 } else { 1 },
            ..COMMAND_LONG_DATA::default()
        }
    }

    fn commands_tick(&mut self, now: Instant) {
        let Some(c) = &mut self.commands else { return };
        let mut copy = None;
        if let Some(p) = &mut c.pending {
            if now >= p.last_sent + c.plan.retry {
                if p.copies >= c.plan.attempts {
                    c.stats.failed += 1;
                    // One command at a time: the pending one is the last started.
                    c.stats.given_up.push(c.stats.started - 1);
                    c.pending = None;
                    c.next_at = now + c.plan.period;
                } else {
                    p.copies += 1;
                    p.last_sent = now;
                    c.stats.copies += 1;
                    copy = Some(COMMAND_LONG_DATA {
                        confirmation: (p.copies - 1) as u8,
                        ..p.msg.clone()
                    });
                }
            }
        } else if now >= c.next_at {
            let msg = Self::planned_command(c.stats.started, c.plan.mix);
            c.stats.started += 1;
            c.stats.copies += 1;
            c.pending = Some(Pending {
                command: msg.command,
                msg: msg.clone(),
                first_sent: now,
                last_sent: now,
                copies: 1,
            });
            copy = Some(msg);
        }
        if let Some(msg) = copy {
            self.send(&MavMessage::COMMAND_LONG(msg));
        }
    }

    fn command_ack(&mut self, command: MavCmd, now: Instant) {
        let Some(c) = &mut self.commands else { return };
        if let Some(p) = &c.pending
            && p.command == command
        {
            c.stats.acked += 1;
            c.stats
                .latencies
                .push(now.saturating_duration_since(p.first_sent));
            c.pending = None;
            c.next_at = now + c.plan.period;
        }
    }

    fn commands_timeout(&self) -> Option<Instant> {
        let c = self.commands.as_ref()?;
        Some(match &c.pending {
            Some(p) => p.last_sent + c.plan.retry,
            None => c.next_at,
        })
    }

    /// `n` distinct waypoints.
    pub fn mission(n: u16) -> Vec<MISSION_ITEM_INT_DATA> {
        (0..n)
            .map(|seq| MISSION_ITEM_INT_DATA {
                seq,
                target_system: 1,
                target_component: 1,
                command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
                x: 553_700_000 + i32::from(seq) * 1000,
                y: 103_900_000 - i32::from(seq) * 700,
                z: 50.0 + f32::from(seq),
                autocontinue: 1,
                ..MISSION_ITEM_INT_DATA::default()
            })
            .collect()
    }

    /// Starts uploading `items` as the mission at `now`.
    pub fn upload(&mut self, items: Vec<MISSION_ITEM_INT_DATA>, now: Instant) {
        self.upload_typed(MavMissionType::MAV_MISSION_TYPE_MISSION, items, now);
    }

    /// Starts uploading `items` as a plan of `mission_type` at `now` (an upload in progress
    /// is replaced: a new `MISSION_COUNT` restarts the transfer).
    pub fn upload_typed(
        &mut self,
        mission_type: MavMissionType,
        items: Vec<MISSION_ITEM_INT_DATA>,
        now: Instant,
    ) {
        let count = items.len() as u16;
        let items: Vec<_> = items
            .into_iter()
            .map(|i| MISSION_ITEM_INT_DATA { mission_type, ..i })
            .collect();
        self.last_upload = Some((mission_type, items.clone()));
        self.upload = Some(Upload {
            mission_type,
            items,
            last: None,
            at: now,
            // MAVSDK counts the first count it sends as one of its tries.
            retries: u32::from(self.mavsdk_retries),
        });
        self.result = None;
        self.send(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count,
            target_system: 1,
            target_component: 1,
            mission_type,
            ..Default::default()
        }));
    }

    /// Cancels the upload in progress (the protocol's cancel: a `MISSION_ACK` with
    /// `MAV_MISSION_OPERATION_CANCELLED`). Returns whether one was in progress.
    pub fn cancel(&mut self) -> bool {
        let Some(up) = self.upload.take() else {
            return false;
        };
        self.cancels += 1;
        self.send(&MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: 1,
            target_component: 1,
            mavtype: MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
            mission_type: up.mission_type,
            ..Default::default()
        }));
        true
    }

    /// Whether an upload is in progress.
    pub fn uploading(&self) -> bool {
        self.upload.is_some()
    }

    /// Starts downloading the vehicle's mission at `now`.
    pub fn download(&mut self, now: Instant) {
        self.downloaded = None;
        self.download = Some(Download {
            count: None,
            items: Vec::new(),
            at: now,
            retries: 0,
        });
        self.send(&MavMessage::MISSION_REQUEST_LIST(
            MISSION_REQUEST_LIST_DATA {
                target_system: 1,
                target_component: 1,
                ..Default::default()
            },
        ));
    }

    /// Clears the vehicle's mission (the ack lands in `result`).
    pub fn clear(&mut self) {
        self.result = None;
        self.send(&MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
            target_system: 1,
            target_component: 1,
            ..Default::default()
        }));
    }

    fn request_item(&mut self, seq: u16) {
        self.send(&MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        }));
    }

    fn download_step(&mut self, msg: &MavMessage, now: Instant) {
        let Some(d) = &mut self.download else { return };
        let next = match msg {
            MavMessage::MISSION_COUNT(c) if c.target_system == 255 && d.count.is_none() => {
                d.count = Some(c.count);
                0
            }
            MavMessage::MISSION_ITEM_INT(i)
                if i.target_system == 255 && usize::from(i.seq) == d.items.len() =>
            {
                d.items.push(i.clone());
                d.items.len() as u16
            }
            _ => return,
        };
        d.at = now;
        d.retries = 0;
        if Some(next) == d.count {
            let items = std::mem::take(&mut d.items);
            self.download = None;
            self.downloaded = Some(items);
            self.send(&MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                target_system: 1,
                target_component: 1,
                mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
                ..Default::default()
            }));
        } else {
            self.request_item(next);
        }
    }

    fn send(&mut self, msg: &MavMessage) {
        let frame = self.sender.frame(msg);
        self.out.push_back(frame);
    }

    /// Bytes received from the vehicle side.
    pub fn handle_bytes(&mut self, now: Instant, bytes: &[u8]) {
        self.reader.push(bytes);
        while let Some(rx) = self.reader.next_frame() {
            *self.received.entry(rx.frame.message_id()).or_default() += 1;
            if rx.frame.message_id() == ids::PARAM_VALUE {
                let from = (rx.frame.system_id(), rx.frame.component_id());
                self.params.value(now, from, rx.frame.payload());
            }
            let Ok(msg) = rx.frame.decode::<MavMessage>() else {
                continue;
            };
            self.handle(msg, now);
        }
    }

    fn handle(&mut self, msg: MavMessage, now: Instant) {
        if let MavMessage::GLOBAL_POSITION_INT(p) = &msg {
            self.positions.push((now, p.time_boot_ms));
        }
        if let MavMessage::HEARTBEAT(h) = &msg
            && h.mavtype != MavType::MAV_TYPE_GCS
        {
            let mode = (
                h.custom_mode,
                h.base_mode
                    .contains(mavlora::dialect::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED),
            );
            if self.modes.last().is_none_or(|&(_, m, a)| (m, a) != mode) {
                self.modes.push((now, mode.0, mode.1));
            }
        }
        if let MavMessage::COMMAND_ACK(a) = &msg {
            self.command_ack(a.command, now);
            return;
        }
        self.download_step(&msg, now);
        if self.upload.is_none()
            && let MavMessage::MISSION_ACK(a) = &msg
            && a.target_system == 255
        {
            self.result = Some((a.mavtype, now));
        }
        let (limit, mavsdk) = (self.retries, self.mavsdk_retries);
        let Some(up) = &mut self.upload else { return };
        match msg {
            MavMessage::MISSION_REQUEST_INT(r)
                if r.target_system == 255 && r.mission_type == up.mission_type =>
            {
                let Some(item) = up.items.get(usize::from(r.seq)).cloned() else {
                    return;
                };
                if up.last != Some(r.seq) {
                    up.retries = u32::from(mavsdk);
                } else if mavsdk {
                    if up.retries >= limit {
                        self.upload = None;
                        self.result =
                            Some((MavMissionResult::MAV_MISSION_OPERATION_CANCELLED, now));
                        return;
                    }
                    up.retries += 1;
                }
                up.last = Some(r.seq);
                up.at = now;
                self.items_sent += 1;
                self.send(&MavMessage::MISSION_ITEM_INT(item));
            }
            MavMessage::MISSION_ACK(a)
                if a.target_system == 255 && a.mission_type == up.mission_type =>
            {
                self.upload = None;
                self.result = Some((a.mavtype, now));
            }
            _ => {}
        }
    }

    /// When something is next due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        if !self.out.is_empty() {
            return Some(Instant::ZERO);
        }
        let retry = self
            .upload
            .as_ref()
            .map(|u| u.at)
            .or(self.download.as_ref().map(|d| d.at))
            .map(|at| at + self.timeout);
        let t = retry.map_or(self.next_heartbeat, |r| r.min(self.next_heartbeat));
        let t = self.params.poll_timeout().map_or(t, |p| p.min(t));
        Some(self.commands_timeout().map_or(t, |c| c.min(t)))
    }

    /// Heartbeats and upload retries due at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        if now >= self.next_heartbeat {
            self.next_heartbeat += Duration::from_secs(1);
            self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                mavtype: MavType::MAV_TYPE_GCS,
                autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
                mavlink_version: 3,
                ..HEARTBEAT_DATA::default()
            }));
        }
        self.commands_tick(now);
        for msg in self.params.handle_timeout(now) {
            self.send(&msg);
        }
        if let Some(d) = &mut self.download
            && now >= d.at + self.timeout
        {
            d.at = now;
            d.retries += 1;
            if d.retries > 5 {
                self.download = None;
            } else if d.count.is_none() {
                self.send(&MavMessage::MISSION_REQUEST_LIST(
                    MISSION_REQUEST_LIST_DATA {
                        target_system: 1,
                        target_component: 1,
                        ..Default::default()
                    },
                ));
            } else {
                let seq = d.items.len() as u16;
                self.request_item(seq);
            }
        }
        let Some(up) = &mut self.upload else { return };
        if now < up.at + self.timeout {
            return;
        }
        if up.retries >= self.retries {
            self.upload = None;
            self.result = Some((MavMissionResult::MAV_MISSION_OPERATION_CANCELLED, now));
            return;
        }
        up.retries += 1;
        up.at = now;
        // MAVSDK only counts a timeout while it waits for a request or the ack: it repeats
        // nothing but its count.
        if self.mavsdk_retries && up.last.is_some() {
            return;
        }
        let msg = match up.last {
            None => MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count: up.items.len() as u16,
                target_system: 1,
                target_component: 1,
                mission_type: up.mission_type,
                ..Default::default()
            }),
            Some(seq) => {
                self.items_sent += 1;
                MavMessage::MISSION_ITEM_INT(up.items[usize::from(seq)].clone())
            }
        };
        self.send(&msg);
    }

    /// The next frame the ground station sends.
    pub fn poll_transmit(&mut self) -> Option<OwnedFrame> {
        self.out.pop_front()
    }
}
