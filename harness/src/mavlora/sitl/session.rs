//! One MavLora link behind a real autopilot, on the real clock:
//!
//! ```text
//! SITL ─pty cable─ mavlora-bridge ─ RadioEmulator ─ mavlora-router ─UDP─ sitl_gcs.py
//!  └─ truth port (TCP / UDP) ─ sitl_truth.py
//! ```
//!
//! The ground station runs one scenario (`--scenario`) and exits; the truth fixture reads the
//! vehicle's own word the whole time and answers questions (`mission 0`, `param NAME`). A
//! SITL that dies while the session runs ends it with an error naming it and its log.

use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};

use crate::clock::Mono;
use crate::driver::autopilot::{Autopilot, AutopilotSpec};
use crate::driver::fixture::{Fixture, FixtureError, Line};
use crate::driver::radio_emulator::RadioEmulator;
use crate::mavlora::fixture::sitl::{GroundEvent, GroundSummary, TruthEvent, TruthSummary};
use crate::mavlora::session::{Bridged, ProgramStatus, RadioCounters, SessionOptions};
use harness_radio::{Direction, LinkStats};

/// Longest wait for a SITL's first heartbeat on its truth port, and for the ground
/// station's first heartbeat through the link (ArduPilot answers in ~1 s, PX4 in ~0.2 s;
/// a loaded 2-core machine is slower).
const CONNECT_TIMEOUT: Duration = Duration::from_secs(60);
/// Longest wait for the truth connection's answer (a plan of a few dozen items over a
/// local link; retries of 1 s).
const TRUTH_ANSWER: Duration = Duration::from_secs(20);
/// How often the session looks whether the SITL still runs while it waits.
const POLL: Duration = Duration::from_millis(500);

/// A ground-station line with the radio's counters when it was read.
pub type GroundLine = Line<GroundEvent, RadioCounters>;

/// What a session needs beyond the bridge and router settings.
pub struct SitlOptions {
    /// Bridge, router, radio, profile and the output folder.
    pub link: SessionOptions,
    /// The autopilot's rig-file name and spec.
    pub autopilot: (String, AutopilotSpec),
    /// `sitl_gcs.py`'s scenario arguments (`--scenario telemetry --listen 30`...).
    pub ground_args: Vec<String>,
    /// Longest the ground station's scenario may take once connected.
    pub budget: Duration,
    /// Questions for the truth connection once the ground station is done (`mission 0`,
    /// `param NAME`): their answers are in the report's truth lines.
    pub truth_after: Vec<String>,
}

/// A running link behind a real autopilot.
pub struct SitlSession {
    pub name: String,
    autopilot: Autopilot,
    radio: Arc<RadioEmulator>,
    truth: Option<Fixture<TruthEvent>>,
    link: Option<Bridged>,
    ground: Fixture<GroundEvent, RadioCounters>,
    budget: Duration,
    truth_after: Vec<String>,
    out_dir: PathBuf,
    /// When the autopilot was started.
    pub started: Mono,
}

/// What a finished session leaves.
pub struct SitlReport {
    pub ground: Vec<GroundLine>,
    pub ground_summary: GroundSummary,
    /// The ground station's exit status code (0 ok, 3 its scenario failed).
    pub ground_exit: Option<i32>,
    pub truth: Vec<TruthEvent>,
    pub truth_summary: Option<TruthSummary>,
    pub downlink: LinkStats,
    pub uplink: LinkStats,
    pub bridge_status: Option<ProgramStatus>,
    pub router_status: Option<ProgramStatus>,
    /// Logs and status files, for the evidence.
    pub files: Vec<PathBuf>,
}

impl SitlReport {
    /// The vehicle clock samples of the truth connection.
    pub fn clock(&self) -> Vec<(Mono, u32)> {
        self.truth
            .iter()
            .filter_map(|e| match e {
                TruthEvent::Clock { t, time_boot_ms } => Some((*t, *time_boot_ms)),
                _ => None,
            })
            .collect()
    }

    /// The autopilot's version from its AUTOPILOT_VERSION, if it sent one.
    pub fn version(&self) -> Option<(String, String)> {
        self.truth.iter().find_map(|e| match e {
            TruthEvent::Version {
                version, git_hash, ..
            } => Some((version.clone(), git_hash.clone())),
            _ => None,
        })
    }

    /// The ground station's events, without the counters.
    pub fn ground_events(&self) -> impl Iterator<Item = &GroundEvent> {
        self.ground.iter().map(|l| &l.event)
    }
}

