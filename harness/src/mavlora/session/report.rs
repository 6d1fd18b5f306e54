//! What a finished session leaves behind, and reading the MavLora programs' status files.

use std::path::{Path, PathBuf};
use std::process::ExitStatus;

use anyhow::Context;
use hostio::status::{Kind as StatusKind, Line as StatusLine};

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
    /// What the bridge and the router last reported, when they ran.
    pub bridge_status: Option<ProgramStatus>,
    pub router_status: Option<ProgramStatus>,
    /// Every router's link announcements to the ground, in order (a crashed router's, then
    /// its successor's).
    pub link_notices: Vec<LinkNotice>,
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

/// What a MavLora program last reported in its status file (`--status-json`, schema
/// `c2-status/1`, `firmware/hostio/STATUS-JSON.md`): its stop line, or the latest periodic
/// line of one that was killed.
#[derive(Debug, Clone)]
pub struct ProgramStatus {
    /// The file it was read from.
    pub path: PathBuf,
    line: StatusLine,
}

impl ProgramStatus {
    /// Reads the last line with counters from `path`; `None` if the program wrote none (it
    /// never got running, or the file is not there). A line of another schema, or one that is
    /// not a status line, is an error naming the file and line: only a torn last line (a
    /// program killed mid-write) is passed over.
    pub fn read(path: &Path) -> anyhow::Result<Option<Self>> {
        let Some(text) = status_text(path)? else {
            return Ok(None);
        };
        let last = hostio::status::last_counters(&text).map_err(|e| file_error(path, &e))?;
        Ok(last.map(|line| ProgramStatus {
            path: path.to_path_buf(),
            line,
        }))
    }

    /// A counter (a total since start); an error naming the file if it has none.
    pub fn counter(&self, name: &str) -> anyhow::Result<f64> {
        self.line
            .counter(name)
            .with_context(|| format!("{}: no counter {name}", self.path.display()))
    }

    /// A gauge (a level at the time of the line); an error naming the file if it has none.
    pub fn gauge(&self, name: &str) -> anyhow::Result<f64> {
        self.line
            .gauge(name)
            .with_context(|| format!("{}: no gauge {name}", self.path.display()))
    }
}

/// A router's announcement of a change in the link's health to the ground stations: a
/// `link_notice` event of its status file.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
pub struct LinkNotice {
    /// `uplink` or `downlink`.
    pub direction: String,
    /// Its new health: `ok`, `degraded`, `lost` or `silent`.
    pub health: String,
    /// The `STATUSTEXT` the ground stations were sent.
    pub text: String,
}

impl LinkNotice {
    /// Every `link_notice` event in the status file at `path`, in order (none if the file is
    /// not there). A line that does not parse is an error naming file and line, but for a
    /// torn last line.
    pub fn read_all(path: &Path) -> anyhow::Result<Vec<LinkNotice>> {
        let Some(text) = status_text(path)? else {
            return Ok(Vec::new());
        };
        let lines = hostio::status::lines(&text).map_err(|e| file_error(path, &e))?;
        let mut notices = Vec::new();
        for (i, line) in lines.into_iter().enumerate() {
            if line.kind != StatusKind::Event
                || line.rest.get("event").and_then(|e| e.as_str()) != Some("link_notice")
            {
                continue;
            }
            let notice = serde_json::from_value(serde_json::Value::Object(line.rest))
                .with_context(|| format!("{}:{}: a link_notice event", path.display(), i + 1))?;
            notices.push(notice);
        }
        Ok(notices)
    }
}

/// The status file at `path`, `None` if it is not there.
fn status_text(path: &Path) -> anyhow::Result<Option<String>> {
    match std::fs::read_to_string(path) {
        Ok(text) => Ok(Some(text)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e).with_context(|| format!("cannot read {}", path.display())),
    }
}

/// A line of the status file at `path` that is not of the schema, naming file and line.
fn file_error(path: &Path, e: &hostio::status::FileError) -> anyhow::Error {
    anyhow::anyhow!("{}:{}: {}", path.display(), e.line, e.error)
}

