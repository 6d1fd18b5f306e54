//! Bringing the chain up and down: FC fixture, bridge, radio emulator, router,
//! GCS fixture.

use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use super::report::{ExitRecord, GCS_PHASE_FAILED, LinkNotice, ProgramStatus, SessionReport};
use super::{Ground, Result, SessionError, SessionOptions, Variant};
use crate::clock::Mono;
use crate::driver::fixture::{Fixture, FixtureError};
use crate::driver::process::Process;
use crate::driver::radio_emulator::{End, RadioEmulator};
use crate::mavlora::MAVLORA_BRIDGE;
use crate::mavlora::fixture::fc::FcEvent;
use crate::mavlora::fixture::gcs::GcsEvent;
use crate::mavlora::fixture::intruder::IntruderEvent;
use harness_radio::{Direction, LinkStats};

/// The radio's (downlink, uplink) counters when a GCS line was read.
pub type RadioCounters = (LinkStats, LinkStats);
/// A GCS fixture line with the radio's counters when it was read.
pub type GcsLine = crate::driver::fixture::Line<GcsEvent, RadioCounters>;

/// A running MavLora link with its fixtures.
pub struct MavloraSession {
    pub options: SessionOptions,
    radio: Arc<RadioEmulator>,
    fc: Fixture<FcEvent>,
    bridge: Option<Process>,
    /// How to start the bridge again (a crash and restart).
    bridge_spawn: Option<BridgeSpawn>,
    /// Logs of bridges that were crashed on purpose.
    crashed_logs: Vec<PathBuf>,
    router: Option<Process>,
    /// How to start the router again.
    router_spawn: Option<RouterSpawn>,
    /// Where the router takes ground stations' datagrams.
    router_ground: Option<SocketAddr>,
    gcs: Fixture<GcsEvent, RadioCounters>,
    fc_summary: PathBuf,
    /// When the first telemetry reached the GCS.
    pub telemetry_at: Mono,
    pub started: Mono,
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
                    return Err(MAVLORA_BRIDGE.missing(p.clone()).into());
                }
            }
        }
        let started = Mono::now();
        let radio = match &options.radio_path {
            Some(path) => path.0.clone(),
            None => Arc::new(RadioEmulator::with_stable_names(
                &options.name,
                options.radio.radio()?,
                dir,
            )?),
        };
        let fc_summary = dir.join("fc.json");
        // Flight controller: its own pty behind a bridge; the radio's port when naive.
        let (fc, fc_port) = start_fc(&options, &fc_summary, (!bridged).then(|| radio.air_path()))?;
        let link = if bridged {
            Some(Bridged::start(&options, &radio, fc_port)?)
        } else {
            None
        };
        let gcs = start_gcs(&options, &radio, link.as_ref())?;
        let (bridge, bridge_spawn, router, router_spawn, router_ground) = match link {
            Some(l) => (
                Some(l.bridge),
                Some(l.bridge_spawn),
                Some(l.router),
                Some(l.router_spawn),
                Some(l.router_ground),
            ),
            None => (None, None, None, None, None),
        };
        let mut session = MavloraSession {
            telemetry_at: started,
            started,
            radio,
            fc,
            bridge,
            bridge_spawn,
            crashed_logs: Vec::new(),
            router,
            router_spawn,
            router_ground,
            gcs,
            fc_summary,
            options,
        };
        session.wait_for_telemetry()?;
        Ok(session)
    }

    /// Up when the vehicle's first message reaches the ground station.
    fn wait_for_telemetry(&mut self) -> Result<()> {
        let timeout = self.options.ready_timeout;
        let first = self.gcs.wait_for("telemetry", timeout, |l| {
            matches!(l.event, GcsEvent::Telemetry { .. })
        });
        let first = match first {
            Ok(first) => first,
            // A fixture that broke its own protocol says so, not "no telemetry".
            Err(e @ (FixtureError::BadLine { .. } | FixtureError::Reported { .. })) => {
                return Err(e.into());
            }
            Err(_) => {
                for p in [&mut self.bridge, &mut self.router].into_iter().flatten() {
                    p.check_running()?;
                }
                self.fc.check_running()?;
                return Err(SessionError::NoTelemetry {
                    timeout,
                    dir: self.options.out_dir.clone(),
                });
            }
        };
        self.telemetry_at = first.at;
        tracing::info!(
            session = %self.options.name,
            after_ms = first.at.ms_since(self.started),
            "telemetry at the GCS"
        );
        Ok(())
    }

    /// Kills `which` program outright (SIGKILL: a crash, nothing flushed), waits `down`, and
    /// starts it again with the same ports, keys and signing-state file; returns when the
    /// new one was started. Its log is `<program>-<n>.log`; the crashed one's is kept.
    pub fn crash_and_restart(&mut self, which: Program, down: Duration) -> Result<Mono> {
        let process = match which {
            Program::Bridge => self.bridge.as_mut(),
            Program::Router => self.router.as_mut(),
        };
        let Some(process) = process else {
            return Err(anyhow::anyhow!("this session runs no {which} to restart").into());
        };
        process.kill();
        self.crashed_logs.push(process.log_path().to_path_buf());
        std::thread::sleep(down);
        let started = Mono::now();
        match which {
            Program::Bridge => {
                let spawn = self.bridge_spawn.as_mut().expect("a bridge has its spawn");
                self.bridge = Some(spawn.start(&self.options, &self.radio.air_path())?);
            }
            Program::Router => {
                let spawn = self.router_spawn.as_mut().expect("a router has its spawn");
                self.router = Some(spawn.start(&self.options, &self.radio.ground_path())?);
            }
        }
        Ok(started)
    }

    /// The log the running `which` writes to.
    pub fn log_of(&self, which: Program) -> Option<&Path> {
        match which {
            Program::Bridge => self.bridge.as_ref(),
            Program::Router => self.router.as_ref(),
        }
        .map(Process::log_path)
    }

    /// Starts `mavlora_intruder.py` against the router's ground port: from `source` (an
    /// address of this host, 127.0.0.2 plays another host), as system `sysid`, its frames
    /// signed with `sign_key` (64 hex characters) if given, for `duration`. Logs to
    /// `<label>.log`; returns once its socket is bound.
    pub fn start_intruder(
        &self,
        label: &str,
        source: &str,
        sysid: u8,
        sign_key: Option<&str>,
        duration: Duration,
    ) -> Result<Fixture<IntruderEvent>> {
        let Some(router) = self.router_ground else {
            return Err(anyhow::anyhow!("this session runs no router to attack").into());
        };
        let mut command = Command::new(&self.options.python);
        command
            .arg(self.options.fixtures_dir.join("mavlora_intruder.py"))
            .args(["--router", &router.to_string(), "--source", source])
            .args(["--sysid", &sysid.to_string()])
            .args(["--duration", &duration.as_secs_f64().to_string()]);
        if let Some(key) = sign_key {
            command.args(["--sign-key", key]);
        }
        let log = self.options.out_dir.join(format!("{label}.log"));
        let intruder = Fixture::start(label, command, &log)?;
        let timeout = Duration::from_secs(10);
        intruder
            .wait_for("ready", timeout, |l| {
                matches!(l.event, IntruderEvent::Ready { .. })
            })
            .map_err(|e| SessionError::FixtureStart {
                name: "mavlora_intruder.py".into(),
                timeout,
                log,
                reason: e.to_string(),
            })?;
        Ok(intruder)
    }

    /// Unplugs one side's radio for `down` and plugs a new one in under the same stable
    /// name (a USB radio pulled and put back); returns when it was back.
    pub fn replug_radio(&self, end: End, down: Duration) -> Result<Mono> {
        Ok(self.radio.replug(end, down)?)
    }

    /// Silences the radio both ways from now for `length`; returns when it began.
    pub fn silence_radio(&self, length: Duration) -> Result<Mono> {
        Ok(self.radio.silence_now(length)?)
    }

    /// The radio's counters now: (downlink, uplink).
    pub fn radio_stats(&self) -> (LinkStats, LinkStats) {
        (
            self.radio.stats(Direction::Downlink),
            self.radio.stats(Direction::Uplink),
        )
    }

    /// Waits for the GCS to finish its plan, stops everything and collects the evidence.
    /// The bridge's and the router's process ids (`None`: not running, or no bridge).
    pub fn pids(&self) -> [Option<u32>; 2] {
        [
            self.bridge.as_ref().map(Process::id),
            self.router.as_ref().map(Process::id),
        ]
    }

    pub fn finish(mut self) -> Result<SessionReport> {
        let dir = self.options.out_dir.clone();
        let budget = match &self.options.ground {
            Ground::Pymavlink => self.options.gcs.budget(),
            Ground::Mavsdk(plan) => plan.budget(),
        };
        let Some(gcs_status) = self.gcs.wait_exit(budget)? else {
            self.stop_all();
            return Err(SessionError::GcsTimeout {
                timeout: budget,
                log: self.gcs.log_path().to_path_buf(),
            });
        };
        // The summary is its last line; the reader sees it before EOF.
        let gcs = self.gcs.summary(Duration::from_secs(2))?;
        let mut exits = vec![ExitRecord {
            name: self.gcs.name().to_string(),
            status: Some(gcs_status),
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
        // terminate() has read its last line.
        let fc = self.fc.summary(Duration::ZERO)?;
        let gcs_events = self
            .gcs
            .lines()
            .into_iter()
            .filter(|l| !matches!(l.event, GcsEvent::Summary(_)))
            .collect();
        let fc_events = self
            .fc
            .lines()
            .into_iter()
            .filter(|l| !matches!(l.event, FcEvent::Summary(_)))
            .collect();
        let status_files: Vec<PathBuf> = [
            self.bridge_spawn.as_ref().map(|b| b.status_files(&dir)),
            self.router_spawn.as_ref().map(|r| r.status_files(&dir)),
        ]
        .into_iter()
        .flatten()
        .flatten()
        .collect();
        // The running (last started) program's file: a restarted one writes a new file.
        let bridge_status = match &self.bridge_spawn {
            Some(b) if self.bridge.is_some() => ProgramStatus::read(&b.status_path(&dir))?,
            _ => None,
        };
        let router_status = match &self.router_spawn {
            Some(r) if self.router.is_some() => ProgramStatus::read(&r.status_path(&dir))?,
            _ => None,
        };
        let mut link_notices = Vec::new();
        if let Some(r) = &self.router_spawn {
            for file in r.status_files(&dir) {
                link_notices.extend(LinkNotice::read_all(&file)?);
            }
        }
        let mut files: Vec<PathBuf> = exits.iter().map(|e| e.log.clone()).collect();
        files.extend(status_files.into_iter().filter(|f| f.exists()));
        files.extend(self.crashed_logs.iter().cloned());
        files.push(self.fc_summary.clone());
        let starts = self.router_spawn.as_ref().map_or(0, |r| r.starts);
        files.extend(
            (1..=starts)
                .map(|n| nth(&dir, "router", "tlog", n))
                .filter(|t| t.exists()),
        );
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
            radio_epoch: self.radio.epoch(),
            bridge_status,
            router_status,
            link_notices,
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

/// Writes a fresh radio signing key (64 hex characters, mode 600) into `dir`. Not a secret
/// worth keeping: it lives as long as the session's evidence.
fn write_key(dir: &Path, name: &str) -> Result<PathBuf> {
    use std::io::Write as _;
    use std::os::unix::fs::OpenOptionsExt as _;
    let path = dir.join(name);
    let io = |source| SessionError::Io {
        path: path.clone(),
        source,
    };
    let mut bytes = [0u8; 32];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut bytes))
        .map_err(io)?;
    let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
    let _ = std::fs::remove_file(&path);
    std::fs::OpenOptions::new()
        .create_new(true)
        .write(true)
        .mode(0o600)
        .open(&path)
        .and_then(|mut f| writeln!(f, "{hex}"))
        .map_err(io)?;
    Ok(path)
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

/// One of the two MavLora programs of a session.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Program {
    /// `mavlora-bridge`, on the drone.
    Bridge,
    /// `mavlora-router`, on the ground.
    Router,
}

impl std::fmt::Display for Program {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Program::Bridge => "bridge",
            Program::Router => "router",
        })
    }
}

