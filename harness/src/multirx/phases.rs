//! MultiRX's phases: per mode, the firmware flashed (a board rig with `flash = true`), each
//! scenario on a freshly started device, and the whole run's session figures folded from them.

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::{Context, Result};

use super::MULTIRX_EMU;
use super::firmware::{self, FirmwareImage};
use super::rigfile::{BoardSetup, DeviceKind, DeviceSetup, Mode};
use super::scenario::{self, ModeLimits, Scenario, SessionFigures, SessionMeasurements};
use super::session::MultirxSession;
use crate::measurement::{Declarations, Dimension, Handle, Selector, Spec};
use crate::record::{DeviceIdentity, PhaseRecord, now_rfc3339, sha256_file};
use crate::rigfile::RigFile;
use crate::runner::live::lock;
use crate::runner::{Device, Phase, PhaseContext};

/// Firmware images flashed during the run, for the device identities.
type Images = Arc<Mutex<Vec<(Mode, FirmwareImage)>>>;

/// The MultiRX of a rig file's `[multirx]`.
pub struct Multirx {
    rig: Arc<RigFile>,
    images: Images,
}

impl Multirx {
    pub fn new(rig: Arc<RigFile>) -> Self {
        Multirx {
            rig,
            images: Images::default(),
        }
    }
}

impl Device for Multirx {
    fn phases(&self) -> Result<Vec<Phase>> {
        let mut phases = Vec::new();
        let Some(section) = &self.rig.devices.multirx else {
            return Ok(phases);
        };
        for &mode in &section.modes {
            let limits = mode_limits(&self.rig, mode)?;
            if let DeviceSetup::Board(board) = &section.device.setup
                && board.flash
            {
                phases.push(flash_phase(&self.images, mode, board.clone()));
            }
            let mut scenarios = scenario::scenarios();
            if matches!(section.device.setup, DeviceSetup::Emulated { .. }) {
                scenarios.extend(scenario::emulated_only());
            }
            for scenario in scenarios {
                phases.push(scenario_phase(mode, scenario, limits.clone()));
            }
            phases.push(whole_run_phase(mode, limits));
        }
        Ok(phases)
    }

    fn identities(&self) -> Vec<DeviceIdentity> {
        identities(&self.rig, &lock(&self.images))
    }
}

fn mode_limits(rig: &RigFile, mode: Mode) -> Result<ModeLimits> {
    let loaded = rig
        .devices
        .multirx
        .as_ref()
        .and_then(|m| m.config(mode))
        .with_context(|| format!("no MultiRX config for mode {mode}"))?;
    let device = rig
        .devices
        .multirx
        .as_ref()
        .map_or(DeviceKind::Emulated, |m| m.device.kind());
    Ok(ModeLimits::new(mode, &loaded.config, device))
}

/// One scenario of one mode, on a device started for it alone.
fn scenario_phase(mode: Mode, scenario: Scenario, limits: ModeLimits) -> Phase {
    let name = format!("multirx::{}::{}", mode.as_str(), scenario.name);
    let ScenarioPlan {
        declared,
        script,
        session: session_measurements,
    } = ScenarioPlan::declare(&scenario, &limits);
    Phase::measured(name, scenario.summary, declared, move |ctx| {
        let session = MultirxSession::start(ctx.rig, mode, scenario.options, &ctx.dir.clone())?;
        let result = script(&session, ctx, &limits);
        let recorded = scenario::record_session(&session, ctx, &session_measurements);
        for log in session.finish() {
            let label = log
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let media = if log.extension().is_some_and(|e| e == "csv") {
                "text/csv"
            } else {
                "text/plain"
            };
            ctx.attach(label, log, media);
        }
        result.and(recorded)
    })
}

/// A MultiRX scenario's measurements, its own and its session's, and the
/// script that records its own.
struct ScenarioPlan {
    declared: Declarations,
    script: scenario::Script,
    session: SessionMeasurements,
}

impl ScenarioPlan {
    fn declare(scenario: &Scenario, limits: &ModeLimits) -> Self {
        let mut declared = Declarations::new();
        let script = (scenario.plan)(&mut declared, limits);
        let session = SessionMeasurements::declare(&mut declared, limits, Some(scenario.name));
        ScenarioPlan {
            declared,
            script,
            session,
        }
    }
}

/// The SAMD21G18A: 256 KiB flash, 32 KiB RAM.
const CHIP_FLASH: f64 = 256.0 * 1024.0;
const CHIP_RAM: f64 = 32.0 * 1024.0;

/// The firmware image's flash and RAM use with this mode's config.
fn declare_flash(mode: Mode) -> (Declarations, [Handle; 2]) {
    let image = |base: &str| {
        Spec::new(base, "B")
            .dim(Dimension::Artifact, "firmware")
            .dim(Dimension::Device, "multirx")
            .dim(Dimension::Mode, mode.as_str())
    };
    let mut declared = Declarations::new();
    let flash = declared.declare(
        image("flash_bytes")
            .describe("flash the firmware image takes with this mode's config")
            .at_most(CHIP_FLASH),
    );
    let ram = declared.declare(
        image("ram_bytes")
            .describe("static RAM (.data + .bss); the stack has the rest")
            .at_most(CHIP_RAM),
    );
    (declared, [flash, ram])
}

