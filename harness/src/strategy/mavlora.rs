//! Brings up a MavLora link for one real-time scenario, on the real clock:
//!
//! ```text
//! FC fixture (pty) ─ mavlora-bridge ─ RadioEmulator ─ mavlora-router ─UDP─ GCS fixture
//!   mavlora_fc.py                      side A │ side B                      mavlora_gcs.py
//! ```
//!
//! [`Variant::Transparent`] is the paper's "no companion computer" case: the
//! flight controller's serial port straight on the drone radio and the ground
//! station straight on the ground radio's serial port. No router either: the
//! router is half of MavLora (it thins ground heartbeats and drops premature
//! mission retransmissions), so keeping it would not be the naive link.
//!
//! The GCS fixture runs a plan ([`GcsPlan`]: telemetry window, commands,
//! mission) and exits; its JSON event lines are read as they come, and each
//! carries the radio's counters at the moment it was read, so a rate taken
//! from the radio and one taken from the GCS cover the same window.
//! [`MavloraSession::finish`] stops everything with SIGTERM, checks each
//! program exited with status 0 and collects the fixtures' summaries, the
//! radio's per-direction [`LinkStats`] and the bridge's and router's last
//! status lines. Every program's stderr is kept as a log in the output folder.

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::clock::Mono;
use crate::driver::process::Process;
use crate::radio::{GilbertElliott, LinkConfig, LinkStats, RadioEmulator, RadioSetup};

/// Why a session could not be brought up or finished.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// A program (bridge, router) is not where the options say.
    #[error("{} not found: build it with `cargo build -p mavlora --bins` (same profile as rig)", .0.display())]
    ProgramMissing(PathBuf),
    /// A fixture did not print its `ready` line.
    #[error("{name} did not start within {timeout:?} (pymavlink and pyserial installed?); see {}", log.display())]
    FixtureStart {
        name: String,
        timeout: Duration,
        log: PathBuf,
    },
    /// Telemetry did not reach the ground station.
    #[error("no telemetry at the ground station within {timeout:?}; see the logs in {}", dir.display())]
    NoTelemetry { timeout: Duration, dir: PathBuf },
    /// The ground station did not finish its plan in time.
    #[error("the GCS fixture did not finish within {timeout:?}; see {}", log.display())]
    GcsTimeout { timeout: Duration, log: PathBuf },
    /// A summary file or line could not be read.
    #[error("cannot read the summary {what}: {reason}")]
    Summary { what: String, reason: String },
    /// The radio setup does not make a radio.
    #[error("radio setup: {0}")]
    Radio(#[from] crate::radio::ConfigError),
    /// Starting or talking to a program failed (the message names it).
    #[error(transparent)]
    Driver(#[from] anyhow::Error),
    /// Files in the output folder.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

type Result<T> = std::result::Result<T, SessionError>;

/// What sits between the flight controller and the radio.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// `mavlora-bridge` on the drone, `mavlora-router` on the ground.
    Bridge,
    /// Nothing: FC on the drone radio, GCS on the ground radio (see the module doc).
    Transparent,
}

/// PX4 stream profile the FC fixture boots with (`mavlora_fc.py --profile`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FcProfile {
    /// Telemetry-radio default.
    Normal,
    /// USB default, closest to the paper's wired 11,440 B/s.
    Config,
}

impl FcProfile {
    pub fn as_str(self) -> &'static str {
        match self {
            FcProfile::Normal => "normal",
            FcProfile::Config => "config",
        }
    }
}

/// What the GCS fixture does, in order (see `fixtures/mavlora_gcs.py`).
#[derive(Debug, Clone, PartialEq)]
pub struct GcsPlan {
    /// Seconds of the telemetry phase.
    pub listen_s: f64,
    /// Seconds of it before the counting window opens.
    pub warmup_s: f64,
    /// Commands to send (0: none).
    pub commands: u32,
    pub command_interval_s: f64,
    pub command_retry_s: f64,
    pub command_tries: u32,
    /// Mission items to upload (0: none).
    pub items: u32,
    pub item_timeout_s: f64,
    pub upload_timeout_s: f64,
}