/// Starts the FC fixture the options name, writing its summary to `summary`, on `port` if
/// given (else on a pty of its own); returns it, once ready, with the port it serves.
fn start_fc(
    options: &SessionOptions,
    summary: &Path,
    port: Option<String>,
) -> Result<(Fixture<FcEvent>, String)> {
    let mut command = Command::new(&options.python);
    command
        .arg(options.fixtures_dir.join(options.fc_profile.fixture()))
        .arg("--summary")
        .arg(summary)
        .args(options.fc_profile.fixture_args());
    if let Some(item) = options.fc_reboot_at_item {
        command.args(["--reboot-at-item", &item.to_string()]);
    }
    if let Some(port) = &port {
        command.args(["--port", port]);
    }
    let fc = Fixture::start("mavlora_fc", command, &options.out_dir.join("fc.log"))?;
    let fixture_timeout = Duration::from_secs(10);
    let ready = fc
        .wait_for("ready", fixture_timeout, |l| {
            matches!(l.event, FcEvent::Ready { .. })
        })
        .map_err(|e| SessionError::FixtureStart {
            name: options.fc_profile.fixture().into(),
            timeout: fixture_timeout,
            log: fc.log_path().to_path_buf(),
            reason: e.to_string(),
        })?;
    let FcEvent::Ready { port: fc_port, .. } = ready.event else {
        unreachable!("waited for ready")
    };
    tracing::debug!(port = %fc_port, "FC fixture ready");
    Ok((fc, fc_port))
}

