//! The record of a run (after OpenHTF `core/test_record.py`): which tool, rig
//! and devices, when, and each phase with its measurements and attachments.
//!
//! The saved `results.json` is the evidence: [`crate::report`]s are rendered
//! from a record loaded back from it, never from live state, so what a
//! reviewer reads in `junit.xml` or `summary.txt` is exactly what was saved.

use std::fs;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::measurement::{Dimension, Measurement, Outcome, Selector};

/// File name of the saved record inside an output folder.
pub const RESULTS_FILE: &str = "results.json";

/// The whole run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunRecord {
    /// The program that ran the test.
    pub tool: ToolIdentity,
    /// The rig description it ran with.
    pub rig: RigIdentity,
    /// Devices under test and peers, as identified during the run.
    pub devices: Vec<DeviceIdentity>,
    /// Start, RFC 3339 UTC (see [`now_rfc3339`]).
    pub started: String,
    /// End, RFC 3339 UTC.
    pub ended: String,
    /// Overall verdict (see [`RunOutcome::from_phases`]).
    pub outcome: RunOutcome,
    /// Phases in the order they ran.
    pub phases: Vec<PhaseRecord>,
}

/// Name, version and source revision of the testing tool, so a result can be
/// traced to the code that produced it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolIdentity {
    /// Program name, e.g. `rig`.
    pub name: String,
    /// Program version.
    pub version: String,
    /// Git commit the program was built from, when known.
    pub git_commit: Option<String>,
}

impl ToolIdentity {
    /// This crate's name and version, with the commit the caller knows.
    pub fn this_build(git_commit: Option<String>) -> Self {
        ToolIdentity {
            name: env!("CARGO_PKG_NAME").to_owned(),
            version: env!("CARGO_PKG_VERSION").to_owned(),
            git_commit,
        }
    }
}

/// The rig file a run used, with its digest so a reviewer can tell which
/// ports, devices and limits applied.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigIdentity {
    /// `rig.name` from the rig file.
    pub name: String,
    /// Path of the rig file.
    pub file: PathBuf,
    /// SHA-256 of the rig file's bytes, lower-case hex.
    pub sha256: String,
}

impl RigIdentity {
    /// Identifies a rig file by name, path and the digest of its contents.
    pub fn of_file(name: impl Into<String>, file: impl Into<PathBuf>) -> io::Result<Self> {
        let file = file.into();
        let sha256 = sha256_file(&file)?;
        Ok(RigIdentity {
            name: name.into(),
            file,
            sha256,
        })
    }
}

/// One device taking part in the run (device under test or a peer).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceIdentity {
    /// Role in the rig: the device's name, or the part of it (`bridge`, `router`).
    pub role: String,
    /// Kind, e.g. `emulated` or `board`.
    pub kind: String,
    /// Free text: program and version, board, probe serial.
    pub description: String,
    /// Serial port it was reached on, when it has one.
    pub port: Option<String>,
    /// SHA-256 of the firmware image flashed or the program run, when known.
    pub firmware_sha256: Option<String>,
}

/// Overall verdict of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RunOutcome {
    /// Every phase passed or was skipped.
    Pass,
    /// At least one phase failed and none errored.
    Fail,
    /// At least one phase could not run to completion.
    Error,
    /// The run has not finished: the record is saved at start and after each
    /// phase with this outcome, so a record left by a rig that died says so.
    Running,
    /// The rig was stopped (SIGINT, SIGTERM) before every phase ran: the
    /// phases done are kept, the one in progress is marked interrupted.
    Interrupted,
}

impl RunOutcome {
    /// Error if any phase errored, else fail if any failed, else pass.
    pub fn from_phases(phases: &[PhaseRecord]) -> Self {
        if phases.iter().any(|p| p.outcome == PhaseOutcome::Error) {
            RunOutcome::Error
        } else if phases.iter().any(|p| p.outcome == PhaseOutcome::Fail) {
            RunOutcome::Fail
        } else {
            RunOutcome::Pass
        }
    }