impl Default for GcsPlan {
    fn default() -> Self {
        GcsPlan {
            listen_s: 3.0,
            warmup_s: 0.0,
            commands: 0,
            command_interval_s: 0.5,
            command_retry_s: 1.5,
            command_tries: 5,
            items: 0,
            item_timeout_s: 1.5,
            upload_timeout_s: 60.0,
        }
    }
}

impl GcsPlan {
    /// Longest the plan can take, with a margin for start-up.
    pub fn budget(&self) -> Duration {
        let commands = f64::from(self.commands)
            * (self.command_interval_s + self.command_retry_s * f64::from(self.command_tries));
        let upload = if self.items > 0 {
            self.upload_timeout_s
        } else {
            0.0
        };
        Duration::from_secs_f64(self.listen_s + commands + upload + 10.0)
    }
}

/// Everything one session needs; the lead maps the rig file onto this.
#[derive(Debug, Clone)]
pub struct SessionOptions {
    /// Labels the radio thread and the logs.
    pub name: String,
    pub python: PathBuf,
    pub fixtures_dir: PathBuf,
    pub bridge_program: PathBuf,
    pub router_program: PathBuf,
    pub radio: RadioSetup,
    pub variant: Variant,
    /// `--profile` of the bridge.
    pub bridge_profile: PathBuf,
    /// `--compact` of the bridge.
    pub compact: bool,
    /// `--rate` of the bridge (radio budget, B/s).
    pub rate: u32,
    pub fc_profile: FcProfile,
    pub gcs: GcsPlan,
    /// Logs, summaries and the router's tlog go here.
    pub out_dir: PathBuf,
    /// Longest wait for the first telemetry at the GCS.
    pub ready_timeout: Duration,
}

/// What comes from the rig file, shared by every real-time scenario.
#[derive(Debug, Clone)]
pub struct SessionDefaults {
    pub python: PathBuf,
    pub fixtures_dir: PathBuf,
    pub bridge_program: PathBuf,
    pub router_program: PathBuf,
    /// Folder holding `px4-normal.toml` and `px4-compact.toml`.
    pub profile_dir: PathBuf,
    /// SiK with loss, for the mission and command scenarios.
    pub lossy_radio: RadioSetup,
    /// SiK without loss, for bandwidth.
    pub clean_radio: RadioSetup,
    /// SiK with independent loss, for commands: a burst model stepped per packet would
    /// stretch one burst over the seconds between two commands on a quiet uplink.
    pub c2_radio: RadioSetup,
}

impl SessionDefaults {
    /// Defaults for a checkout at `repo`: `python3`, `fixtures/`,
    /// `mavlora/profiles/`, the MavLora programs next to the running
    /// executable (or one folder up, for test binaries in `deps/`), SiK 64k
    /// loss-free and with 10 % bursty loss each way.
    pub fn for_repo(repo: &Path) -> Result<SessionDefaults> {
        Ok(SessionDefaults {
            python: PathBuf::from("python3"),
            fixtures_dir: repo.join("fixtures"),
            bridge_program: program_near_exe("mavlora-bridge")?,
            router_program: program_near_exe("mavlora-router")?,
            profile_dir: repo.join("mavlora/profiles"),
            lossy_radio: sik_with_loss(0.10, 2.0)?,
            clean_radio: RadioSetup::builtin("sik-64k")?,
            c2_radio: sik_with_independent_loss(0.10)?,
        })
    }

