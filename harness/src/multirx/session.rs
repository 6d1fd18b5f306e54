//! Brings up MultiRX with everything around it for one scenario: ports (pty
//! pairs or the bench's adapters), the receiver fixtures, the device itself
//! (emulated) and the monitors on its flight-controller and status lines.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use serialport::TTYPort;

use super::MULTIRX_EMU;
use super::rigfile::{DeviceSetup, Mode};
use crate::clock::Mono;
use crate::driver::process::Process;
use crate::driver::pty::{PtyLink, PtyPair};
use crate::multirx::boot_check;
use crate::multirx::driver::fc::FcMonitor;
use crate::multirx::driver::receiver::{Loss, ReceiverFixture, ReceiverSpec};
use crate::multirx::driver::status::StatusMonitor;
use crate::multirx::driver::tx_probe;
use crate::multirx::px4_rc_input::{FcFrame, Px4RcInput, RcReport};
use crate::rigfile::{PortSpec, RigFile};
use multirx_core::boot::ImageKind;

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
    /// End of the window the last [`MultirxSession::px4_report`] judged;
    /// the capture stops there too, so it shows exactly what was judged.
    judged_until: std::sync::Mutex<Option<Mono>>,
    /// Where logs of this session go.
    pub log_dir: PathBuf,
    device: Option<Process>,
    /// The emulated device's TX probe (see `multirx-emu --tx-log`).
    tx_log: Option<PathBuf>,
    /// The emulated wires into the device: receivers in order, then IFS.
    links: Vec<PtyLink>,
    _ptys: Vec<PtyPair>,
}

impl MultirxSession {
    /// Brings MultiRX up in `mode` as `rig` describes, logging into `log_dir`.
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
        let mut ptys = Vec::new();
        let mut links = Vec::new();

        // Lines the rig reads: flight controller and status.
        let mut rig_side = |name: &str, spec: &PortSpec| -> Result<(TTYPort, Option<String>)> {
            match spec {
                PortSpec::Pty => {
                    let mut pair = PtyPair::new()?;
                    let master = pair.take_master()?;
                    let path = pair.path().to_string();
                    ptys.push(pair);
                    Ok((master, Some(path)))
                }
                PortSpec::Path(path) if !emulated => {
                    let port = hostio::sbus::port(&path.to_string_lossy())
                        .open_native()
                        .with_context(|| format!("cannot open {name} port {}", path.display()))?;
                    Ok((port, None))
                }
                PortSpec::Path(path) => bail!(
                    "multirx.ports.{name} = \"{}\": an emulated device is wired with \"pty\" ports; device paths are for kind = \"board\"",
                    path.display()
                ),
            }
        };
        let (fc_port, fc_device_path) = rig_side("fc", &section.ports.fc)?;
        let (status_port, status_device_path) = rig_side("status", &section.ports.status)?;

        // Lines fixtures write into the device: receivers and IFS.
        let mut device_inputs = Vec::new();
        let mut fixture_port = |name: &str, spec: &PortSpec| -> Result<String> {
            match spec {
                PortSpec::Pty => {
                    // The device opens a stable name, as a bench's /dev/serial/by-id: a
                    // receiver can be unplugged and plugged in again under it.
                    let link =
                        PtyLink::with_stable_output(name, &log_dir.join(format!("{name}-device")))?;
                    let fixture_end = link.input_path().to_string();
                    device_inputs.push(link.output_path());
                    links.push(link);
                    Ok(fixture_end)
                }
                PortSpec::Path(path) if !emulated => Ok(path.to_string_lossy().into_owned()),
                PortSpec::Path(path) => bail!(
                    "multirx.ports.{name} = \"{}\": an emulated device is wired with \"pty\" ports",
                    path.display()
                ),
            }
        };
        let receiver_ports = section
            .ports
            .receivers
            .iter()
            .enumerate()
            .map(|(i, spec)| fixture_port(&format!("rx{i}"), spec))
            .collect::<Result<Vec<_>>>()?;
        let ifs_port = match (&section.ports.ifs, config.ifs_channels.is_empty()) {
            (Some(spec), false) => Some(fixture_port("ifs", spec)?),
            _ => None,
        };

        // Fixtures first, so they hear the device's first power events.
        let script = rig.fixtures.dir.join("sbus_receiver.py");
        let fm = config.flight_mode_channel + 1;
        let receivers = receiver_ports
            .iter()
            .enumerate()
            .map(|(i, port)| -> Result<ReceiverFixture> {
                let stick = pilot_stick(i as u8);
                let spec = ReceiverSpec {
                    name: format!("rx{i}"),
                    port: port.clone(),
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
                };
                Ok(ReceiverFixture::start(
                    &rig.fixtures.python,
                    &script,
                    &spec,
                    log_dir,
                )?)
            })
            .collect::<Result<Vec<_>>>()?;
        let receivers = Arc::new(receivers);
        let ifs = match ifs_port {
            Some(port) => {
                let spec = ReceiverSpec {
                    name: "ifs".into(),
                    port,
                    period_ms: section.receivers.period_ms,
                    boot_ms: 0,
                    boot_jitter_ms: section.receivers.period_ms,
                    loss: Loss::Silent,
                    powered: true,
                    channels: vec![],
                };
                Some(ReceiverFixture::start(
                    &rig.fixtures.python,
                    &script,
                    &spec,
                    log_dir,
                )?)
            }
            None => None,
        };

