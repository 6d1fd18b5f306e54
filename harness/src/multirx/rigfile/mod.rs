//! `[multirx]`: the MultiRX device under test and how the rig is wired to it.
//!
//! Each MultiRX config the section names is read and checked once, at load
//! ([`LoadedConfig`]: its mode, its receivers against the ports, and for a board
//! [`multirx_core::board::SAMD21_UARTS`] and its throttle channel's neutral, named
//! explicitly: [`multirx_core::Config::from_toml_for_bench`]).

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::rigfile::{Checker, PortSpec, RigFileError, dotted};

/// Firmware crate of a board rig that names none, relative to the rig file.
pub const DEFAULT_FIRMWARE_DIR: &str = "../firmware/multirx/samd21";
/// Chip flashed when a board rig names none.
pub const DEFAULT_CHIP: &str = "ATSAMD21G18A";
/// Most receivers a MultiRX has inputs for (the core's number).
pub const MAX_RECEIVERS: usize = multirx_core::config::MAX_RECEIVERS;
/// Longest receiver boot silence accepted, in milliseconds.
pub const MAX_BOOT_MS: u32 = 5000;

/// `[multirx]`: the MultiRX device and how the rig is wired to it.
#[derive(Debug, Clone, PartialEq)]
pub struct MultirxSection {
    /// Mode suites to run, in file order, without duplicates.
    pub modes: Vec<Mode>,
    /// `[multirx.device]`.
    pub device: DeviceSection,
    /// `[multirx.ports]`.
    pub ports: PortsSection,
    /// `[multirx.receivers]`.
    pub receivers: ReceiversSection,
}

impl MultirxSection {
    /// The MultiRX config for `mode`; present for every mode in
    /// [`MultirxSection::modes`].
    pub fn config(&self, mode: Mode) -> Option<&LoadedConfig> {
        self.device.configs.get(&mode)
    }

    /// The config files it names, to keep with evidence: `multirx-<mode>.toml` and where each
    /// is.
    pub fn input_files(&self) -> Vec<(String, PathBuf)> {
        self.device
            .configs
            .iter()
            .map(|(mode, loaded)| (format!("multirx-{mode}.toml"), loaded.path.clone()))
            .collect()
    }
}

/// A MultiRX config file, read and checked when the rig file was loaded:
/// everything in the rig uses this, none reads the file again (the emulated
/// device and the firmware build are handed `path`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LoadedConfig {
    /// Absolute path of the file.
    pub path: PathBuf,
    pub config: multirx_core::Config,
}

/// MultiRX operating mode (the core's); each has its own scenario suite and config file.
pub use multirx_core::Mode;

/// What the MultiRX under test is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DeviceKind {
    /// The host build of the MultiRX core, started by the rig.
    Emulated,
    /// A SAMD21 board flashed with the firmware, reached over a debug probe.
    Board,
}

impl DeviceKind {
    /// Lower-case name, as in rig files.
    pub fn as_str(self) -> &'static str {
        match self {
            DeviceKind::Emulated => "emulated",
            DeviceKind::Board => "board",
        }
    }
}

impl fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// `[multirx.device]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceSection {
    /// The MultiRX config for each mode.
    pub configs: BTreeMap<Mode, LoadedConfig>,
    /// Kind-specific settings.
    pub setup: DeviceSetup,
}

impl DeviceSection {
    /// Which kind of device this is.
    pub fn kind(&self) -> DeviceKind {
        match self.setup {
            DeviceSetup::Emulated { .. } => DeviceKind::Emulated,
            DeviceSetup::Board(_) => DeviceKind::Board,
        }
    }
}

/// Settings that exist for one device kind only; keys of the other kind are
/// rejected at load, so a bench file cannot half-describe an emulator.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DeviceSetup {
    /// Host program over serial ports.
    Emulated {
        /// Program to start; `None` means `multirx-emu` next to the running
        /// `rig` binary. A bare name is looked up on `PATH`; anything with a
        /// `/` was resolved relative to the rig file.
        program: Option<PathBuf>,
    },
    /// Flashed SAMD21 board.
    Board(BoardSetup),
}