    /// Options for a bridge session over `radio`, logging into `out_dir`.
    pub fn options(&self, name: &str, radio: &RadioSetup, out_dir: &Path) -> SessionOptions {
        SessionOptions {
            name: name.to_string(),
            python: self.python.clone(),
            fixtures_dir: self.fixtures_dir.clone(),
            bridge_program: self.bridge_program.clone(),
            router_program: self.router_program.clone(),
            radio: radio.clone(),
            variant: Variant::Bridge,
            bridge_profile: self.profile_dir.join("px4-compact.toml"),
            compact: true,
            rate: 3000,
            fc_profile: FcProfile::Normal,
            gcs: GcsPlan::default(),
            out_dir: out_dir.to_path_buf(),
            ready_timeout: Duration::from_secs(15),
        }
    }
}

/// SiK 64k with Gilbert-Elliott loss of `loss` (0..1) and mean burst
/// `burst` packets in both directions (seeds 1 down, 2 up).
pub fn sik_with_loss(loss: f64, burst: f64) -> Result<RadioSetup> {
    let mut setup = RadioSetup::builtin("sik-64k")?;
    let ge = GilbertElliott::with_mean(loss, burst)?;
    setup.downlink = LinkConfig {
        burst: Some(ge),
        seed: 1,
        ..LinkConfig::default()
    };
    setup.uplink = LinkConfig {
        burst: Some(ge),
        seed: 2,
        ..LinkConfig::default()
    };
    Ok(setup)
}

/// SiK 64k losing `loss` of the air packets each way, independently (seeds 3 down, 4 up).
pub fn sik_with_independent_loss(loss: f64) -> Result<RadioSetup> {
    let mut setup = RadioSetup::builtin("sik-64k")?;
    let independent = |seed| LinkConfig {
        burst: Some(GilbertElliott {
            p_good_to_bad: 0.0,
            p_bad_to_good: 1.0,
            loss_good: loss,
            loss_bad: loss,
        }),
        seed,
        ..LinkConfig::default()
    };
    setup.downlink = independent(3);
    setup.uplink = independent(4);
    setup.radio()?;
    Ok(setup)
}

/// `name` next to the running executable, or in its parent folder (a test
/// binary runs from `target/<profile>/deps/`).
pub fn program_near_exe(name: &str) -> Result<PathBuf> {
    let exe = std::env::current_exe().map_err(|source| SessionError::Io {
        path: PathBuf::from("/proc/self/exe"),
        source,
    })?;
    let here = exe.with_file_name(name);
    if here.exists() {
        return Ok(here);
    }
    match exe.parent().and_then(Path::parent).map(|p| p.join(name)) {
        Some(up) if up.exists() => Ok(up),
        _ => Err(SessionError::ProgramMissing(here)),
    }
}

/// One JSON line a fixture printed, with when the rig read it.
#[derive(Debug, Clone)]
pub struct FixtureLine {
    pub at: Mono,
    pub value: Value,
    /// The radio's (downlink, uplink) counters when the line was read.
    pub radio: Option<(LinkStats, LinkStats)>,
}

impl FixtureLine {
    pub fn event(&self) -> Option<&str> {
        self.value.get("event").and_then(Value::as_str)
    }
}

#[derive(Default)]
struct Lines {
    list: Mutex<Vec<FixtureLine>>,
    changed: Condvar,
    closed: Mutex<bool>,
}

/// Reads a fixture's stdout as JSON lines on a thread.
struct LineReader {
    lines: Arc<Lines>,
}