/// The bridge and router of a bridged session, started.
pub(crate) struct Bridged {
    pub(crate) bridge: Process,
    pub(crate) bridge_spawn: BridgeSpawn,
    pub(crate) router: Process,
    pub(crate) router_spawn: RouterSpawn,
    /// Where the router takes ground stations' datagrams.
    pub(crate) router_ground: SocketAddr,
    /// The GCS fixture's port, where the router sends until a ground station talks.
    pub(crate) gcs_port: u16,
    /// The ground signing key, when the session signs the ground side.
    pub(crate) gcs_key: Option<PathBuf>,
}

impl Bridged {
    /// Starts the bridge on the FC fixture's `fc_port` and the radio's air end, and the router
    /// on its ground end.
    pub(crate) fn start(
        options: &SessionOptions,
        radio: &RadioEmulator,
        fc_port: String,
    ) -> Result<Bridged> {
        let dir = &options.out_dir;
        // The radio leg is signed in every phase: a fresh key per session, owner-only
        // (the binaries refuse others-readable keys), each end with its own state file.
        let key = write_key(dir, "radio.key")?;
        let mut bridge_spawn = BridgeSpawn {
            fc_port,
            key: key.clone(),
            starts: 0,
        };
        let bridge = bridge_spawn.start(options, &radio.air_path())?;
        let gcs_port = free_udp_port(dir)?;
        let router_ground = SocketAddr::from(([127, 0, 0, 1], free_udp_port(dir)?));
        let gcs_key = if options.ground_key {
            Some(write_key(dir, "ground.key")?)
        } else {
            None
        };
        let mut router_spawn = RouterSpawn {
            key,
            ground_key: gcs_key.clone(),
            send_to: gcs_port,
            bind: router_ground,
            starts: 0,
        };
        let router = router_spawn.start(options, &radio.ground_path())?;
        Ok(Bridged {
            bridge,
            bridge_spawn,
            router,
            router_spawn,
            router_ground,
            gcs_port,
            gcs_key,
        })
    }
}

