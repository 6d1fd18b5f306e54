//! What a finished session leaves behind, and reading the MavLora programs'
//! status lines.

use std::path::{Path, PathBuf};
use std::process::ExitStatus;

use super::chain::GcsLine;
use crate::driver::fixture::Line;
use crate::mavlora::fixture::fc::{FcEvent, FcSummary};
use crate::mavlora::fixture::gcs::{GcsEvent, GcsSummary};
use crate::stats;
use harness_radio::LinkStats;

/// `mavlora_gcs.py`'s exit status when it ran its plan to the end but a phase
/// did not succeed (a lost command, a refused mission): the measurements say
/// which, so it is not an unclean exit.
pub const GCS_PHASE_FAILED: i32 = 3;

/// How one program ended.
#[derive(Debug, Clone)]
pub struct ExitRecord {
    pub name: String,
    /// `None`: it had to be killed.
    pub status: Option<ExitStatus>,
    /// Exit codes besides 0 that still mean it ended as designed.
    pub accepted: Vec<i32>,
    pub log: PathBuf,
}

impl ExitRecord {
    /// Exited with status 0 (or an accepted code), not by a signal or a kill.
    pub fn clean(&self) -> bool {
        self.status
            .and_then(|s| s.code())
            .is_some_and(|c| c == 0 || self.accepted.contains(&c))
    }
}

/// Everything a finished session leaves behind.
#[derive(Debug, Clone)]
pub struct SessionReport {
    /// `mavlora_fc.py`'s summary.
    pub fc: FcSummary,
    /// `mavlora_gcs.py`'s summary line.
    pub gcs: GcsSummary,
    /// The GCS's event lines, each with the radio's counters when read.
    pub gcs_events: Vec<GcsLine>,
    /// The FC fixture's event lines (`ready`, `interval`, `mission`, `reboot`).
    pub fc_events: Vec<Line<FcEvent>>,
    /// Drone → ground, whole session.
    pub downlink: LinkStats,
    /// Ground → drone, whole session.
    pub uplink: LinkStats,
    /// The radio model's time zero on the rig's clock (its scheduled silences count from it).
    pub radio_epoch: crate::clock::Mono,
    /// Last status line of the bridge and the router, when they ran.
    pub bridge_status: Option<String>,
    pub router_status: Option<String>,
    /// Every program, in the order stopped.
    pub exits: Vec<ExitRecord>,
    /// Logs and files kept as evidence.
    pub files: Vec<PathBuf>,
}

impl SessionReport {
    /// Whether every program exited by itself or on SIGTERM with status 0.
    pub fn all_clean(&self) -> bool {
        self.exits.iter().all(ExitRecord::clean)
    }

    /// The GCS's first line that `pick` accepts.
    pub fn gcs_event(&self, pick: impl Fn(&GcsEvent) -> bool) -> Option<&GcsLine> {
        self.gcs_events.iter().find(|l| pick(&l.event))
    }

    /// When the rig read the GCS's `window_start` and `window_end` lines.
    pub fn window(&self) -> Option<(&GcsLine, &GcsLine)> {
        Some((
            self.gcs_event(|e| matches!(e, GcsEvent::WindowStart { .. }))?,
            self.gcs_event(|e| matches!(e, GcsEvent::WindowEnd { .. }))?,
        ))
    }

    /// Drone → ground bytes on air per second over the GCS's counting
    /// window, as the radio counted them, with the seconds between the two
    /// lines; `None` without a window.
    pub fn downlink_rate(&self) -> Option<(f64, f64)> {
        let (a, b) = self.window()?;
        let (sa, sb) = (&a.snapshot.0, &b.snapshot.0);
        let secs = b.at.since(a.at).as_secs_f64();
        (secs > 0.0).then(|| {
            (
                stats::rate((sb.bytes_sent - sa.bytes_sent) as f64, secs),
                secs,
            )
        })
    }
}

/// The last `status` line a MavLora program logged, without its timestamp
/// and colours.
pub fn last_status(log: &Path) -> Option<String> {
    let text = std::fs::read_to_string(log).ok()?;
    text.lines()
        .map(strip_ansi)
        .rev()
        .find(|l| l.contains(" status ") || l.ends_with(" status"))
        .map(|l| match l.find("INFO") {
            Some(i) => l[i..].to_string(),
            None => l,
        })
}

/// Removes terminal colour sequences (`ESC [ ... m`).
fn strip_ansi(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            for c in chars.by_ref() {
                if c.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// `key=value` of a status line as a number (`radio_tx_bytes=1234`).
pub fn status_field(line: &str, key: &str) -> Option<f64> {
    line.split_whitespace()
        .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
        .and_then(|v| v.parse().ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_fields_are_read_from_a_bridge_line() {
        let line = "2026-11-23T13:00:00.1Z  INFO mavlora_bridge: status fc_rx=120 radio_tx_bytes=4567 peer_loss=None";
        assert_eq!(status_field(line, "radio_tx_bytes"), Some(4567.0));
        assert_eq!(status_field(line, "fc_rx"), Some(120.0));
        assert_eq!(status_field(line, "peer_loss"), None);
        assert_eq!(status_field(line, "radio_tx"), None);
    }

    #[test]
    fn status_line_is_found_in_a_coloured_log() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("bridge.log");
        std::fs::write(
            &log,
            "\u{1b}[2m2026\u{1b}[0m \u{1b}[32m INFO\u{1b}[0m mavlora_bridge: status \u{1b}[3mfc_rx\u{1b}[0m=5\nlater line\n",
        )
        .unwrap();
        let line = last_status(&log).unwrap();
        assert_eq!(line, "INFO mavlora_bridge: status fc_rx=5");
        assert_eq!(status_field(&line, "fc_rx"), Some(5.0));
    }
}