impl LineReader {
    fn start(
        name: &str,
        stdout: std::process::ChildStdout,
        radio: Option<Arc<RadioEmulator>>,
    ) -> Result<LineReader> {
        let lines = Arc::new(Lines::default());
        let sink = lines.clone();
        let label = name.to_string();
        std::thread::Builder::new()
            .name(format!("fixture-{name}"))
            .spawn(move || {
                for line in BufReader::new(stdout).lines() {
                    let Ok(line) = line else { break };
                    let at = Mono::now();
                    // Snapshot first: the point is the counters at this moment.
                    let radio = radio
                        .as_ref()
                        .map(|r| (r.stats(RadioSetup::DOWNLINK), r.stats(RadioSetup::UPLINK)));
                    match serde_json::from_str::<Value>(&line) {
                        Ok(value) => {
                            sink.list
                                .lock()
                                .unwrap()
                                .push(FixtureLine { at, value, radio });
                            sink.changed.notify_all();
                        }
                        Err(_) => {
                            tracing::warn!(fixture = %label, line, "unparsable fixture output")
                        }
                    }
                }
                *sink.closed.lock().unwrap() = true;
                sink.changed.notify_all();
            })
            .map_err(|e| anyhow::anyhow!("cannot start the reader of {name}: {e}"))?;
        Ok(LineReader { lines })
    }

    /// Waits for the first line matching `pred`.
    fn wait_for(
        &self,
        timeout: Duration,
        pred: impl Fn(&FixtureLine) -> bool,
    ) -> Option<FixtureLine> {
        let deadline = Instant::now() + timeout;
        let mut list = self.lines.list.lock().unwrap();
        loop {
            if let Some(l) = list.iter().find(|l| pred(l)) {
                return Some(l.clone());
            }
            let now = Instant::now();
            if now >= deadline || *self.lines.closed.lock().unwrap() {
                return None;
            }
            let wait = (deadline - now).min(Duration::from_millis(100));
            list = self.lines.changed.wait_timeout(list, wait).unwrap().0;
        }
    }

    fn all(&self) -> Vec<FixtureLine> {
        self.lines.list.lock().unwrap().clone()
    }
}

/// A running MavLora link with its fixtures.
pub struct MavloraSession {
    pub options: SessionOptions,
    radio: Arc<RadioEmulator>,
    fc: Process,
    fc_lines: LineReader,
    bridge: Option<Process>,
    router: Option<Process>,
    gcs: Process,
    gcs_lines: LineReader,
    fc_summary: PathBuf,
    /// When the first telemetry reached the GCS.
    pub telemetry_at: Mono,
    pub started: Mono,
}

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
    /// `mavlora_fc.py`'s summary file.
    pub fc: Value,
    /// `mavlora_gcs.py`'s summary line.
    pub gcs: Value,
    /// The GCS's event lines, each with the radio's counters when read.
    pub gcs_events: Vec<FixtureLine>,
    /// The FC fixture's event lines (`ready`, `mission`, `reboot`).
    pub fc_events: Vec<FixtureLine>,
    /// Drone → ground, whole session.
    pub downlink: LinkStats,
    /// Ground → drone, whole session.
    pub uplink: LinkStats,
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

    /// The event `name`'s line.
    pub fn event(&self, name: &str) -> Option<&FixtureLine> {
        self.gcs_events.iter().find(|l| l.event() == Some(name))
    }

    /// Drone → ground bytes on air per second between two GCS events, as the
    /// radio counted them, with the seconds between them.
    pub fn downlink_rate(&self, from: &str, to: &str) -> Option<(f64, f64)> {
        let (a, b) = (self.event(from)?, self.event(to)?);
        let (sa, sb) = (&a.radio.as_ref()?.0, &b.radio.as_ref()?.0);
        let secs = b.at.since(a.at).as_secs_f64();
        (secs > 0.0).then(|| ((sb.bytes_sent - sa.bytes_sent) as f64 / secs, secs))
    }
}