/// Starts the GCS fixture on its plan: on the router's UDP side when bridged, else straight
/// on the radio's ground end.
fn start_gcs(
    options: &SessionOptions,
    radio: &Arc<RadioEmulator>,
    link: Option<&Bridged>,
) -> Result<Fixture<GcsEvent, RadioCounters>> {
    let (name, command) = match &options.ground {
        Ground::Pymavlink => ("mavlora_gcs", pymavlink_gcs(options, radio, link)),
        Ground::Mavsdk(plan) => {
            let Some(link) = link else {
                return Err(anyhow::anyhow!(
                    "MAVSDK as the ground station needs the router (a bridged session)"
                )
                .into());
            };
            if link.gcs_key.is_some() {
                return Err(anyhow::anyhow!(
                    "mavsdk_gcs.py does not sign: no --ground-key with MAVSDK as the ground station"
                )
                .into());
            }
            let mut command = Command::new(&options.python);
            command
                .arg(options.fixtures_dir.join("mavsdk_gcs.py"))
                .args(["--udp", &format!("127.0.0.1:{}", link.gcs_port)])
                .args(["--uploads", &plan.uploads.to_string()])
                .args(["--items", &plan.items.to_string()])
                .args(["--pause", &plan.pause_s.to_string()])
                .args(["--settle", &plan.settle_s.to_string()])
                // Within the session's wait for telemetry, so its own error line (which
                // names what it waited for) comes first.
                .args([
                    "--connect-timeout",
                    &(options.ready_timeout.as_secs_f64() - 2.0)
                        .max(1.0)
                        .to_string(),
                ]);
            ("mavsdk_gcs", command)
        }
    };
    // Each line carries the radio's counters when it was read, so a
    // rate taken from the radio covers the GCS's own window.
    let counters = radio.clone();
    let gcs = Fixture::start_with(name, command, &options.out_dir.join("gcs.log"), move || {
        (
            counters.stats(Direction::Downlink),
            counters.stats(Direction::Uplink),
        )
    })?;
    Ok(gcs)
}