    /// Lower-case name, as serialized.
    pub fn as_str(self) -> &'static str {
        match self {
            RunOutcome::Pass => "pass",
            RunOutcome::Fail => "fail",
            RunOutcome::Error => "error",
            RunOutcome::Running => "running",
            RunOutcome::Interrupted => "interrupted",
        }
    }
}

/// Verdict of one phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PhaseOutcome {
    /// Every measurement passed, was marginal or was skipped.
    Pass,
    /// A measurement failed or was never recorded.
    Fail,
    /// The phase returned an error (IO, timeout, a device that did not
    /// answer): its measurements say nothing about the SLA.
    Error,
    /// The phase was not run; the reason is in [`PhaseRecord::error`].
    Skipped,
    /// The rig was stopped while the phase ran: it has no verdict.
    Interrupted,
}

impl PhaseOutcome {
    /// Judges a phase that ran: error if it returned one, else fail if any
    /// measurement failed or is unset, else pass.
    pub fn judge(measurements: &[Measurement], error: Option<&str>) -> Self {
        if error.is_some() {
            PhaseOutcome::Error
        } else if measurements
            .iter()
            .any(|m| matches!(m.outcome, Outcome::Fail | Outcome::Unset))
        {
            PhaseOutcome::Fail
        } else {
            PhaseOutcome::Pass
        }
    }

    /// Lower-case name, as serialized.
    pub fn as_str(self) -> &'static str {
        match self {
            PhaseOutcome::Pass => "pass",
            PhaseOutcome::Fail => "fail",
            PhaseOutcome::Error => "error",
            PhaseOutcome::Skipped => "skipped",
            PhaseOutcome::Interrupted => "interrupted",
        }
    }
}

/// One phase (scenario step) of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhaseRecord {
    /// Dotted name: `device.suite.scenario`.
    pub name: String,
    /// Start, RFC 3339 UTC.
    pub started: String,
    /// Wall-clock duration in seconds.
    pub duration_s: f64,
    /// Verdict (see [`PhaseOutcome::judge`]).
    pub outcome: PhaseOutcome,
    /// Measurements declared by the phase, recorded or not.
    pub measurements: Vec<Measurement>,
    /// Files the phase left as evidence (captures, logs).
    pub attachments: Vec<Attachment>,
    /// The error the phase returned; for a skipped phase, why it was skipped.
    pub error: Option<String>,
    /// Log lines the phase emitted, in order.
    pub log: Vec<String>,
}

impl PhaseRecord {
    /// A phase that ran: its outcome is judged from the measurements and the
    /// error (see [`PhaseOutcome::judge`]).
    pub fn ran(
        name: impl Into<String>,
        started: impl Into<String>,
        duration_s: f64,
        measurements: Vec<Measurement>,
        error: Option<String>,
    ) -> Self {
        let outcome = PhaseOutcome::judge(&measurements, error.as_deref());
        PhaseRecord {
            name: name.into(),
            started: started.into(),
            duration_s,
            outcome,
            measurements,
            attachments: Vec::new(),
            error,
            log: Vec::new(),
        }
    }

    /// A phase that was not run; its declared measurements are kept, marked
    /// skipped with the same reason, so the report still lists each SLA.
    pub fn skipped(
        name: impl Into<String>,
        started: impl Into<String>,
        mut measurements: Vec<Measurement>,
        why: impl Into<String>,
    ) -> Self {
        let why = why.into();
        for m in &mut measurements {
            m.skip(why.clone());
        }
        PhaseRecord {
            name: name.into(),
            started: started.into(),
            duration_s: 0.0,
            outcome: PhaseOutcome::Skipped,
            measurements,
            attachments: Vec::new(),
            error: Some(why),
            log: Vec::new(),
        }
    }

    /// The phase that was running when the rig was stopped: no measurements
    /// (what it recorded so far was never judged), the signal as its error.
    pub fn interrupted(
        name: impl Into<String>,
        started: impl Into<String>,
        duration_s: f64,
        why: impl Into<String>,
    ) -> Self {
        PhaseRecord {
            name: name.into(),
            started: started.into(),
            duration_s,
            outcome: PhaseOutcome::Interrupted,
            measurements: Vec::new(),
            attachments: Vec::new(),
            error: Some(why.into()),
            log: Vec::new(),
        }
    }