impl MavloraSession {
    /// Starts FC fixture → bridge → radio → router → GCS and waits until
    /// telemetry reaches the GCS.
    pub fn start(options: SessionOptions) -> Result<MavloraSession> {
        let dir = &options.out_dir;
        std::fs::create_dir_all(dir).map_err(|source| SessionError::Io {
            path: dir.clone(),
            source,
        })?;
        let bridged = options.variant == Variant::Bridge;
        if bridged {
            for p in [&options.bridge_program, &options.router_program] {
                if !p.exists() {
                    return Err(SessionError::ProgramMissing(p.clone()));
                }
            }
        }
        let started = Mono::now();
        let radio = Arc::new(RadioEmulator::new(&options.name, options.radio.radio()?)?);

        // Flight controller: its own pty behind a bridge; the radio's port when naive.
        let fc_summary = dir.join("fc.json");
        let mut command = Command::new(&options.python);
        command
            .arg(options.fixtures_dir.join("mavlora_fc.py"))
            .arg("--summary")
            .arg(&fc_summary)
            .args(["--profile", options.fc_profile.as_str(), "--path", "route"]);
        if !bridged {
            command.args(["--port", radio.a_path()]);
        }
        let mut fc = Process::spawn("mavlora_fc", command, &dir.join("fc.log"))?;
        let fc_lines = LineReader::start("mavlora_fc", fc.take_stdout().unwrap(), None)?;
        let fixture_timeout = Duration::from_secs(10);
        let ready = fc_lines
            .wait_for(fixture_timeout, |l| l.event() == Some("ready"))
            .ok_or_else(|| SessionError::FixtureStart {
                name: "mavlora_fc.py".into(),
                timeout: fixture_timeout,
                log: fc.log_path().to_path_buf(),
            })?;
        let fc_port = ready.value["port"].as_str().unwrap_or_default().to_string();
        tracing::debug!(port = %fc_port, "FC fixture ready");

        let mut bridge = None;
        let mut router = None;
        let gcs_target: Vec<String>;
        if bridged {
            let mut command = Command::new(&options.bridge_program);
            command
                .args(["--fc", &fc_port, "--radio", radio.a_path()])
                .arg("--profile")
                .arg(&options.bridge_profile)
                .args(["--rate", &options.rate.to_string()])
                .args(["--status-interval", "2"])
                .env("NO_COLOR", "1");
            if options.compact {
                command.arg("--compact");
            }
            bridge = Some(Process::spawn(
                "mavlora-bridge",
                command,
                &dir.join("bridge.log"),
            )?);
            let port = free_udp_port(dir)?;
            let mut command = Command::new(&options.router_program);
            command
                .args(["--radio", radio.b_path()])
                .args(["--udp", &format!("127.0.0.1:{port}")])
                .args(["--udp-bind", "127.0.0.1:0", "--status-interval", "2"])
                .arg("--tlog")
                .arg(dir.join("router.tlog"))
                .env("NO_COLOR", "1");
            router = Some(Process::spawn(
                "mavlora-router",
                command,
                &dir.join("router.log"),
            )?);
            gcs_target = vec!["--udp".into(), format!("127.0.0.1:{port}")];
        } else {
            gcs_target = vec!["--serial".into(), radio.b_path().to_string()];
        }

        let p = &options.gcs;
        let mut command = Command::new(&options.python);
        command
            .arg(options.fixtures_dir.join("mavlora_gcs.py"))
            .args(&gcs_target)
            .arg("--events")
            .args(["--listen", &p.listen_s.to_string()])
            .args(["--warmup", &p.warmup_s.to_string()])
            .args(["--commands", &p.commands.to_string()])
            .args(["--command-interval", &p.command_interval_s.to_string()])
            .args(["--command-retry", &p.command_retry_s.to_string()])
            .args(["--command-tries", &p.command_tries.to_string()])
            .args(["--items", &p.items.to_string()])
            .args(["--item-timeout", &p.item_timeout_s.to_string()])
            .args(["--upload-timeout", &p.upload_timeout_s.to_string()]);
        let mut gcs = Process::spawn("mavlora_gcs", command, &dir.join("gcs.log"))?;
        let gcs_lines = LineReader::start(
            "mavlora_gcs",
            gcs.take_stdout().unwrap(),
            Some(radio.clone()),
        )?;

        let mut session = MavloraSession {
            telemetry_at: started,
            started,
            radio,
            fc,
            fc_lines,
            bridge,
            router,
            gcs,
            gcs_lines,
            fc_summary,
            options,
        };
        // Up when the vehicle's first message reaches the ground station.
        let timeout = session.options.ready_timeout;
        let Some(first) = session
            .gcs_lines
            .wait_for(timeout, |l| l.event() == Some("telemetry"))
        else {
            for p in [&mut session.bridge, &mut session.router]
                .into_iter()
                .flatten()
            {
                p.check_running()?;
            }
            session.fc.check_running()?;
            return Err(SessionError::NoTelemetry {
                timeout,
                dir: session.options.out_dir.clone(),
            });
        };
        session.telemetry_at = first.at;
        tracing::info!(
            session = %session.options.name,
            after_ms = first.at.ms_since(started),
            "telemetry at the GCS"
        );
        Ok(session)
    }