        let hook_receivers = receivers.clone();
        let status = StatusMonitor::start(
            status_port,
            Box::new(move |rx, on| {
                if let Some(r) = hook_receivers.get(usize::from(rx)) {
                    let _ = r.send(if on { "power on" } else { "power off" });
                }
            }),
        )?;
        let fc = FcMonitor::start(fc_port)?;

        let device = match &section.device.setup {
            DeviceSetup::Emulated { program } => {
                let program = match program {
                    Some(p) => p.clone(),
                    None => MULTIRX_EMU
                        .find()
                        .map_err(|e| anyhow::anyhow!("{e}, or set program in [multirx.device]"))?,
                };
                let mut command = Command::new(&program);
                command.arg("--config").arg(&loaded.path);
                for path in &device_inputs[..receiver_ports.len()] {
                    command.args(["--rx", path]);
                }
                command.args(["--fc", fc_device_path.as_deref().unwrap_or_default()]);
                command.args([
                    "--status",
                    status_device_path.as_deref().unwrap_or_default(),
                ]);
                if ifs.is_some() {
                    command.args(["--ifs", &device_inputs[receiver_ports.len()]]);
                }
                command.arg("--tx-log").arg(log_dir.join(TX_LOG));
                // Its counters as data, kept with the phase's evidence.
                command.arg("--status-json").arg(log_dir.join(EMU_STATUS));
                let mut process =
                    Process::spawn("multirx-emu", command, &log_dir.join("multirx-emu.log"))?;
                std::thread::sleep(Duration::from_millis(50));
                process.check_running()?;
                Some(process)
            }
            DeviceSetup::Board(_) => None,
        };

        let mut session = MultirxSession {
            mode,
            config,
            receivers,
            ifs,
            fc,
            status,
            boot: None,
            started: Mono::now(),
            judged_until: std::sync::Mutex::new(None),
            log_dir: log_dir.to_path_buf(),
            tx_log: device.as_ref().map(|_| log_dir.join(TX_LOG)),
            device,
            links,
            _ptys: ptys,
        };
        // The device is up when its output reaches the flight controller.
        session.fc.wait_for(
            session.started,
            Duration::from_secs(5),
            "MultiRX output",
            |_| true,
        )?;
        // ...and it is the device the rig file names: its boot line carries
        // the image's build id and the config's hash.
        let kind = if emulated {
            ImageKind::Emulated
        } else {
            ImageKind::Samd21
        };
        let expected = boot_check::Expected::new(kind, &session.config);
        let seen = session.status.wait_for_boot(boot_check::BOOT_LINE_TIMEOUT);
        let boot = boot_check::check(seen, &expected, &loaded.path)?;
        tracing::info!(
            build = format!("{:016x}", boot.build_id),
            config = format!("{:016x}", boot.config_hash),
            reset = boot.reset.name(),
            first_frame_ms = boot.first_frame.as_secs_f64() * 1000.0,
            "MultiRX identified"
        );
        session.boot = Some(boot);
        Ok(session)
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
        let Some(path) = &self.tx_log else {
            return Ok(None);
        };
        let until = self.judged_until.lock().unwrap().unwrap_or_else(Mono::now);
        let lines = tx_probe::read_past(path, until, std::time::Duration::from_millis(500))?;
        Ok(Some(tx_probe::cadence(&lines, self.started, until)))
    }

    /// PX4's view of the whole session so far.
    pub fn px4_report(&self) -> RcReport {
        let frames = self.fc.frames();
        let until = Mono::now();
        *self.judged_until.lock().unwrap() = Some(until);
        Px4RcInput {
            mode_channel: self.config.flight_mode_channel + 1,
        }
        .replay(&frames, self.started, until)
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
        if let Some(mut device) = self.device.take() {
            device.stop(Duration::from_secs(2));
            logs.push(device.log_path().to_path_buf());
            let status = self.log_dir.join(EMU_STATUS);
            if status.exists() {
                logs.push(status);
            }
        }
        logs.extend(self.tx_log.clone().filter(|p| p.exists()));
        self.fc.stop();
        self.status.stop();
        match self.write_capture() {
            Ok(path) => logs.push(path),
            Err(e) => tracing::warn!(error = %e, "flight-controller capture not written"),
        }
        logs
    }
}

/// The emulated device's TX probe file, in the session's log folder.
const TX_LOG: &str = "multirx-tx.log";
/// The emulated device's status file (`--status-json`), in the session's log folder.
const EMU_STATUS: &str = "multirx-emu.status.jsonl";