    /// Measurements that make this phase fail (failed or never recorded).
    pub fn failing_measurements(&self) -> impl Iterator<Item = &Measurement> {
        self.measurements
            .iter()
            .filter(|m| matches!(m.outcome, Outcome::Fail | Outcome::Unset))
    }

    /// This phase's measurements that `selector` matches.
    pub fn select<'a>(&'a self, selector: &Selector) -> impl Iterator<Item = &'a Measurement> {
        self.measurements.iter().filter(|m| selector.matches(m))
    }
}

/// A file kept as evidence of a phase.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Attachment {
    /// Short name, e.g. `fc-capture`.
    pub name: String,
    /// Path relative to the output folder, so the folder can be archived and
    /// moved as a whole.
    pub path: PathBuf,
    /// SHA-256 of the file, lower-case hex.
    pub sha256: String,
    /// Media type, e.g. `application/octet-stream`, `text/plain`.
    pub media_type: String,
}

impl Attachment {
    /// Describes a file already written inside `out_dir`, computing its
    /// digest. Fails with `InvalidInput` if `file` is not inside `out_dir`,
    /// since the record must stay valid when the folder is moved.
    pub fn from_file(
        out_dir: &Path,
        file: &Path,
        name: impl Into<String>,
        media_type: impl Into<String>,
    ) -> io::Result<Self> {
        // The folder may be given relative to the working directory (`rig run --out
        // target/rig-report`) and the file absolute (a SITL's log): compare both absolute.
        let inside = |file: &Path, dir: &Path| file.strip_prefix(dir).ok().map(Path::to_path_buf);
        let path = inside(file, out_dir)
            .or_else(|| {
                inside(
                    &std::path::absolute(file).ok()?,
                    &std::path::absolute(out_dir).ok()?,
                )
            })
            .ok_or_else(|| {
                io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!(
                        "attachment {} is not inside the output folder {}",
                        file.display(),
                        out_dir.display()
                    ),
                )
            })?;
        Ok(Attachment {
            name: name.into(),
            sha256: sha256_file(file)?,
            path,
            media_type: media_type.into(),
        })
    }
}

impl RunRecord {
    /// Every measurement `selector` matches, with its phase, in run order.
    pub fn select<'a>(
        &'a self,
        selector: &Selector,
    ) -> impl Iterator<Item = (&'a PhaseRecord, &'a Measurement)> {
        self.phases
            .iter()
            .flat_map(move |p| p.select(selector).map(move |m| (p, m)))
    }

    /// The first measurement named `base` with every dimension of `dims` at
    /// that value, e.g. `find("bytes_per_s", &[(Dimension::Variant,
    /// "compact"), (Dimension::Transport, "pty")])`.
    pub fn find(&self, base: &str, dims: &[(Dimension, &str)]) -> Option<&Measurement> {
        let selector = dims
            .iter()
            .fold(Selector::base(base), |s, (d, v)| s.dim(*d, *v));
        self.select(&selector).map(|(_, m)| m).next()
    }

    /// Writes `results.json` (pretty JSON) into `dir`, creating it, and
    /// returns its path. The file is written under a temporary name and
    /// renamed, so a crash never leaves a truncated record behind.
    pub fn save(&self, dir: &Path) -> io::Result<PathBuf> {
        fs::create_dir_all(dir)?;
        let path = dir.join(RESULTS_FILE);
        let mut json = serde_json::to_vec_pretty(self).map_err(io::Error::other)?;
        json.push(b'\n');
        write_atomically(&path, &json)?;
        Ok(path)
    }

    /// Reads a record saved by [`RunRecord::save`]. A malformed file gives
    /// `InvalidData` naming the file.
    pub fn load(path: &Path) -> io::Result<Self> {
        let text = fs::read_to_string(path)?;
        serde_json::from_str(&text).map_err(|e| {
            io::Error::new(
                io::ErrorKind::InvalidData,
                format!("{}: {e}", path.display()),
            )
        })
    }
}