/// How to reach and prepare a MultiRX board.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BoardSetup {
    /// Which debug probe to use.
    pub probe: ProbeSelector,
    /// Chip name as probe-rs knows it.
    pub chip: String,
    /// The firmware crate, built with each mode's config before flashing.
    pub firmware: PathBuf,
    /// Whether to flash the firmware before the run (off by default so a
    /// bench run does not silently replace a certified image).
    pub flash: bool,
}

/// A debug probe: the only one attached, or one by USB id.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ProbeSelector {
    /// The single attached probe (`"auto"`).
    Auto,
    /// `"VID:PID"` or `"VID:PID:SERIAL"`, hex ids, as probe-rs accepts them.
    Usb {
        /// USB vendor id.
        vid: u16,
        /// USB product id.
        pid: u16,
        /// Probe serial number, to tell identical probes apart.
        serial: Option<String>,
    },
}

impl ProbeSelector {
    /// Parses `auto`, `VID:PID` or `VID:PID:SERIAL` (ids in hex).
    pub fn parse(s: &str) -> Result<Self, String> {
        if s == "auto" {
            return Ok(ProbeSelector::Auto);
        }
        let mut parts = s.splitn(3, ':');
        let hex = |p: Option<&str>, what: &str| {
            let p = p.unwrap_or("");
            u16::from_str_radix(p, 16).map_err(|_| {
                format!("{what} `{p}` in \"{s}\" is not a 16-bit hex USB id; expected \"auto\", \"VID:PID\" or \"VID:PID:SERIAL\", e.g. \"2e8a:000c\"")
            })
        };
        let vid = hex(parts.next(), "vendor id")?;
        let pid = hex(parts.next(), "product id")?;
        let serial = match parts.next() {
            None => None,
            Some("") => return Err(format!("empty serial number in \"{s}\"")),
            Some(serial) => Some(serial.to_owned()),
        };
        Ok(ProbeSelector::Usb { vid, pid, serial })
    }
}

/// Renders the selector as probe-rs's `--probe` accepts it.
impl fmt::Display for ProbeSelector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ProbeSelector::Auto => f.write_str("auto"),
            ProbeSelector::Usb { vid, pid, serial } => {
                write!(f, "{vid:04x}:{pid:04x}")?;
                if let Some(s) = serial {
                    write!(f, ":{s}")?;
                }
                Ok(())
            }
        }
    }
}

/// `[multirx.ports]`: where each MultiRX line is reached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PortsSection {
    /// Flight-controller side: where MultiRX's SBUS output is read.
    pub fc: PortSpec,
    /// MultiRX status line (power and active receiver).
    pub status: PortSpec,
    /// Independent fail-safe input into MultiRX, if wired.
    pub ifs: Option<PortSpec>,
    /// One per receiver input, in receiver order (1..=6 entries).
    pub receivers: Vec<PortSpec>,
}

/// `[multirx.receivers]`: how the emulated receivers behave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReceiversSection {
    /// SBUS frame period: 7 (high speed) or 14 (normal) ms.
    pub period_ms: u32,
    /// Silence after power-on before the first frame, 0..=5000 ms.
    pub boot_ms: u32,
}

impl Default for ReceiversSection {
    fn default() -> Self {
        ReceiversSection {
            period_ms: 7,
            boot_ms: 300,
        }
    }
}