/// `mavlora_gcs.py` on the options' plan.
fn pymavlink_gcs(
    options: &SessionOptions,
    radio: &Arc<RadioEmulator>,
    link: Option<&Bridged>,
) -> Command {
    let p = &options.gcs;
    let mut command = Command::new(&options.python);
    command.arg(options.fixtures_dir.join("mavlora_gcs.py"));
    match link {
        Some(l) => command.args(["--udp", &format!("127.0.0.1:{}", l.gcs_port)]),
        None => command.args(["--serial", &radio.ground_path()]),
    };
    command
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
    if let Some(key) = link.and_then(|l| l.gcs_key.as_ref()) {
        command.arg("--key").arg(key);
    }
    command
}

/// The log of a program's `n`th start: `<stem>.<ext>`, then `<stem>-<n>.<ext>`.
fn nth(dir: &Path, stem: &str, ext: &str, n: u32) -> PathBuf {
    match n {
        1 => dir.join(format!("{stem}.{ext}")),
        n => dir.join(format!("{stem}-{n}.{ext}")),
    }
}

/// What starting the router takes, kept to start it again.
pub(crate) struct RouterSpawn {
    key: PathBuf,
    ground_key: Option<PathBuf>,
    /// The GCS fixture's port, where the router sends until a ground station talks.
    send_to: u16,
    bind: SocketAddr,
    /// Routers started so far.
    starts: u32,
}

