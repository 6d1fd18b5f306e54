//! Brings up MultiRX with everything around it for one scenario: ports (pty
//! pairs or the bench's adapters), the receiver fixtures, the device itself
//! (emulated) and the monitors on its flight-controller and status lines.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use multirx_core::boot::ResetCause;
use serialport::TTYPort;

use super::MULTIRX_EMU;
use super::rigfile::{DeviceSetup, Mode, MultirxSection};
use crate::clock::Mono;
use crate::driver::process::Process;
use crate::driver::pty::{PtyLink, PtyPair};
use crate::multirx::boot_check;
use crate::multirx::driver::fc::FcMonitor;
use crate::multirx::driver::probe::ProbeDriver;
use crate::multirx::driver::receiver::{Loss, ReceiverFixture, ReceiverSpec};
use crate::multirx::driver::status::StatusMonitor;
use crate::multirx::driver::tx_probe;
use crate::multirx::px4_rc_input::{FcFrame, Px4RcInput, RcReport};
use crate::rigfile::{PortSpec, RigFile};

/// Raw stick value pilot `rx` holds on channels 1–4, distinct per pilot so the
/// flight controller side can tell whose sticks it is getting.
pub fn pilot_stick(rx: u8) -> u16 {
    400 + 200 * u16::from(rx)
}

/// Flight-mode switch position pilots use for manual (position) flight.
pub const POSITION_MODE: u16 = 992;

/// What a scenario wants from its receivers.
#[derive(Debug, Clone, Copy)]
pub struct SessionOptions {
    pub loss: Loss,
}

impl Default for SessionOptions {
    fn default() -> Self {
        SessionOptions {
            loss: Loss::Failsafe,
        }
    }
}

/// MultiRX up and wired for one scenario.
pub struct MultirxSession {
    pub mode: Mode,
    /// The device's configuration, as loaded from the rig's config file.
    pub config: multirx_core::Config,
    pub receivers: Arc<Vec<ReceiverFixture>>,
    /// The independent fail-safe system, when the config names IFS channels.
    pub ifs: Option<ReceiverFixture>,
    pub fc: FcMonitor,
    pub status: StatusMonitor,
    /// The device's boot line, checked against the rig file at start.
    pub boot: Option<multirx_core::BootReport>,
    /// When the session was up.
    pub started: Mono,
    /// Start of the window the session's figures judge: when the session was up, or the
    /// first frame after a [`MultirxSession::reset_device`] (a reset's gap is the
    /// scenario's to judge, by its own limits).
    judged_from: Mutex<Mono>,
    /// End of the window the last [`MultirxSession::px4_report`] judged;
    /// the capture stops there too, so it shows exactly what was judged.
    judged_until: Mutex<Option<Mono>>,
    /// Where logs of this session go.
    pub log_dir: PathBuf,
    /// The emulated device: how it is started, the running program, the files of every
    /// run (a reset starts another).
    emulator: Option<Emulator>,
    /// The board's probe, for a reset.
    probe: Option<ProbeDriver>,
    /// The emulated wires into the device: receivers in order, then IFS.
    links: Vec<PtyLink>,
    _ptys: Vec<PtyPair>,
}

