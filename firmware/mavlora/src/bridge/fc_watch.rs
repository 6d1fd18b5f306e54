//! Which flight controller is on the wire, and whether it just started or rebooted.
//!
//! Detection (the bridge re-sends the stream-rate configuration on each event):
//! - the first `HEARTBEAT` of an autopilot (`autopilot != MAV_AUTOPILOT_INVALID`) is
//!   [`FcEvent::Appeared`]: the configuration needs its system and component id as target;
//! - a heartbeat after more than `silence` without one is [`FcEvent::Rebooted`] (a PX4 reboot
//!   takes several seconds; a reopened serial port looks the same and needs the same);
//! - `time_boot_ms` going backwards in `SYSTEM_TIME`, `ATTITUDE` or `GLOBAL_POSITION_INT` is
//!   [`FcEvent::Rebooted`] too (a reboot faster than `silence`).
//!
//! Sequence numbers are not used: after a reboot they restart at 0, but a jump back is
//! indistinguishable from 255 lost frames.

use crate::time::Duration;

use mavlink::MavlinkVersion;

use crate::dialect::{MavAutopilot, MavMessage};
use crate::time::Instant;
use crate::wire::{Frame, ids};

/// What the watch saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FcEvent {
    /// First heartbeat of the flight controller.
    Appeared,
    /// The flight controller restarted (or came back after silence).
    Rebooted,
}

/// Sans-IO reboot detector for one flight controller.
#[derive(Debug, Clone)]
pub struct FcWatch {
    silence: Duration,
    fc: Option<(u8, u8)>,
    version: Option<MavlinkVersion>,
    autopilot: Option<MavAutopilot>,
    last_heartbeat: Option<Instant>,
    last_boot_ms: Option<u32>,
}

/// Message ids carrying `time_boot_ms` that the watch decodes.
const UPTIME_IDS: [u32; 3] = [ids::SYSTEM_TIME, ids::ATTITUDE, ids::GLOBAL_POSITION_INT];

impl FcWatch {
    /// A watch that has seen nothing.
    pub fn new(silence: Duration) -> Self {
        Self {
            silence,
            fc: None,
            version: None,
            autopilot: None,
            last_heartbeat: None,
            last_boot_ms: None,
        }
    }

    /// The flight controller's (system id, component id), once seen.
    pub fn fc(&self) -> Option<(u8, u8)> {
        self.fc
    }

    /// The MAVLink version of the flight controller's last heartbeat: a MAVLink 1 autopilot
    /// gets MAVLink 1 frames and `REQUEST_DATA_STREAM` instead of `SET_MESSAGE_INTERVAL`.
    pub fn version(&self) -> Option<MavlinkVersion> {
        self.version
    }

    /// The autopilot its last heartbeat named (ArduPilot and PX4 take different requests).
    pub fn autopilot(&self) -> Option<MavAutopilot> {
        self.autopilot
    }

    /// Whether `frame` comes from the flight controller's autopilot component.
    pub fn is_fc<T: AsRef<[u8]>>(&self, frame: &Frame<T>) -> bool {
        self.fc == Some((frame.system_id(), frame.component_id()))
    }

    /// Looks at one frame from the flight-controller side; `msg` is its decoded form when the
    /// caller decoded it anyway.
    pub fn observe<T: AsRef<[u8]>>(
        &mut self,
        frame: &Frame<T>,
        msg: Option<&MavMessage>,
        now: Instant,
    ) -> Option<FcEvent> {
        let id = frame.message_id();
        if id == ids::HEARTBEAT {
            let Some(MavMessage::HEARTBEAT(hb)) = msg else {
                return None;
            };
            if hb.autopilot == MavAutopilot::MAV_AUTOPILOT_INVALID {
                return None;
            }
            let me = (frame.system_id(), frame.component_id());
            let event = match (self.fc, self.last_heartbeat) {
                (None, _) => Some(FcEvent::Appeared),
                (Some(fc), _) if fc != me => Some(FcEvent::Appeared),
                (Some(_), Some(last)) if now.saturating_duration_since(last) > self.silence => {
                    Some(FcEvent::Rebooted)
                }
                _ => None,
            };
            self.fc = Some(me);
            self.version = Some(frame.version());
            self.autopilot = Some(hb.autopilot);
            self.last_heartbeat = Some(now);
            if event.is_some() {
                self.last_boot_ms = None;
            }
            return event;
        }
        if !UPTIME_IDS.contains(&id) || !self.is_fc(frame) {
            return None;
        }
        let boot_ms = match msg? {
            MavMessage::SYSTEM_TIME(m) => m.time_boot_ms,
            MavMessage::ATTITUDE(m) => m.time_boot_ms,
            MavMessage::GLOBAL_POSITION_INT(m) => m.time_boot_ms,
            _ => return None,
        };
        let previous = self.last_boot_ms.replace(boot_ms);
        // 1 s of slack: messages of different ids may be stamped slightly out of order.
        match previous {
            Some(prev) if boot_ms.saturating_add(1000) < prev => {
                // One reboot, one event: the heartbeat that follows a silent reboot must not
                // count it again.
                self.last_heartbeat = Some(now);
                Some(FcEvent::Rebooted)
            }
            _ => None,
        }
    }

    /// Whether the watch wants `frame` decoded (heartbeats and uptime carriers).
    pub fn wants<T: AsRef<[u8]>>(&self, frame: &Frame<T>) -> bool {
        frame.message_id() == ids::HEARTBEAT || UPTIME_IDS.contains(&frame.message_id())
    }
}