// The section as written: serde shapes that mirror the TOML, unknown keys rejected.

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawMultirx {
    pub modes: Option<Vec<Mode>>,
    pub device: RawDevice,
    pub ports: RawPorts,
    #[serde(default)]
    pub receivers: RawReceivers,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDevice {
    pub kind: DeviceKind,
    pub program: Option<String>,
    #[serde(default)]
    pub configs: RawConfigs,
    pub probe: Option<String>,
    pub chip: Option<String>,
    pub flash: Option<bool>,
    pub firmware: Option<PathBuf>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawConfigs {
    pub parallel: Option<PathBuf>,
    pub scan: Option<PathBuf>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawPorts {
    pub fc: PortSpec,
    pub status: PortSpec,
    pub ifs: Option<PortSpec>,
    pub receivers: Vec<PortSpec>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawReceivers {
    pub period_ms: Option<u32>,
    pub boot_ms: Option<u32>,
}

impl Checker<'_> {
    pub(crate) fn multirx(&self, raw: RawMultirx) -> Result<MultirxSection, RigFileError> {
        let modes = match raw.modes {
            None => Mode::ALL.to_vec(),
            Some(modes) => {
                let at = ["multirx", "modes"];
                if modes.is_empty() {
                    return Err(self.invalid(
                        &at,
                        "empty; list \"parallel\" and/or \"scan\", or remove [multirx] to run no MultiRX scenarios",
                    ));
                }
                for (i, m) in modes.iter().enumerate() {
                    if modes[..i].contains(m) {
                        return Err(self.invalid(&at, format!("\"{m}\" is listed twice")));
                    }
                }
                modes
            }
        };

        let d = raw.device;
        let mut config_paths = BTreeMap::new();
        for (mode, p) in [
            (Mode::Parallel, d.configs.parallel),
            (Mode::Scan, d.configs.scan),
        ] {
            if let Some(p) = p {
                config_paths.insert(mode, self.resolve(&p));
            }
        }
        if let Some(mode) = modes.iter().find(|m| !config_paths.contains_key(m)) {
            return Err(self.invalid_named(
                &["multirx", "device", "configs", mode.as_str()],
                format!("multirx.device.configs.{mode}"),
                format!(
                    "mode \"{mode}\" is in multirx.modes but has no MultiRX config file; \
                     add {mode} = \"multirx/{mode}.toml\" under [multirx.device.configs]"
                ),
            ));
        }
        let only_for = |key: &str, kind: DeviceKind| {
            self.invalid(
                &["multirx", "device", key],
                format!(
                    "only for kind = \"{kind}\"; this device is kind = \"{}\"",
                    d.kind
                ),
            )
        };
        let setup = match d.kind {
            DeviceKind::Emulated => {
                for (key, set) in [
                    ("probe", d.probe.is_some()),
                    ("chip", d.chip.is_some()),
                    ("flash", d.flash.is_some()),
                    ("firmware", d.firmware.is_some()),
                ] {
                    if set {
                        return Err(only_for(key, DeviceKind::Board));
                    }
                }
                let program = match d.program.as_deref() {
                    Some("") => {
                        return Err(self.invalid(
                            &["multirx", "device", "program"],
                            "empty; omit it to use multirx-emu next to the rig binary",
                        ));
                    }
                    p => p.map(|p| self.resolve_program(p)),
                };
                DeviceSetup::Emulated { program }
            }
            DeviceKind::Board => {
                if d.program.is_some() {
                    return Err(only_for("program", DeviceKind::Emulated));
                }
                let probe = match d.probe.as_deref() {
                    None => ProbeSelector::Auto,
                    Some(s) => ProbeSelector::parse(s)
                        .map_err(|e| self.invalid(&["multirx", "device", "probe"], e))?,
                };
                let chip = d.chip.unwrap_or_else(|| DEFAULT_CHIP.to_owned());
                if chip.trim().is_empty() {
                    return Err(self.invalid(
                        &["multirx", "device", "chip"],
                        format!("empty; e.g. \"{DEFAULT_CHIP}\""),
                    ));
                }
                let firmware = self.resolve(
                    d.firmware
                        .as_deref()
                        .unwrap_or(Path::new(DEFAULT_FIRMWARE_DIR)),
                );
                DeviceSetup::Board(BoardSetup {
                    probe,
                    chip,
                    flash: d.flash.unwrap_or(false),
                    firmware,
                })
            }
        };

        let ports = self.ports(raw.ports)?;

        let r = raw.receivers;
        let defaults = ReceiversSection::default();
        let period_ms = r.period_ms.unwrap_or(defaults.period_ms);
        if period_ms != 7 && period_ms != 14 {
            return Err(self.invalid(
                &["multirx", "receivers", "period_ms"],
                format!(
                    "{period_ms} ms; SBUS sends a frame every 7 ms (high speed) or 14 ms (normal)"
                ),
            ));
        }
        let boot_ms = r.boot_ms.unwrap_or(defaults.boot_ms);
        if boot_ms > MAX_BOOT_MS {
            return Err(self.invalid(
                &["multirx", "receivers", "boot_ms"],
                format!("{boot_ms} ms is out of range 0..={MAX_BOOT_MS}"),
            ));
        }

        let mut configs = BTreeMap::new();
        for (mode, path) in config_paths {
            let config = self.multirx_config(mode, path, &setup, &ports)?;
            configs.insert(mode, config);
        }

        Ok(MultirxSection {
            modes,
            device: DeviceSection { configs, setup },
            ports,
            receivers: ReceiversSection { period_ms, boot_ms },
        })
    }

    /// Reads the config for `mode` and checks it against the rig: its own
    /// mode, one receiver per receiver port, and what a board can wire.
    fn multirx_config(
        &self,
        mode: Mode,
        path: PathBuf,
        setup: &DeviceSetup,
        ports: &PortsSection,
    ) -> Result<LoadedConfig, RigFileError> {
        let at = ["multirx", "device", "configs", mode.as_str()];
        let field = dotted(&at);
        let text = (self.read_config)(&path).map_err(|source| {
            let l = self.loc.locate(&at);
            RigFileError::ConfigRead {
                path: self.given.to_path_buf(),
                line: l.line,
                column: l.column,
                field: field.clone(),
                config: path.clone(),
                source,
            }
        })?;
        let parsed = match setup {
            // Real hardware flies the neutral when nobody is in control: its throttle must be
            // chosen for the flight controller, not left at mid-stick by default.
            DeviceSetup::Board(_) => {
                multirx_core::Config::from_toml_for_bench(&text, multirx_core::board::SAMD21_UARTS)
            }
            DeviceSetup::Emulated { .. } => multirx_core::Config::from_toml(&text),
        };
        let config = parsed.map_err(|source| RigFileError::Config {
            path: self.given.to_path_buf(),
            field: field.clone(),
            config: path.clone(),
            source: Box::new(source),
        })?;
        let says = match config.mode {
            multirx_core::Mode::Parallel => Mode::Parallel,
            multirx_core::Mode::Scan => Mode::Scan,
        };
        if says != mode {
            return Err(self.invalid(
                &at,
                format!(
                    "{} says mode = \"{says}\"; the {mode} suite needs a config with mode = \"{mode}\"",
                    path.display()
                ),
            ));
        }
        if usize::from(config.receivers) != ports.receivers.len() {
            return Err(self.invalid(
                &at,
                format!(
                    "{} configures {} receivers but multirx.ports.receivers lists {} ports",
                    path.display(),
                    config.receivers,
                    ports.receivers.len()
                ),
            ));
        }
        Ok(LoadedConfig { path, config })
    }

    fn ports(&self, raw: RawPorts) -> Result<PortsSection, RigFileError> {
        let n = raw.receivers.len();
        let at = ["multirx", "ports", "receivers"];
        if n == 0 {
            return Err(self.invalid(&at, "no receivers given, at least 1"));
        }
        if n > MAX_RECEIVERS {
            return Err(self.invalid(&at, format!("{n} receivers given, at most {MAX_RECEIVERS}")));
        }
        let resolve = |p: PortSpec| match p {
            PortSpec::Pty => PortSpec::Pty,
            // Joined but not normalized: a device path is kept as written
            // (by-id names are symlinks and must stay readable).
            PortSpec::Path(p) => PortSpec::Path(self.base.join(p)),
        };
        let ports = PortsSection {
            fc: resolve(raw.fc),
            status: resolve(raw.status),
            ifs: raw.ifs.map(resolve),
            receivers: raw.receivers.into_iter().map(resolve).collect(),
        };
        // One device path wired to two lines is a wiring mistake that would
        // otherwise show up as garbled frames mid-run.
        let mut named: Vec<(String, &[&str], &PortSpec)> = vec![
            (
                "multirx.ports.fc".into(),
                &["multirx", "ports", "fc"],
                &ports.fc,
            ),
            (
                "multirx.ports.status".into(),
                &["multirx", "ports", "status"],
                &ports.status,
            ),
        ];
        if let Some(ifs) = &ports.ifs {
            named.push((
                "multirx.ports.ifs".into(),
                &["multirx", "ports", "ifs"],
                ifs,
            ));
        }
        for (i, r) in ports.receivers.iter().enumerate() {
            named.push((format!("multirx.ports.receivers[{i}]"), &at, r));
        }
        for (i, (field, at, spec)) in named.iter().enumerate() {
            if let PortSpec::Path(p) = spec
                && let Some((other, _, _)) = named[..i].iter().find(|(_, _, s)| s == spec)
            {
                return Err(self.invalid_named(
                    at,
                    field.clone(),
                    format!("{} is also used for {other}", p.display()),
                ));
            }
        }
        Ok(ports)
    }
}

#[cfg(test)]
mod tests;