    /// The radio's counters now: (downlink, uplink).
    pub fn radio_stats(&self) -> (LinkStats, LinkStats) {
        (
            self.radio.stats(RadioSetup::DOWNLINK),
            self.radio.stats(RadioSetup::UPLINK),
        )
    }

    /// Waits for the GCS to finish its plan, stops everything and collects the evidence.
    pub fn finish(mut self) -> Result<SessionReport> {
        let dir = self.options.out_dir.clone();
        let budget = self.options.gcs.budget();
        let gcs_status = self.gcs.wait_timeout(budget)?;
        let gcs_status = match gcs_status {
            Some(s) => Some(s),
            None => {
                self.stop_all();
                return Err(SessionError::GcsTimeout {
                    timeout: budget,
                    log: self.gcs.log_path().to_path_buf(),
                });
            }
        };
        // The reader sees EOF after the exit; wait for its last line.
        let _ = self
            .gcs_lines
            .wait_for(Duration::from_secs(2), |l| l.value.get("event").is_none());
        let mut exits = vec![ExitRecord {
            name: "mavlora_gcs".into(),
            status: gcs_status,
            accepted: vec![GCS_PHASE_FAILED],
            log: self.gcs.log_path().to_path_buf(),
        }];
        let grace = Duration::from_secs(5);
        // Bridge first, so the FC is not left talking to nobody mid-frame; router; FC last
        // (it writes its summary on SIGTERM).
        for p in [self.bridge.as_mut(), self.router.as_mut()]
            .into_iter()
            .flatten()
        {
            exits.push(ExitRecord {
                name: p.name().to_string(),
                status: p.terminate(grace)?,
                accepted: Vec::new(),
                log: p.log_path().to_path_buf(),
            });
        }
        exits.push(ExitRecord {
            name: "mavlora_fc".into(),
            status: self.fc.terminate(grace)?,
            accepted: Vec::new(),
            log: self.fc.log_path().to_path_buf(),
        });
        let (downlink, uplink) = self.radio_stats();
        let summary_err = |what: &Path, reason: String| SessionError::Summary {
            what: what.display().to_string(),
            reason,
        };
        let fc_text = std::fs::read_to_string(&self.fc_summary)
            .map_err(|e| summary_err(&self.fc_summary, e.to_string()))?;
        let fc: Value = serde_json::from_str(&fc_text)
            .map_err(|e| summary_err(&self.fc_summary, e.to_string()))?;
        let lines = self.gcs_lines.all();
        let gcs = lines
            .iter()
            .rev()
            .find(|l| l.value.get("event").is_none())
            .map(|l| l.value.clone())
            .ok_or_else(|| {
                summary_err(
                    self.gcs.log_path(),
                    "the GCS fixture printed no summary line".into(),
                )
            })?;
        let gcs_events = lines
            .into_iter()
            .filter(|l| l.value.get("event").is_some())
            .collect();
        let fc_events = self.fc_lines.all();
        let bridge_status = self.bridge.as_ref().and_then(|p| last_status(p.log_path()));
        let router_status = self.router.as_ref().and_then(|p| last_status(p.log_path()));
        let mut files: Vec<PathBuf> = exits.iter().map(|e| e.log.clone()).collect();
        files.push(self.fc_summary.clone());
        let tlog = dir.join("router.tlog");
        if tlog.exists() {
            files.push(tlog);
        }
        for e in &exits {
            if !e.clean() {
                tracing::warn!(program = %e.name, status = ?e.status, "did not exit cleanly");
            }
        }
        Ok(SessionReport {
            fc,
            gcs,
            gcs_events,
            fc_events,
            downlink,
            uplink,
            bridge_status,
            router_status,
            exits,
            files,
        })
    }