impl MultirxSession {
    /// Brings MultiRX up in `mode` as `rig` describes, logging into `log_dir`: the wiring,
    /// the receiver fixtures (first, so they hear the device's first power events), the
    /// monitors of its FC and status lines, the device itself if emulated; then waits for its
    /// output and checks its boot line against the rig file's config.
    pub fn start(
        rig: &RigFile,
        mode: Mode,
        options: SessionOptions,
        log_dir: &Path,
    ) -> Result<Self> {
        let section = rig
            .devices
            .multirx
            .as_ref()
            .context("the rig file has no [multirx] section")?;
        let loaded = section.config(mode).with_context(|| {
            format!("no MultiRX config for mode {mode} in [multirx.device.configs]")
        })?;
        let config = loaded.config.clone();
        std::fs::create_dir_all(log_dir)?;
        let emulated = matches!(section.device.setup, DeviceSetup::Emulated { .. });
        let wiring = Wiring::new(section, &config, log_dir, emulated)?;

        let receivers = Arc::new(
            wiring
                .receivers
                .iter()
                .enumerate()
                .map(|(i, port)| {
                    start_receiver(
                        rig,
                        &receiver_spec(section, &config, options, i, port),
                        log_dir,
                    )
                })
                .collect::<Result<Vec<_>>>()?,
        );
        let ifs = match &wiring.ifs {
            Some(port) => Some(start_receiver(rig, &ifs_spec(section, port), log_dir)?),
            None => None,
        };
        let hook_receivers = receivers.clone();
        let status = StatusMonitor::start(
            wiring.status,
            Box::new(move |rx, on| {
                if let Some(r) = hook_receivers.get(usize::from(rx)) {
                    let _ = r.send(if on { "power on" } else { "power off" });
                }
            }),
        )?;
        let fc = FcMonitor::start(wiring.fc)?;
        let (emulator, probe) = match &section.device.setup {
            DeviceSetup::Emulated { program } => {
                let launch = EmulatorLaunch {
                    program: program.clone(),
                    config: loaded.path.clone(),
                    ends: wiring.device_ends,
                    log_dir: log_dir.to_path_buf(),
                };
                (Some(Emulator::start(launch)?), None)
            }
            DeviceSetup::Board(board) => (
                None,
                Some(ProbeDriver {
                    selector: board.probe.clone(),
                    chip: board.chip.clone(),
                }),
            ),
        };

        // Once the device runs (the emulated one has been up 50 ms): the session is judged
        // from here, not from its start-up.
        let started = Mono::now();
        let mut session = MultirxSession {
            mode,
            config,
            receivers,
            ifs,
            fc,
            status,
            boot: None,
            started,
            judged_from: Mutex::new(started),
            judged_until: Mutex::new(None),
            log_dir: log_dir.to_path_buf(),
            emulator,
            probe,
            links: wiring.links,
            _ptys: wiring.ptys,
        };
        session.identify(&section.device.setup, &loaded.path)?;
        Ok(session)
    }

    /// Waits for the device's output at the flight controller, then checks it is the device
    /// the rig file names: its boot line carries the image's build id and the config's hash.
    fn identify(&mut self, setup: &DeviceSetup, config_path: &Path) -> Result<()> {
        self.fc.wait_for(
            self.started,
            Duration::from_secs(5),
            "MultiRX output",
            |_| true,
        )?;
        let expected = match setup {
            DeviceSetup::Emulated { .. } => boot_check::Expected::emulated(&self.config),
            DeviceSetup::Board(board) => {
                boot_check::Expected::board(&self.config, &board.firmware, config_path)
                    .with_context(|| {
                        format!(
                            "cannot hash the firmware's inputs in {} to know which image the board must run",
                            board.firmware.display()
                        )
                    })?
            }
        };
        let seen = self.status.wait_for_boot(boot_check::BOOT_LINE_TIMEOUT);
        let boot = boot_check::check(seen, &expected, config_path)?;
        tracing::info!(
            build = format!("{:016x}", boot.build_id),
            config = format!("{:016x}", boot.config_hash),
            reset = boot.reset.name(),
            first_frame_ms = boot.first_frame.as_secs_f64() * 1000.0,
            "MultiRX identified"
        );
        self.boot = Some(boot);
        Ok(())
    }

    /// Unplugs receiver `rx`'s wire into the device for `down` and plugs a new one in
    /// under the same stable name (a USB adapter pulled and put back); returns when it is
    /// back. Emulated rigs only: a bench's wires are real.
    pub fn replug_receiver(&self, rx: u8, down: Duration) -> Result<Mono> {
        let link = self.links.get(usize::from(rx)).with_context(|| {
            format!(
                "receiver {rx} has no emulated wire to replug (a bench rig, or no such receiver)"
            )
        })?;
        link.replug_output(down)
    }

    pub fn receiver(&self, rx: u8) -> &ReceiverFixture {
        &self.receivers[usize::from(rx)]
    }

    pub fn pilot_value(&self, rx: u8) -> u16 {
        self.config.pilot_values[usize::from(rx)]
    }

    /// 0-based pilot channel index into `FcFrame::channels`.
    pub fn pilot_index(&self) -> usize {
        usize::from(self.config.pilot_channel)
    }

    /// 0-based flight-mode channel index.
    pub fn mode_index(&self) -> usize {
        usize::from(self.config.flight_mode_channel)
    }