/// Built → flashed: the board gets the firmware with this mode's config.
fn flash_phase(images: &Images, mode: Mode, board: BoardSetup) -> Phase {
    let name = format!("multirx::{}::flash", mode.as_str());
    let (declared, [flash_bytes, ram_bytes]) = declare_flash(mode);
    let images = images.clone();
    Phase::custom(name.clone(), declared, move |env, declared| {
        let rig = &env.rig;
        let started = now_rfc3339();
        let clock = Instant::now();
        let mut ctx = PhaseContext::new(rig, Path::new(""), declared);
        let result = (|| -> Result<()> {
            let config = &rig
                .devices
                .multirx
                .as_ref()
                .and_then(|m| m.config(mode))
                .context("config")?
                .path;
            ctx.log(format!(
                "building {} with {}",
                board.firmware.display(),
                config.display()
            ));
            let image = firmware::build(&board.firmware, config)?;
            ctx.record(flash_bytes, image.flash_bytes as f64);
            ctx.record(ram_bytes, image.ram_bytes as f64);
            ctx.log(format!(
                "image {} sha256 {}",
                image.elf.display(),
                image.sha256
            ));
            let flashed = firmware::flash(&board, &image)?;
            ctx.log(format!(
                "flashed through {} in {:.1} s",
                flashed.probe,
                flashed.duration.as_secs_f64()
            ));
            lock(&images).push((mode, image));
            Ok(())
        })();
        let (measurements, log, _) = ctx.into_parts();
        let mut record = PhaseRecord::ran(
            &name,
            started,
            clock.elapsed().as_secs_f64(),
            measurements,
            result.err().map(|e| format!("{e:#}")),
        );
        record.log = log;
        record
    })
}

/// The whole run's session measurements of a mode.
fn declare_whole_run(limits: &ModeLimits) -> (Declarations, SessionMeasurements) {
    let mut declared = Declarations::new();
    let whole = SessionMeasurements::declare(&mut declared, limits, None);
    (declared, whole)
}

/// Folds the per-scenario session measurements of one mode into whole-run ones.
fn whole_run_phase(mode: Mode, limits: ModeLimits) -> Phase {
    let name = format!("multirx::{}::whole_run", mode.as_str());
    let (declared, whole) = declare_whole_run(&limits);
    Phase::custom(name.clone(), declared, move |env, declared| {
        let started = now_rfc3339();
        let mut ctx = PhaseContext::new(&env.rig, Path::new(""), declared);
        // Each whole-run measurement is the same measurement of every scenario of this mode,
        // which the scenario dimension tells apart.
        let [gap, fc_gap, losses] = scenario::session_specs(&limits, None)
            .map(|spec| Selector::like(&spec).has(Dimension::Scenario));
        let hold = scenario::host_hold_spec(&limits, None)
            .map(|spec| Selector::like(&spec).has(Dimension::Scenario));
        let (gaps, fc_gaps, losses, holds) = env.with_phases(|ran| {
            let values = |selector: &Selector| -> Vec<f64> {
                ran.iter()
                    .flat_map(|p| p.select(selector))
                    .filter_map(|m| m.value)
                    .collect()
            };
            let holds = hold.as_ref().map(values);
            (values(&gap), values(&fc_gap), values(&losses), holds)
        });
        let count = gaps.len();
        if count == 0 {
            let (measurements, _, _) = ctx.into_parts();
            PhaseRecord::skipped(&name, started, measurements, "no scenario of this mode ran")
        } else {
            ctx.log(format!("{count} scenarios"));
            let worst = |v: Vec<f64>| v.into_iter().fold(0.0, f64::max);
            whole.record(
                &mut ctx,
                &SessionFigures {
                    output_gap_ms: worst(gaps),
                    fc_gap_ms: worst(fc_gaps),
                    rc_losses: losses.into_iter().fold(0.0, |sum, v| sum + v),
                    host_hold_ms: holds.map(worst),
                },
            );
            let (measurements, log, _) = ctx.into_parts();
            let mut r = PhaseRecord::ran(&name, started, 0.0, measurements, None);
            r.log = log;
            r
        }
    })
}

fn identities(rig: &RigFile, images: &[(Mode, FirmwareImage)]) -> Vec<DeviceIdentity> {
    let Some(section) = &rig.devices.multirx else {
        return Vec::new();
    };
    let port = Some(section.ports.fc.to_string());
    match &section.device.setup {
        DeviceSetup::Emulated { program } => {
            let path = program.clone().unwrap_or_else(|| MULTIRX_EMU.path());
            vec![DeviceIdentity {
                role: "multirx".into(),
                kind: "emulated".into(),
                description: format!("multirx-emu (multirx-core {})", env!("CARGO_PKG_VERSION")),
                port,
                firmware_sha256: sha256_file(&path).ok(),
            }]
        }
        DeviceSetup::Board(board) => {
            let describe = |what: &str| {
                format!(
                    "MultiRX SAMD21 board, chip {}, probe {}, {what}",
                    board.chip, board.probe
                )
            };
            if images.is_empty() {
                return vec![DeviceIdentity {
                    role: "multirx".into(),
                    kind: "board".into(),
                    description: describe("firmware as found (not flashed by this run)"),
                    port,
                    firmware_sha256: None,
                }];
            }
            images
                .iter()
                .map(|(mode, image)| DeviceIdentity {
                    role: "multirx".into(),
                    kind: "board".into(),
                    description: describe(&format!("flashed for the {mode} suite")),
                    port: port.clone(),
                    firmware_sha256: Some(image.sha256.clone()),
                })
                .collect()
        }
    }
}
