//! What `fixtures/sbus_receiver.py` prints (fixtures/README.md, "stdout
//! events"): every event has the fixture's own `t` (`time.monotonic()`, when
//! it acted) and its `name`.

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::clock::Mono;
use crate::driver::fixture::{FixtureOutput, mono, mono_opt};

/// How a receiver reports that its pilot's transmitter is gone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Loss {
    /// Frames continue with the failsafe flag.
    Failsafe,
    /// Frames stop.
    Silent,
}

impl Loss {
    pub fn as_str(self) -> &'static str {
        match self {
            Loss::Failsafe => "failsafe",
            Loss::Silent => "silent",
        }
    }
}

/// One line of `sbus_receiver.py`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case", deny_unknown_fields)]
pub enum ReceiverEvent {
    /// The port is open.
    Ready {
        #[serde(deserialize_with = "mono")]
        t: Mono,
        name: String,
        port: String,
        /// False when a pty refused 100000 8E2 and defaults were used.
        port_configured: bool,
        power: bool,
        tx: bool,
        loss: Loss,
        period_ms: f64,
        boot_ms: f64,
        lost_frames: u32,
        /// Whether it runs under SCHED_FIFO (refused without CAP_SYS_NICE: then its frames
        /// follow host load).
        realtime: bool,
    },
    /// Power after a `power` command.
    Power {
        #[serde(deserialize_with = "mono")]
        t: Mono,
        name: String,
        on: bool,
    },
    /// Transmitter after a `tx` command.
    Tx {
        #[serde(deserialize_with = "mono")]
        t: Mono,
        name: String,
        on: bool,
        /// When the last frame was written; `None` before the first.
        #[serde(deserialize_with = "mono_opt")]
        last_frame: Option<Mono>,
    },
    /// Channels after a `set` command (1-based channel → raw value).
    Set {
        #[serde(deserialize_with = "mono")]
        t: Mono,
        name: String,
        channels: BTreeMap<String, u16>,
    },
    /// The wire's fault after a `line` command (`clean`, `garbage`, `stutter`, `flood`).
    Line {
        #[serde(deserialize_with = "mono")]
        t: Mono,
        name: String,
        fault: String,
        /// Noise bursts drawn again so far because they framed as an SBUS frame (SBUS has no
        /// checksum: no decoder can tell those from a frame).
        noise_redrawn: u64,
        /// Longest interval between two of the fixture's writes under the line state this
        /// event ends (ms): how long the host held the stimulus itself.
        max_write_gap_ms: f64,
    },
    /// The first frame written after a power or transmitter change; `t` is when.
    FirstFrame {
        #[serde(deserialize_with = "mono")]
        t: Mono,
        name: String,
        flags: u8,
    },
    /// A bad command line, or a port that would not open (`line` null).
    Error {
        #[serde(deserialize_with = "mono")]
        t: Mono,
        name: String,
        message: String,
        line: Option<String>,
    },
    /// Its last line.
    Exit {
        #[serde(deserialize_with = "mono")]
        t: Mono,
        name: String,
        frames_sent: u64,
        frames_dropped: u64,
    },
}

/// Frames a receiver wrote and dropped, from its `exit` event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReceiverSummary {
    pub frames_sent: u64,
    pub frames_dropped: u64,
}

impl ReceiverEvent {
    /// The fixture's own timestamp of the event.
    pub fn t(&self) -> Mono {
        match self {
            ReceiverEvent::Ready { t, .. }
            | ReceiverEvent::Power { t, .. }
            | ReceiverEvent::Tx { t, .. }
            | ReceiverEvent::Set { t, .. }
            | ReceiverEvent::Line { t, .. }
            | ReceiverEvent::FirstFrame { t, .. }
            | ReceiverEvent::Error { t, .. }
            | ReceiverEvent::Exit { t, .. } => *t,
        }
    }

    /// A `tx` event's last frame before the change (a silent link loss is
    /// timed from it); `None` for other events or before the first frame.
    pub fn last_frame(&self) -> Option<Mono> {
        match self {
            ReceiverEvent::Tx { last_frame, .. } => *last_frame,
            _ => None,
        }
    }
}

impl FixtureOutput for ReceiverEvent {
    type Summary = ReceiverSummary;

    fn summary(&self) -> Option<ReceiverSummary> {
        match *self {
            ReceiverEvent::Exit {
                frames_sent,
                frames_dropped,
                ..
            } => Some(ReceiverSummary {
                frames_sent,
                frames_dropped,
            }),
            _ => None,
        }
    }

    fn error(&self) -> Option<String> {
        match self {
            ReceiverEvent::Error { message, line, .. } => Some(match line {
                Some(line) => format!("{message} (line {line:?})"),
                None => message.clone(),
            }),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_readme_events() {
        let e: ReceiverEvent = serde_json::from_str(
            r#"{"t": 12.5, "name": "rx0", "event": "tx", "on": false, "last_frame": 12.49}"#,
        )
        .unwrap();
        assert_eq!(
            e,
            ReceiverEvent::Tx {
                t: Mono::from_secs_f64(12.5),
                name: "rx0".into(),
                on: false,
                last_frame: Some(Mono::from_secs_f64(12.49)),
            }
        );
        let e: ReceiverEvent = serde_json::from_str(
            r#"{"t": 1.0, "name": "rx0", "event": "ready", "port": "/dev/pts/3", "port_configured": false,
                "power": false, "tx": false, "loss": "silent", "period_ms": 7.0, "boot_ms": 300.0, "lost_frames": 0, "realtime": false}"#,
        )
        .unwrap();
        assert!(matches!(
            e,
            ReceiverEvent::Ready {
                loss: Loss::Silent,
                ..
            }
        ));
    }

    #[test]
    fn a_renamed_field_is_refused_by_name() {
        let err = serde_json::from_str::<ReceiverEvent>(
            r#"{"t": 12.5, "name": "rx0", "event": "tx", "on": false, "last_frame_at": 12.49}"#,
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("last_frame_at"), "{err}");
        let err = serde_json::from_str::<ReceiverEvent>(
            r#"{"t": 12.5, "name": "rx0", "event": "first_frame"}"#,
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("flags"), "{err}");
    }
}