    /// Whether `frame` shows pilot `rx` in control: its pilot-channel value and its sticks.
    pub fn shows_pilot(&self, frame: &FcFrame, rx: u8) -> bool {
        frame.channels[self.pilot_index()] == self.pilot_value(rx)
            && frame.channels[0] == pilot_stick(rx)
    }

    /// Whether `frame` shows nobody in control: neutral sticks, the flight-mode channel at
    /// auto-loiter and the pilot channel at "none".
    pub fn shows_loiter(&self, frame: &FcFrame) -> bool {
        let c = &self.config;
        frame.channels[self.mode_index()] == c.auto_loiter_value
            && frame.channels[self.pilot_index()] == c.no_receiver_value
            && frame.channels[..4] == c.neutral[..4]
    }

    /// The longest a scenario may wait for MultiRX to give control to a pilot.
    pub fn acquire_timeout(&self) -> Duration {
        let c = &self.config;
        let scan = match self.mode {
            Mode::Parallel => Duration::ZERO,
            Mode::Scan => Duration::from_micros(c.scan_window.as_micros() * u64::from(c.receivers)),
        };
        scan + Duration::from_secs(3)
    }

    /// Turns pilot `rx`'s transmitter on and waits until the flight controller shows it in control.
    pub fn fly(&self, rx: u8) -> Result<FcFrame> {
        let since = Mono::now();
        self.receiver(rx).set_tx(true)?;
        self.fc.wait_for(
            since,
            self.acquire_timeout(),
            &format!("pilot {rx} in control"),
            |f| self.shows_pilot(f, rx),
        )
    }

    /// The device's cadence from its TX probe (device time: see
    /// [`tx_probe`]), over the window the last [`Self::px4_report`] judged;
    /// `None` without a probe (a board: there the flight-controller side is
    /// all we see).
    pub fn device_cadence(&self) -> Result<Option<tx_probe::Cadence>> {
        let Some(emulator) = &self.emulator else {
            return Ok(None);
        };
        let path = emulator.tx_log();
        let until = self.judged_until.lock().unwrap().unwrap_or_else(Mono::now);
        let from = *self.judged_from.lock().unwrap();
        let lines = tx_probe::read_past(&path, until, std::time::Duration::from_millis(500))?;
        Ok(Some(tx_probe::cadence(&lines, from, until)))
    }

    /// PX4's view of the whole session so far (since the last reset, if any).
    pub fn px4_report(&self) -> RcReport {
        let until = Mono::now();
        *self.judged_until.lock().unwrap() = Some(until);
        self.px4_replay(*self.judged_from.lock().unwrap(), until)
    }

    /// PX4's view of the output between `from` and `until`.
    pub fn px4_replay(&self, from: Mono, until: Mono) -> RcReport {
        Px4RcInput {
            mode_channel: self.config.flight_mode_channel + 1,
        }
        .replay(&self.fc.frames(), from, until)
    }

    /// Resets the device as a panic would, in flight: a board through its probe (a system
    /// reset request); an emulated device is killed, every receiver it powered switched off
    /// (a reset floats the power switches' gates, which their pull-downs turn off: see
    /// `firmware/multirx/samd21/src/board.rs`) and the program started again, reporting a
    /// `software` reset. Returns when the reset happened, and judges the session's figures
    /// from `judge_from` on (the first frame after the reset, which the caller waits for).
    pub fn reset_device(&self) -> Result<Mono> {
        if let Some(emulator) = &self.emulator {
            let reset = emulator.reset(|| {
                for r in self.receivers.iter() {
                    // A receiver already off ignores it.
                    let _ = r.send("power off");
                }
            })?;
            return Ok(reset);
        }
        let probe = self
            .probe
            .as_ref()
            .context("neither an emulated device nor a board's probe to reset")?;
        let name = probe.reset()?;
        let reset = Mono::now();
        tracing::info!(probe = %name, "MultiRX board reset through its probe");
        Ok(reset)
    }

    /// The session's figures judge from `from` on (see [`Self::reset_device`]).
    pub fn judge_from(&self, from: Mono) {
        *self.judged_from.lock().unwrap() = from;
    }

    /// The first boot line read after `after` reporting `cause`, waiting up to `timeout`.
    pub fn boot_after(
        &self,
        after: Mono,
        cause: ResetCause,
        timeout: Duration,
    ) -> Option<multirx_core::BootReport> {
        self.status
            .wait_for_boot_after(after, timeout, |b| b.reset == cause)
    }