/// `program kind t_s: counters {...} gauges {...}`, for a phase's log.
impl std::fmt::Display for ProgramStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let l = &self.line;
        write!(f, "{} {:?} at {:.1} s:", l.program, l.kind, l.t_s)?;
        for (name, values) in [("counters", &l.counters), ("gauges", &l.gauges)] {
            if let Some(values) = values {
                write!(f, " {name} {}", serde_json::Value::Object(values.clone()))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const START: &str = r#"{"schema":"c2-status/1","program":"mavlora-router","kind":"start","t_s":0.0,"mono_s":1.0,"version":"0.1.0"}"#;
    const STATUS: &str = r#"{"schema":"c2-status/1","program":"mavlora-router","kind":"status","t_s":2.0,"mono_s":3.0,"counters":{"ground_rejected":1},"gauges":{"radio_queued_bytes":0}}"#;
    const STOP: &str = r#"{"schema":"c2-status/1","program":"mavlora-router","kind":"stop","t_s":4.0,"mono_s":5.0,"exit_code":0,"error":null,"counters":{"ground_rejected":3},"gauges":{"radio_queued_bytes":12}}"#;

    fn read(text: &str) -> anyhow::Result<Option<ProgramStatus>> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("router.status.jsonl");
        std::fs::write(&path, text).unwrap();
        ProgramStatus::read(&path)
    }

    #[test]
    fn the_stop_line_is_the_last_status() {
        let status = read(&format!("{START}\n{STATUS}\n{STOP}\n"))
            .unwrap()
            .unwrap();
        assert_eq!(status.counter("ground_rejected").unwrap(), 3.0);
        assert_eq!(status.gauge("radio_queued_bytes").unwrap(), 12.0);
        let missing = status.counter("radio_tx_unsigned").unwrap_err().to_string();
        assert!(
            missing.contains("router.status.jsonl: no counter radio_tx_unsigned"),
            "{missing}"
        );
    }

    #[test]
    fn a_killed_program_leaves_its_latest_status_and_maybe_a_torn_line() {
        let torn = &STOP[..40];
        let status = read(&format!("{START}\n{STATUS}\n{torn}"))
            .unwrap()
            .unwrap();
        assert_eq!(status.counter("ground_rejected").unwrap(), 1.0);
        assert!(read(START).unwrap().is_none(), "started, never reported");
    }

    #[test]
    fn another_schema_or_a_bad_line_inside_the_file_names_file_and_line() {
        let other = STATUS.replace("c2-status/1", "c2-status/2");
        let e = read(&format!("{START}\n{other}\n{STOP}\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("router.status.jsonl:2: schema"), "{e}");
        let e = read(&format!("{START}\nINFO status x=1\n{STOP}\n"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("router.status.jsonl:2: not a status line"),
            "{e}"
        );
    }

    #[test]
    fn link_notices_are_the_event_lines_in_order() {
        let event = |health: &str, text: &str| {
            format!(
                r#"{{"schema":"c2-status/1","program":"mavlora-router","kind":"event","t_s":1.0,"mono_s":2.0,"event":"link_notice","direction":"uplink","health":"{health}","loss_pct":80.0,"text":"{text}"}}"#
            )
        };
        let other = r#"{"schema":"c2-status/1","program":"mavlora-router","kind":"event","t_s":1.0,"mono_s":2.0,"event":"something_else"}"#;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("router.status.jsonl");
        let text = format!(
            "{START}\n{}\n{STATUS}\n{other}\n{}\n{STOP}\n",
            event("degraded", "Uplink GCS>UAV degraded: 80% lost"),
            event("ok", "Uplink GCS>UAV restored: 0% lost")
        );
        std::fs::write(&path, text).unwrap();
        let notices = LinkNotice::read_all(&path).unwrap();
        let healths: Vec<&str> = notices.iter().map(|n| n.health.as_str()).collect();
        assert_eq!(healths, ["degraded", "ok"]);
        assert_eq!(notices[0].text, "Uplink GCS>UAV degraded: 80% lost");
        let broken = event("degraded", "x").replace(r#""direction":"uplink","#, "");
        std::fs::write(&path, format!("{START}\n{broken}\n{STOP}\n")).unwrap();
        let e = format!("{:#}", LinkNotice::read_all(&path).unwrap_err());
        assert!(
            e.contains("router.status.jsonl:2: a link_notice event"),
            "{e}"
        );
        assert!(
            LinkNotice::read_all(&dir.path().join("none"))
                .unwrap()
                .is_empty()
        );
    }
}