impl SitlSession {
    /// Starts the autopilot, its truth connection, the bridge, radio and router, and the
    /// ground station; returns once the ground station has the vehicle's heartbeat.
    pub fn start(options: SitlOptions) -> Result<SitlSession> {
        let o = &options.link;
        let dir = o.out_dir.clone();
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        for p in [&o.bridge_program, &o.router_program] {
            if !p.exists() {
                bail!(
                    "{} not found: build it (cargo build --release -p mavlora --bins)",
                    p.display()
                );
            }
        }
        let (name, spec) = &options.autopilot;
        let radio = Arc::new(RadioEmulator::with_stable_names(
            &o.name,
            o.radio.radio()?,
            &dir,
        )?);
        let started = Mono::now();
        let mut autopilot = spec.start(name, &dir)?;
        let truth = match autopilot.truth() {
            Some(port) => {
                let mut command = Command::new(&o.python);
                command
                    .arg(o.fixtures_dir.join("sitl_truth.py"))
                    .args(port.fixture_args())
                    .args(["--sysid", &autopilot.sysid.to_string()]);
                let truth = Fixture::start("sitl_truth", command, &dir.join("truth.log"))?;
                wait_alive(
                    &mut autopilot,
                    &truth,
                    "the vehicle's heartbeat on its truth port",
                    |e| matches!(e, TruthEvent::Ready { .. }),
                )?;
                Some(truth)
            }
            None => None,
        };
        let link = Bridged::start(o, &radio, autopilot.fc_port().to_string())?;
        let mut command = Command::new(&o.python);
        command
            .arg(o.fixtures_dir.join("sitl_gcs.py"))
            .args(["--udp", &format!("127.0.0.1:{}", link.gcs_port)])
            .args(&options.ground_args);
        let counters = radio.clone();
        let ground = Fixture::start_with("sitl_gcs", command, &dir.join("gcs.log"), move || {
            (
                counters.stats(Direction::Downlink),
                counters.stats(Direction::Uplink),
            )
        })?;
        let mut session = SitlSession {
            name: o.name.clone(),
            autopilot,
            radio,
            truth,
            link: Some(link),
            ground,
            budget: options.budget,
            truth_after: options.truth_after,
            out_dir: dir,
            started,
        };
        let connected = wait_alive(
            &mut session.autopilot,
            &session.ground,
            "the vehicle's heartbeat at the ground station",
            |e| matches!(e, GroundEvent::Connected { .. }),
        );
        if let Err(e) = connected {
            let link = session.link.as_mut().expect("started");
            for p in [&mut link.bridge, &mut link.router] {
                p.check_running()?;
            }
            return Err(e);
        }
        tracing::info!(
            session = %session.name,
            after_ms = Mono::now().ms_since(started),
            "vehicle heartbeat at the ground station"
        );
        Ok(session)
    }