    /// Writes every frame the flight controller saw as CSV (evidence, and
    /// the data behind the gap and handover figures).
    fn write_capture(&self) -> std::io::Result<PathBuf> {
        use std::io::Write;
        let path = self.log_dir.join("fc-frames.csv");
        let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
        writeln!(out, "t_ms,gap_ms,pilot,ch1,flight_mode,frame_lost,failsafe")?;
        let mut last = self.started;
        let until = self.judged_until.lock().unwrap().unwrap_or_else(Mono::now);
        for f in self
            .fc
            .frames()
            .iter()
            .filter(|f| f.at >= self.started && f.at <= until)
        {
            writeln!(
                out,
                "{:.3},{:.3},{},{},{},{},{}",
                f.at.ms_since(self.started),
                f.at.ms_since(last),
                f.channels[self.pilot_index()],
                f.channels[0],
                f.channels[self.mode_index()],
                u8::from(f.frame_lost),
                u8::from(f.failsafe)
            )?;
            last = f.at;
        }
        out.flush()?;
        Ok(path)
    }

    /// Writes every status line the device sent (power, link, control, overflow, boot) with
    /// when the rig read it: what the device decided, next to what the flight controller saw.
    fn write_status_events(&self) -> std::io::Result<PathBuf> {
        use std::io::Write;
        let path = self.log_dir.join("status-events.txt");
        let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
        writeln!(out, "# rig_t_ms  status line (device micros first)")?;
        for (at, event) in self.status.events() {
            writeln!(out, "{:.3}  {event}", at.ms_since(self.started))?;
        }
        out.flush()?;
        Ok(path)
    }

    /// Stops everything; returns the log and capture files written.
    pub fn finish(mut self) -> Vec<PathBuf> {
        let mut logs: Vec<PathBuf> = self
            .receivers
            .iter()
            .map(|r| {
                r.stop();
                r.log_path()
            })
            .collect();
        if let Some(ifs) = &self.ifs {
            ifs.stop();
            logs.push(ifs.log_path());
        }
        if let Some(emulator) = self.emulator.take() {
            logs.extend(emulator.stop());
        }
        self.fc.stop();
        self.status.stop();
        match self.write_capture() {
            Ok(path) => logs.push(path),
            Err(e) => tracing::warn!(error = %e, "flight-controller capture not written"),
        }
        match self.write_status_events() {
            Ok(path) => logs.push(path),
            Err(e) => tracing::warn!(error = %e, "status events not written"),
        }
        logs
    }
}

/// The serial lines between the rig and the device, made (pty pairs) or opened (a bench's
/// adapters) as the rig file says.
struct Wiring {
    /// The rig's end of the flight-controller line.
    fc: TTYPort,
    /// The rig's end of the status line.
    status: TTYPort,
    /// The ports the receiver fixtures write to, in receiver order.
    receivers: Vec<String>,
    /// The port the IFS fixture writes to, when the config names IFS channels and the rig
    /// wires one.
    ifs: Option<String>,
    /// What an emulated device opens.
    device_ends: DeviceEnds,
    /// The emulated wires into the device: receivers in order, then IFS.
    links: Vec<PtyLink>,
    ptys: Vec<PtyPair>,
}

/// The paths an emulated device opens: its end of each line.
#[derive(Default)]
struct DeviceEnds {
    fc: String,
    status: String,
    receivers: Vec<String>,
    ifs: Option<String>,
}