/// Writes `bytes` to `path` via a temporary file in the same folder and a
/// rename, so readers see either the old file or the whole new one.
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let file_name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "path has no file name"))?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(file_name);
    tmp_name.push(format!(".{}.tmp", std::process::id()));
    let tmp = path.with_file_name(tmp_name);
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Lower-case hex SHA-256 of a file's contents.
pub fn sha256_file(path: &Path) -> io::Result<String> {
    let mut f = fs::File::open(path)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
    }
    Ok(hex(&hasher.finalize()))
}

/// Lower-case hex SHA-256 of bytes.
pub fn sha256_bytes(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write as _;
    bytes.iter().fold(String::with_capacity(64), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

/// The current time as RFC 3339 UTC with milliseconds, e.g.
/// `2026-01-31T09:12:03.123Z`, the format of the record's timestamps.
pub fn now_rfc3339() -> String {
    chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::measurement::{Declarations, Spec};

    /// A small record with a passing phase, a failing one (one failed and
    /// one unset measurement), an errored one and a skipped one.
    pub(crate) fn sample_record() -> RunRecord {
        let mux = |base: &str, mode: &str, unit: &str| {
            Spec::new(base, unit)
                .dim(Dimension::Device, "mux")
                .dim(Dimension::Mode, mode)
        };
        let pty = |base: &str, unit: &str| {
            Spec::new(base, unit)
                .dim(Dimension::Device, "link")
                .dim(Dimension::Transport, "pty")
        };
        let mut d1 = Declarations::new();
        let pass = d1.declare(
            mux("handover_ms", "parallel", "ms")
                .describe("time from the active TX off to the other receiver's frames at the FC")
                .at_most(50.0),
        );
        d1.record(pass, 12.5);
        let marginal = d1.declare(
            mux("handover_ms", "scan", "ms")
                .at_most(4500.0)
                .marginal_above(4000.0),
        );
        d1.record(marginal, 4100.0);
        let mut d2 = Declarations::new();
        let fail = d2.declare(
            pty("bytes_per_s", "B/s")
                .dim(Dimension::Radio, "sik_64k")
                .at_most(951.0),
        );
        d2.record(fail, 1200.0);
        d2.declare(pty("position_rate", "Hz").at_least(3.0));
        let mut d3 = Declarations::new();
        d3.declare(pty("mission_upload_s", "s").at_most(60.0));
        let mut d4 = Declarations::new();
        d4.declare(mux("loiter_entry_ms", "scan", "ms").at_most(100.0));
        let mut p1 = PhaseRecord::ran(
            "mux.parallel.scenario_b",
            "2026-01-31T09:12:03.123Z",
            1.25,
            d1.into_measurements(),
            None,
        );
        p1.log.push("TX 1 off at t=2.000 s".into());
        p1.attachments.push(Attachment {
            name: "fc-capture".into(),
            path: PathBuf::from("mux.parallel.scenario_b/fc.sbus"),
            sha256: sha256_bytes(b"frames"),
            media_type: "application/octet-stream".into(),
        });
        let p2 = PhaseRecord::ran(
            "link.bridge.bandwidth",
            "2026-01-31T09:12:05.000Z",
            30.0,
            d2.into_measurements(),
            None,
        );
        let p3 = PhaseRecord::ran(
            "link.mission_upload",
            "2026-01-31T09:12:35.000Z",
            0.5,
            d3.into_measurements(),
            Some("router exited with status 1 <&>".into()),
        );
        let p4 = PhaseRecord::skipped(
            "mux.scan.scenario_c",
            "2026-01-31T09:12:36.000Z",
            d4.into_measurements(),
            "scan not in mux.modes",
        );
        let phases = vec![p1, p2, p3, p4];
        RunRecord {
            tool: ToolIdentity::this_build(Some("0123abcd".into())),
            rig: RigIdentity {
                name: "emulated".into(),
                file: PathBuf::from("/work/rigs/emulated.toml"),
                sha256: sha256_bytes(b"rig"),
            },
            devices: vec![DeviceIdentity {
                role: "mux".into(),
                kind: "emulated".into(),
                description: "mux-emu 0.1.0".into(),
                port: Some("/dev/pts/7".into()),
                firmware_sha256: None,
            }],
            started: "2026-01-31T09:12:03.000Z".into(),
            ended: "2026-01-31T09:12:36.500Z".into(),
            outcome: RunOutcome::from_phases(&phases),
            phases,
        }
    }

    #[test]
    fn phase_outcomes_are_judged() {
        let r = sample_record();
        let outcomes: Vec<_> = r.phases.iter().map(|p| p.outcome).collect();
        assert_eq!(
            outcomes,
            [
                PhaseOutcome::Pass,
                PhaseOutcome::Fail,
                PhaseOutcome::Error,
                PhaseOutcome::Skipped
            ]
        );
        assert_eq!(r.outcome, RunOutcome::Error);
        assert_eq!(r.phases[1].failing_measurements().count(), 2);
        assert_eq!(RunOutcome::from_phases(&r.phases[..2]), RunOutcome::Fail);
        assert_eq!(RunOutcome::from_phases(&r.phases[..1]), RunOutcome::Pass);
        assert_eq!(r.phases[3].measurements[0].outcome, Outcome::Skipped);
    }

    #[test]
    fn unset_measurement_fails_phase() {
        let mut d = Declarations::new();
        d.declare(Spec::new("a", "ms").at_most(1.0));
        assert_eq!(
            PhaseOutcome::judge(d.measurements(), None),
            PhaseOutcome::Fail
        );
        assert_eq!(PhaseOutcome::judge(&[], None), PhaseOutcome::Pass);
    }

    #[test]
    fn save_load_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let r = sample_record();
        let path = r.save(&dir.path().join("out")).unwrap();
        assert_eq!(path, dir.path().join("out").join(RESULTS_FILE));
        let back = RunRecord::load(&path).unwrap();
        assert_eq!(back, r);
        let text = fs::read_to_string(&path).unwrap();
        assert!(text.contains("\n  \"tool\": {"), "pretty JSON: {text}");
        assert!(text.contains(r#""outcome": "marginal""#));
        let leftovers: Vec<_> = fs::read_dir(dir.path().join("out"))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(leftovers, [RESULTS_FILE], "no temporary file left");
    }

    #[test]
    fn save_replaces_an_earlier_record() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = sample_record();
        r.save(dir.path()).unwrap();
        r.phases.truncate(1);
        let path = r.save(dir.path()).unwrap();
        assert_eq!(RunRecord::load(&path).unwrap().phases.len(), 1);
    }

    #[test]
    fn load_rejects_malformed_record_naming_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(RESULTS_FILE);
        fs::write(&path, r#"{"tool": 1}"#).unwrap();
        let err = RunRecord::load(&path).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidData);
        assert!(err.to_string().contains(RESULTS_FILE), "{err}");
    }

    #[test]
    fn nan_value_survives_as_failed_with_note() {
        let mut d = Declarations::new();
        let h = d.declare(Spec::new("a", "ms").at_most(1.0));
        d.record(h, f64::NAN);
        let mut r = sample_record();
        r.phases[0].measurements.extend(d.into_measurements());
        let dir = tempfile::tempdir().unwrap();
        let back = RunRecord::load(&r.save(dir.path()).unwrap()).unwrap();
        let m = back.phases[0].measurements.last().unwrap();
        assert_eq!((m.value, m.outcome), (None, Outcome::Fail));
        assert!(m.note.as_deref().unwrap().contains("NaN"));
    }

    #[test]
    fn digests_and_attachment_paths() {
        assert_eq!(
            sha256_bytes(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("sub").join("cap.bin");
        fs::create_dir_all(file.parent().unwrap()).unwrap();
        fs::write(&file, b"abc").unwrap();
        let a =
            Attachment::from_file(dir.path(), &file, "cap", "application/octet-stream").unwrap();
        assert_eq!(a.path, Path::new("sub/cap.bin"));
        assert_eq!(a.sha256, sha256_bytes(b"abc"));
        let outside =
            Attachment::from_file(&dir.path().join("sub"), Path::new("/etc/hosts"), "x", "y");
        assert_eq!(outside.unwrap_err().kind(), io::ErrorKind::InvalidInput);
        // CI's `rig run --out target/rig-report`: a relative folder, a file made absolute (a
        // SITL's log). The SITL phases' logs were refused as outside the folder.
        let cwd = std::env::current_dir().unwrap();
        let relative = tempfile::tempdir_in(&cwd).unwrap();
        let folder = relative.path().strip_prefix(&cwd).unwrap();
        assert!(folder.is_relative());
        let log = relative.path().join("px4-sitl.log");
        fs::write(&log, b"log").unwrap();
        let a = Attachment::from_file(folder, &log, "log", "text/plain").unwrap();
        assert_eq!(a.path, Path::new("px4-sitl.log"));
        let rig = RigIdentity::of_file("r", &file).unwrap();
        assert_eq!(rig.sha256, sha256_bytes(b"abc"));
    }

    #[test]
    fn now_is_rfc3339_utc() {
        let now = now_rfc3339();
        assert!(now.ends_with('Z'), "{now}");
        chrono::DateTime::parse_from_rfc3339(&now).unwrap();
    }

    #[test]
    fn saved_record_keeps_dimensions_and_is_selected_by_them() {
        let dir = tempfile::tempdir().unwrap();
        let r = sample_record();
        let back = RunRecord::load(&r.save(dir.path()).unwrap()).unwrap();
        let text = fs::read_to_string(dir.path().join(RESULTS_FILE)).unwrap();
        assert!(text.contains(r#""dimensions": {"#), "{text}");
        let m = back
            .find(
                "bytes_per_s",
                &[(Dimension::Radio, "sik_64k"), (Dimension::Transport, "pty")],
            )
            .unwrap();
        assert_eq!(m.name, "link.pty.sik_64k.bytes_per_s");
        assert_eq!(m.value, Some(1200.0));
        assert!(
            back.find("bytes_per_s", &[(Dimension::Variant, "compact")])
                .is_none()
        );
        let handovers: Vec<_> = back
            .select(&Selector::base("handover_ms").dim(Dimension::Device, "mux"))
            .map(|(p, m)| (p.name.as_str(), m.dimensions.get(Dimension::Mode).unwrap()))
            .collect();
        assert_eq!(
            handovers,
            [
                ("mux.parallel.scenario_b", "parallel"),
                ("mux.parallel.scenario_b", "scan")
            ]
        );
        let skipped: Vec<_> = back
            .select(&Selector::any().dim(Dimension::Mode, "scan"))
            .map(|(_, m)| m.outcome)
            .collect();
        assert_eq!(skipped, [Outcome::Marginal, Outcome::Skipped]);
    }

    /// `rig report` re-renders archived evidence: a record saved before
    /// measurements had dimensions still loads, names and verdicts intact.
    #[test]
    fn a_record_saved_without_dimensions_loads() {
        let dir = tempfile::tempdir().unwrap();
        let path = sample_record().save(dir.path()).unwrap();
        let mut json: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(&path).unwrap()).unwrap();
        for phase in json["phases"].as_array_mut().unwrap() {
            for m in phase["measurements"].as_array_mut().unwrap() {
                m.as_object_mut().unwrap().remove("dimensions").unwrap();
            }
        }
        fs::write(&path, serde_json::to_string_pretty(&json).unwrap()).unwrap();
        let old = RunRecord::load(&path).unwrap();
        let new = sample_record();
        assert_eq!(old.phases.len(), new.phases.len());
        for (o, n) in old.phases.iter().zip(&new.phases) {
            for (om, nm) in o.measurements.iter().zip(&n.measurements) {
                assert!(om.dimensions.is_empty());
                assert_eq!(
                    (&om.name, om.value, om.outcome),
                    (&nm.name, nm.value, nm.outcome)
                );
            }
        }
        assert!(
            old.find("handover_ms", &[]).is_none(),
            "nothing to select by"
        );
    }
}