    /// Asks the truth connection (`mission 0`, `param NAME`) and waits up to `timeout` for
    /// the answer `wanted` picks out.
    pub fn ask_truth(
        &mut self,
        question: &str,
        timeout: Duration,
        wanted: impl Fn(&TruthEvent) -> bool,
    ) -> Result<TruthEvent> {
        let truth = self
            .truth
            .as_ref()
            .ok_or_else(|| anyhow!("{} has no truth connection", self.autopilot.name))?;
        let before = truth.lines().len();
        truth.send(question)?;
        let deadline = Instant::now() + timeout;
        loop {
            self.autopilot.check_running()?;
            if let Some(l) = truth
                .lines()
                .into_iter()
                .skip(before)
                .find(|l| wanted(&l.event))
            {
                return Ok(l.event);
            }
            if let Some(l) = truth
                .lines()
                .into_iter()
                .skip(before)
                .find(|l| matches!(l.event, TruthEvent::Error { .. }))
            {
                bail!("truth connection: {:?} (asked {question:?})", l.event);
            }
            if Instant::now() >= deadline {
                bail!("no answer to {question:?} on the truth connection within {timeout:?}");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The ground station's lines so far.
    pub fn ground_lines(&self) -> Vec<GroundLine> {
        self.ground.lines()
    }

    /// The logs and status files the session writes, for the evidence whatever its end
    /// (a SITL that died is shown with its log).
    pub fn files(&self) -> Vec<PathBuf> {
        let mut files = vec![
            self.ground.log_path().to_path_buf(),
            self.ground.transcript_path(),
        ];
        if let Some(t) = &self.truth {
            files.push(t.log_path().to_path_buf());
            files.push(t.transcript_path());
        }
        if let Some(link) = &self.link {
            files.push(link.bridge.log_path().to_path_buf());
            files.push(link.router.log_path().to_path_buf());
            files.push(link.bridge_spawn.status_path(&self.out_dir));
            files.push(link.router_spawn.status_path(&self.out_dir));
        }
        files.extend(self.autopilot.log_path().map(PathBuf::from));
        files
    }

    /// The autopilot's process id, if the rig started it (a test kills it mid-phase).
    pub fn autopilot_pid(&self) -> Option<u32> {
        self.autopilot.pid()
    }

    /// Waits for the ground station to finish its scenario (checking that the SITL lives),
    /// then stops everything and collects the evidence.
    pub fn finish(mut self) -> Result<SitlReport> {
        let deadline = Instant::now() + self.budget;
        let status = loop {
            if let Err(e) = self.autopilot.check_running() {
                self.stop_all();
                return Err(e.into());
            }
            if let Some(status) = self.ground.wait_exit(POLL)? {
                break status;
            }
            if Instant::now() >= deadline {
                self.stop_all();
                bail!(
                    "the ground station did not finish its scenario within {:?}; see {}",
                    self.budget,
                    self.ground.log_path().display()
                );
            }
        };
        let ground_summary = self.ground.summary(Duration::from_secs(2))?;
        for question in std::mem::take(&mut self.truth_after) {
            let answered = self.ask_truth(&question, TRUTH_ANSWER, |e| {
                matches!(e, TruthEvent::Mission { .. } | TruthEvent::Param { .. })
            });
            if let Err(e) = answered {
                self.stop_all();
                return Err(e);
            }
        }
        let grace = Duration::from_secs(5);
        let dir = self.out_dir.clone();
        let mut files = vec![
            self.ground.log_path().to_path_buf(),
            self.ground.transcript_path(),
        ];
        let (mut bridge_status, mut router_status) = (None, None);
        if let Some(link) = self.link.as_mut() {
            for p in [&mut link.bridge, &mut link.router] {
                p.terminate(grace)?;
                files.push(p.log_path().to_path_buf());
            }
            let b = link.bridge_spawn.status_path(&dir);
            let r = link.router_spawn.status_path(&dir);
            bridge_status = ProgramStatus::read(&b)?;
            router_status = ProgramStatus::read(&r)?;
            files.extend([b, r].into_iter().filter(|f| f.exists()));
        }
        // The autopilot must have lived to the end: a death now is still this phase's.
        let alive = self.autopilot.check_running();
        let (mut truth_lines, mut truth_summary) = (Vec::new(), None);
        if let Some(truth) = &self.truth {
            let _ = truth.send("quit");
            truth.terminate(grace)?;
            truth_lines = truth.lines().into_iter().map(|l| l.event).collect();
            truth_summary = truth.summary(Duration::ZERO).ok();
            files.push(truth.log_path().to_path_buf());
            files.push(truth.transcript_path());
        }
        self.autopilot.stop(grace);
        files.extend(self.autopilot.log_path().map(PathBuf::from));
        alive?;
        Ok(SitlReport {
            ground: self.ground.lines(),
            ground_summary,
            ground_exit: status.code(),
            truth: truth_lines,
            truth_summary,
            downlink: self.radio.stats(Direction::Downlink),
            uplink: self.radio.stats(Direction::Uplink),
            bridge_status,
            router_status,
            files,
        })
    }

    fn stop_all(&mut self) {
        let grace = Duration::from_secs(2);
        self.ground.stop(grace);
        if let Some(link) = self.link.as_mut() {
            link.bridge.stop(grace);
            link.router.stop(grace);
        }
        if let Some(t) = &self.truth {
            t.stop(grace);
        }
        self.autopilot.stop(grace);
    }
}

/// Waits for the first line `wanted` picks out, checking every [`POLL`] that the autopilot
/// still runs (a dead SITL is named, with its log, rather than waited out).
fn wait_alive<E: crate::driver::fixture::FixtureOutput, S: Clone + Send + 'static>(
    autopilot: &mut Autopilot,
    fixture: &Fixture<E, S>,
    what: &str,
    wanted: impl Fn(&E) -> bool,
) -> Result<()> {
    let deadline = Instant::now() + CONNECT_TIMEOUT;
    loop {
        autopilot.check_running()?;
        match fixture.wait_for(what, POLL, |l| wanted(&l.event)) {
            Ok(_) => return Ok(()),
            Err(FixtureError::Timeout { .. }) if Instant::now() < deadline => {}
            Err(e) => return Err(e.into()),
        }
    }
}