impl Wiring {
    fn new(
        section: &MultirxSection,
        config: &multirx_core::Config,
        log_dir: &Path,
        emulated: bool,
    ) -> Result<Wiring> {
        let mut ptys = Vec::new();
        let mut links = Vec::new();
        let mut device_ends = DeviceEnds::default();

        // Lines the rig reads: flight controller and status.
        let mut rig_side = |name: &str, spec: &PortSpec| -> Result<(TTYPort, String)> {
            match spec {
                PortSpec::Pty => {
                    let mut pair = PtyPair::new()?;
                    let master = pair.take_master()?;
                    let path = pair.path().to_string();
                    ptys.push(pair);
                    Ok((master, path))
                }
                PortSpec::Path(path) if !emulated => {
                    let port = hostio::sbus::port(&path.to_string_lossy())
                        .open_native()
                        .with_context(|| format!("cannot open {name} port {}", path.display()))?;
                    Ok((port, String::new()))
                }
                PortSpec::Path(path) => bail!(
                    "multirx.ports.{name} = \"{}\": an emulated device is wired with \"pty\" \
                     ports; device paths are for kind = \"board\"",
                    path.display()
                ),
            }
        };
        let (fc, fc_end) = rig_side("fc", &section.ports.fc)?;
        let (status, status_end) = rig_side("status", &section.ports.status)?;
        device_ends.fc = fc_end;
        device_ends.status = status_end;

        // Lines fixtures write into the device: receivers and IFS; the fixture's end and the
        // device's.
        let mut fixture_port = |name: &str, spec: &PortSpec| -> Result<(String, String)> {
            match spec {
                PortSpec::Pty => {
                    // The device opens a stable name, as a bench's /dev/serial/by-id: a
                    // receiver can be unplugged and plugged in again under it.
                    let link =
                        PtyLink::with_stable_output(name, &log_dir.join(format!("{name}-device")))?;
                    let ends = (link.input_path().to_string(), link.output_path());
                    links.push(link);
                    Ok(ends)
                }
                PortSpec::Path(path) if !emulated => {
                    Ok((path.to_string_lossy().into_owned(), String::new()))
                }
                PortSpec::Path(path) => bail!(
                    "multirx.ports.{name} = \"{}\": an emulated device is wired with \"pty\" ports",
                    path.display()
                ),
            }
        };
        let mut receivers = Vec::new();
        for (i, spec) in section.ports.receivers.iter().enumerate() {
            let (fixture, device) = fixture_port(&format!("rx{i}"), spec)?;
            receivers.push(fixture);
            device_ends.receivers.push(device);
        }
        let ifs = match (&section.ports.ifs, config.ifs_channels.is_empty()) {
            (Some(spec), false) => {
                let (fixture, device) = fixture_port("ifs", spec)?;
                device_ends.ifs = Some(device);
                Some(fixture)
            }
            _ => None,
        };
        Ok(Wiring {
            fc,
            status,
            receivers,
            ifs,
            device_ends,
            links,
            ptys,
        })
    }
}

/// Pilot `i`'s receiver on `port`: its own stick values on channels 1–4 and the flight-mode
/// channel at auto-loiter, powered off until the device powers it.
fn receiver_spec(
    section: &MultirxSection,
    config: &multirx_core::Config,
    options: SessionOptions,
    i: usize,
    port: &str,
) -> ReceiverSpec {
    let stick = pilot_stick(i as u8);
    let fm = config.flight_mode_channel + 1;
    ReceiverSpec {
        name: format!("rx{i}"),
        port: port.to_owned(),
        period_ms: section.receivers.period_ms,
        boot_ms: section.receivers.boot_ms,
        boot_jitter_ms: section.receivers.period_ms,
        loss: options.loss,
        powered: false,
        channels: vec![
            (1, stick),
            (2, stick),
            (3, stick),
            (4, stick),
            (fm, config.auto_loiter_value),
        ],
    }
}

/// The independent fail-safe system on `port`: always powered, sending nothing until told.
fn ifs_spec(section: &MultirxSection, port: &str) -> ReceiverSpec {
    ReceiverSpec {
        name: "ifs".into(),
        port: port.to_owned(),
        period_ms: section.receivers.period_ms,
        boot_ms: 0,
        boot_jitter_ms: section.receivers.period_ms,
        loss: Loss::Silent,
        powered: true,
        channels: vec![],
    }
}

/// Starts `fixtures/sbus_receiver.py` as `spec` says.
fn start_receiver(rig: &RigFile, spec: &ReceiverSpec, log_dir: &Path) -> Result<ReceiverFixture> {
    let script = rig.fixtures.dir.join("sbus_receiver.py");
    Ok(ReceiverFixture::start(
        &rig.fixtures.python,
        &script,
        spec,
        log_dir,
    )?)
}

/// How the emulated device is started: `program` (else `multirx-emu` next to the rig) with
/// the config at `config` on its ends of the lines.
struct EmulatorLaunch {
    program: Option<PathBuf>,
    config: PathBuf,
    ends: DeviceEnds,
    log_dir: PathBuf,
}