    fn stop_all(&mut self) {
        let grace = Duration::from_secs(2);
        self.gcs.stop(grace);
        for p in [self.bridge.as_mut(), self.router.as_mut()]
            .into_iter()
            .flatten()
        {
            p.stop(grace);
        }
        self.fc.stop(grace);
    }
}

/// A UDP port free now on loopback, for the router to send to.
fn free_udp_port(dir: &Path) -> Result<u16> {
    UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .map(|a| a.port())
        .map_err(|source| SessionError::Io {
            path: dir.to_path_buf(),
            source,
        })
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

    fn options(dir: &Path) -> SessionOptions {
        let repo = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let defaults = SessionDefaults {
            python: PathBuf::from("python3"),
            fixtures_dir: repo.join("fixtures"),
            bridge_program: PathBuf::from("/bin/true"),
            router_program: PathBuf::from("/bin/true"),
            profile_dir: repo.join("mavlora/profiles"),
            lossy_radio: sik_with_loss(0.1, 2.0).unwrap(),
            clean_radio: RadioSetup::builtin("sik-64k").unwrap(),
            c2_radio: sik_with_independent_loss(0.1).unwrap(),
        };
        defaults.options("t", &defaults.clean_radio, dir)
    }

    #[test]
    fn a_missing_program_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let mut o = options(dir.path());
        o.bridge_program = dir.path().join("no-such-bridge");
        let err = MavloraSession::start(o).err().unwrap();
        assert!(matches!(err, SessionError::ProgramMissing(_)), "{err}");
        assert!(err.to_string().contains("no-such-bridge"), "{err}");
    }

    #[test]
    fn a_fixture_that_does_not_start_names_its_log() {
        let dir = tempfile::tempdir().unwrap();
        let mut o = options(dir.path());
        o.fixtures_dir = dir.path().join("no-fixtures");
        let err = MavloraSession::start(o).err().unwrap();
        assert!(matches!(err, SessionError::FixtureStart { .. }), "{err}");
        assert!(err.to_string().contains("fc.log"), "{err}");
        let log = std::fs::read_to_string(dir.path().join("fc.log")).unwrap();
        assert!(log.contains("mavlora_fc.py"), "{log}");
    }

    #[test]
    fn gcs_budget_covers_every_retry_of_every_command() {
        let plan = GcsPlan {
            listen_s: 2.0,
            commands: 10,
            ..GcsPlan::default()
        };
        // 10 × (0.5 + 1.5 × 5) + 2 + 10 margin
        assert_eq!(plan.budget(), Duration::from_secs(92));
    }

    #[test]
    fn lossy_sik_has_the_asked_mean_loss_both_ways() {
        let s = sik_with_loss(0.1, 2.0).unwrap();
        for ge in [&s.uplink.burst, &s.downlink.burst] {
            let ge = ge.as_ref().unwrap();
            let mean = ge.p_good_to_bad / (ge.p_good_to_bad + ge.p_bad_to_good);
            assert!((mean - 0.1).abs() < 1e-9, "{ge:?}");
        }
        assert_ne!(s.uplink.seed, s.downlink.seed);
    }
}