impl RouterSpawn {
    /// The running router's status file: `router.status.jsonl`, then `router-<n>.status.jsonl`.
    pub(crate) fn status_path(&self, dir: &Path) -> PathBuf {
        nth(dir, "router", "status.jsonl", self.starts)
    }

    /// Every router's status file.
    fn status_files(&self, dir: &Path) -> Vec<PathBuf> {
        (1..=self.starts)
            .map(|n| nth(dir, "router", "status.jsonl", n))
            .collect()
    }

    /// Starts a router on `radio_port`; the first logs to `router.log` and `router.tlog`,
    /// later ones to `router-<n>.log`/`.tlog`. Every one shares the signing-state file.
    fn start(&mut self, options: &SessionOptions, radio_port: &str) -> Result<Process> {
        let dir = &options.out_dir;
        self.starts += 1;
        let mut command = Command::new(&options.router_program);
        command
            .args(["--radio", radio_port])
            .args(["--rate", &options.rate.to_string()])
            .args(["--burst", &options.burst.to_string()])
            .args(["--udp", &format!("127.0.0.1:{}", self.send_to)])
            .args([
                "--udp-bind",
                &self.bind.to_string(),
                "--status-interval",
                "2",
            ])
            .arg("--tlog")
            .arg(nth(dir, "router", "tlog", self.starts))
            .arg("--status-json")
            .arg(self.status_path(dir))
            .arg("--key")
            .arg(&self.key)
            .arg("--signing-state")
            .arg(dir.join("router.signing-state"))
            .env("NO_COLOR", "1");
        if let Some(period) = options.link_quality_period {
            command.args(["--link-quality-period", &period.to_string()]);
        }
        if let Some(key) = &self.ground_key {
            command.arg("--ground-key").arg(key);
        }
        let log = nth(dir, "router", "log", self.starts);
        Ok(Process::spawn("mavlora-router", command, &log)?)
    }
}

/// What starting the bridge takes, kept to start it again.
pub(crate) struct BridgeSpawn {
    fc_port: String,
    key: PathBuf,
    /// Bridges started so far.
    starts: u32,
}

impl BridgeSpawn {
    /// The running bridge's status file: `bridge.status.jsonl`, then `bridge-<n>.status.jsonl`.
    pub(crate) fn status_path(&self, dir: &Path) -> PathBuf {
        nth(dir, "bridge", "status.jsonl", self.starts)
    }

    /// Every bridge's status file.
    fn status_files(&self, dir: &Path) -> Vec<PathBuf> {
        (1..=self.starts)
            .map(|n| nth(dir, "bridge", "status.jsonl", n))
            .collect()
    }

    /// Starts a bridge between the FC fixture's port and `radio_port`; the first logs to
    /// `bridge.log`, later ones to `bridge-<n>.log`. Every one shares the signing-state file.
    fn start(&mut self, options: &SessionOptions, radio_port: &str) -> Result<Process> {
        let dir = &options.out_dir;
        self.starts += 1;
        let mut command = Command::new(&options.bridge_program);
        command
            .args(["--fc", &self.fc_port, "--radio", radio_port])
            .arg("--profile")
            .arg(&options.bridge_profile)
            .args(["--rate", &options.rate.to_string()])
            .args(["--burst", &options.burst.to_string()])
            .args(["--status-interval", "2"])
            .arg("--key")
            .arg(&self.key)
            .arg("--signing-state")
            .arg(dir.join("bridge.signing-state"))
            .arg("--status-json")
            .arg(self.status_path(dir))
            .env("NO_COLOR", "1");
        if options.compact {
            command.arg("--compact");
        }
        if let Some(baud) = options.fc_baud {
            command.args(["--fc-baud", &baud.to_string()]);
        }
        if let Some(period) = options.link_quality_period {
            command.args(["--link-quality-period", &period.to_string()]);
        }
        let log = nth(dir, "bridge", "log", self.starts);
        Ok(Process::spawn("mavlora-bridge", command, &log)?)
    }
}