/// One run of the emulated device's program: its process and files. The first run's files
/// have the plain names; a run after a reset has `.reset-<n>` before the extension.
struct EmulatorRun {
    process: Process,
    /// Its TX probe (see `multirx-emu --tx-log`).
    tx_log: PathBuf,
    /// Its status lines (`--status-json`).
    status: PathBuf,
}

/// The emulated device across resets.
struct Emulator {
    launch: EmulatorLaunch,
    current: Mutex<Option<EmulatorRun>>,
    /// Files of runs a reset ended.
    ended: Mutex<Vec<PathBuf>>,
    runs: std::sync::atomic::AtomicUsize,
}

impl Emulator {
    fn start(launch: EmulatorLaunch) -> Result<Emulator> {
        let first = launch.spawn(0, ResetCause::Host)?;
        Ok(Emulator {
            launch,
            current: Mutex::new(Some(first)),
            ended: Mutex::new(Vec::new()),
            runs: std::sync::atomic::AtomicUsize::new(1),
        })
    }

    /// The TX probe of the run in progress.
    fn tx_log(&self) -> PathBuf {
        let current = self.current.lock().unwrap();
        match &*current {
            Some(run) => run.tx_log.clone(),
            None => self.launch.log_dir.join(TX_LOG),
        }
    }

    /// Kills the running program (a reset stops the chip at once), calls `power_off` (what
    /// the reset does to the receivers) and starts the program again; returns the kill's time.
    fn reset(&self, power_off: impl FnOnce()) -> Result<Mono> {
        let mut current = self.current.lock().unwrap();
        let mut run = current
            .take()
            .context("the emulated device is not running")?;
        let reset = Mono::now();
        run.process.kill();
        power_off();
        self.ended.lock().unwrap().extend(run.files());
        let n = self.runs.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        *current = Some(self.launch.spawn(n, ResetCause::Software)?);
        Ok(reset)
    }

    /// Stops the program; returns every run's files that exist.
    fn stop(self) -> Vec<PathBuf> {
        let mut files = self.ended.into_inner().unwrap();
        if let Some(mut run) = self.current.into_inner().unwrap() {
            run.process.stop(Duration::from_secs(2));
            files.extend(run.files());
        }
        files.retain(|p| p.exists());
        files
    }
}

impl EmulatorRun {
    fn files(&self) -> [PathBuf; 3] {
        [
            self.process.log_path().to_path_buf(),
            self.status.clone(),
            self.tx_log.clone(),
        ]
    }
}

impl EmulatorLaunch {
    /// Starts run `n` reporting `reset` on its boot line; fails if it exits at once.
    fn spawn(&self, n: usize, reset: ResetCause) -> Result<EmulatorRun> {
        let program = match &self.program {
            Some(p) => p.clone(),
            None => MULTIRX_EMU
                .find()
                .map_err(|e| anyhow::anyhow!("{e}, or set program in [multirx.device]"))?,
        };
        let file = |name: &str| {
            let name = match (n, name.split_once('.')) {
                (0, _) | (_, None) => name.to_owned(),
                (n, Some((stem, ext))) => format!("{stem}.reset-{n}.{ext}"),
            };
            self.log_dir.join(name)
        };
        let (tx_log, status) = (file(TX_LOG), file(EMU_STATUS));
        let ends = &self.ends;
        let mut command = Command::new(&program);
        command.arg("--config").arg(&self.config);
        for path in &ends.receivers {
            command.args(["--rx", path]);
        }
        command.args(["--fc", &ends.fc, "--status", &ends.status]);
        if let Some(ifs) = &ends.ifs {
            command.args(["--ifs", ifs]);
        }
        command.arg("--tx-log").arg(&tx_log);
        // Its counters as data, kept with the phase's evidence.
        command.arg("--status-json").arg(&status);
        command.args(["--reset-cause", reset.name()]);
        let mut process = Process::spawn("multirx-emu", command, &file("multirx-emu.log"))?;
        std::thread::sleep(Duration::from_millis(50));
        process.check_running()?;
        Ok(EmulatorRun {
            process,
            tx_log,
            status,
        })
    }
}

/// The emulated device's TX probe file, in the session's log folder.
const TX_LOG: &str = "multirx-tx.log";
/// The emulated device's status file (`--status-json`), in the session's log folder.
const EMU_STATUS: &str = "multirx-emu.status.jsonl";
