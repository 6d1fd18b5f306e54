//! Runs a rig's scenarios as libtest-mimic trials (so `cargo test`-style
//! filters, `--list` and `--exact` work), one phase record per trial, then
//! writes the run record and the reports rendered from it.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::{Context, Result};
use libtest_mimic::{Arguments, Failed, Trial};

use crate::driver::program::MULTIRX_EMU;
use crate::measurement::{Declarations, Dimension, Handle, Outcome, Selector, Spec};
use crate::record::{
    Attachment, DeviceIdentity, PhaseOutcome, PhaseRecord, RigIdentity, RunOutcome, RunRecord,
    ToolIdentity, now_rfc3339, sha256_file,
};
use crate::report::{self, ReportPaths};
use crate::rigfile::{BoardSetup, DeviceSetup, Mode, RigFile};
use crate::scenario::PhaseContext;
use crate::scenario::multirx::{self, ModeLimits, Scenario, SessionMeasurements};
use crate::strategy::firmware::{self, FirmwareImage};
use crate::strategy::multirx::MultirxSession;

mod mavlora;

/// What to run and where to write.
pub struct RunOptions {
    pub out_dir: PathBuf,
    pub filter: Option<String>,
    pub exact: bool,
    pub list: bool,
}

/// How a run ended.
pub struct RunResult {
    pub record: Option<RunRecord>,
    pub paths: Option<ReportPaths>,
}

type Phases = Arc<Mutex<Vec<PhaseRecord>>>;
/// Firmware images flashed during the run, for the device identities.
type Images = Arc<Mutex<Vec<(Mode, FirmwareImage)>>>;

/// Runs everything the rig file describes.
pub fn run(rig: RigFile, options: RunOptions) -> Result<RunResult> {
    let rig = Arc::new(rig);
    let phases: Phases = Arc::default();
    let out_dir = options.out_dir.clone();
    let mut trials = Vec::new();
    let mut known_names = Vec::new();
    let images: Images = Arc::default();
    if let Some(section) = &rig.multirx {
        for &mode in &section.modes {
            let limits = mode_limits(&rig, mode)?;
            if let DeviceSetup::Board(board) = &section.device.setup
                && board.flash
            {
                let flash = declare_flash(mode);
                known_names.extend(names(&flash.0));
                trials.push(flash_trial(
                    &rig,
                    &phases,
                    &images,
                    mode,
                    board.clone(),
                    flash,
                ));
            }
            for scenario in multirx::scenarios() {
                let plan = ScenarioPlan::declare(&scenario, &limits);
                known_names.extend(names(&plan.declared));
                trials.push(scenario_trial(
                    &rig,
                    &phases,
                    &out_dir,
                    mode,
                    scenario,
                    limits.clone(),
                    plan,
                ));
            }
            let whole_run = declare_whole_run(&limits);
            known_names.extend(names(&whole_run.0));
            trials.push(whole_run_trial(&rig, &phases, mode, limits, whole_run));
        }
    }
    known_names.extend(mavlora::add_trials(&rig, &phases, &out_dir, &mut trials));
    rig.check_limit_names(known_names.iter().map(String::as_str))?;

    let args = Arguments {
        filter: options.filter.clone(),
        exact: options.exact,
        list: options.list,
        // Scenarios time real devices and processes: one at a time.
        test_threads: Some(1),
        ..Arguments::default()
    };
    if options.list {
        let _ = libtest_mimic::run(&args, trials);
        return Ok(RunResult {
            record: None,
            paths: None,
        });
    }
    std::fs::create_dir_all(&out_dir)
        .with_context(|| format!("cannot create output folder {}", out_dir.display()))?;
    let started = now_rfc3339();
    let _conclusion = libtest_mimic::run(&args, trials);
    let phases = std::mem::take(&mut *phases.lock().unwrap());
    let record = RunRecord {
        tool: ToolIdentity::this_build(git_commit()),
        rig: RigIdentity::of_file(rig.rig.name.clone(), &rig.path)?,
        devices: devices(&rig, &images.lock().unwrap()),
        started,
        ended: now_rfc3339(),
        outcome: RunOutcome::from_phases(&phases),
        phases,
    };
    let paths = report::write_all(&record, &out_dir)?;
    Ok(RunResult {
        record: Some(record),
        paths: Some(paths),
    })
}

/// The flat names of declared measurements, for the `[limits]` check.
fn names(declared: &Declarations) -> impl Iterator<Item = String> + '_ {
    declared.measurements().iter().map(|m| m.name.clone())
}

fn mode_limits(rig: &RigFile, mode: Mode) -> Result<ModeLimits> {
    let loaded = rig
        .multirx
        .as_ref()
        .and_then(|m| m.config(mode))
        .with_context(|| format!("no MultiRX config for mode {mode}"))?;
    Ok(ModeLimits::new(mode, &loaded.config))
}

fn scenario_trial(
    rig: &Arc<RigFile>,
    phases: &Phases,
    out_dir: &Path,
    mode: Mode,
    scenario: Scenario,
    limits: ModeLimits,
    plan: ScenarioPlan,
) -> Trial {
    let name = format!("multirx::{}::{}", mode.as_str(), scenario.name);
    let (rig, phases, out_dir) = (rig.clone(), phases.clone(), out_dir.to_path_buf());
    Trial::test(name.clone(), move || {
        let record = run_scenario(&rig, &out_dir, &name, mode, &scenario, &limits, plan);
        conclude(&phases, record)
    })
}

fn run_scenario(
    rig: &RigFile,
    out_dir: &Path,
    name: &str,
    mode: Mode,
    scenario: &Scenario,
    limits: &ModeLimits,
    plan: ScenarioPlan,
) -> PhaseRecord {
    let ScenarioPlan {
        declared,
        script,
        session: session_measurements,
    } = plan;
    let dir = phase_dir(out_dir, name);
    run_phase(rig, out_dir, name, scenario.summary, declared, |ctx| {
        let session = MultirxSession::start(rig, mode, scenario.options, &dir)?;
        let result = script(&session, ctx, limits);
        let recorded = multirx::record_session(&session, ctx, &session_measurements);
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
    script: multirx::Script,
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

/// A phase's own folder in the output folder: `multirx::parallel::b_handover` →
/// `multirx.parallel.b_handover`.
fn phase_dir(out_dir: &Path, name: &str) -> PathBuf {
    out_dir.join(name.replace("::", "."))
}

/// One phase: takes the `measurements` it declared, runs `body` with the phase's context (its folder is
/// [`phase_dir`]), and turns what it recorded, logged and attached into a [`PhaseRecord`].
fn run_phase(
    rig: &RigFile,
    out_dir: &Path,
    name: &str,
    summary: &str,
    measurements: Declarations,
    body: impl FnOnce(&mut PhaseContext) -> Result<()>,
) -> PhaseRecord {
    let started = now_rfc3339();
    let clock = Instant::now();
    let mut ctx = PhaseContext::new(rig, &phase_dir(out_dir, name), measurements);
    ctx.log(summary);
    let error = body(&mut ctx).err().map(|e| format!("{e:#}"));
    let (measurements, log, files) = ctx.into_parts();
    let mut record = PhaseRecord::ran(
        name,
        started,
        clock.elapsed().as_secs_f64(),
        measurements,
        error,
    );
    record.log = log;
    for (label, path, media) in files {
        match Attachment::from_file(out_dir, &path, label, media) {
            Ok(a) => record.attachments.push(a),
            Err(e) => record
                .log
                .push(format!("attachment {} not kept: {e}", path.display())),
        }
    }
    record
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
fn flash_trial(
    rig: &Arc<RigFile>,
    phases: &Phases,
    images: &Images,
    mode: Mode,
    board: BoardSetup,
    (declared, [flash_bytes, ram_bytes]): (Declarations, [Handle; 2]),
) -> Trial {
    let name = format!("multirx::{}::flash", mode.as_str());
    let (rig, phases, images) = (rig.clone(), phases.clone(), images.clone());
    Trial::test(name.clone(), move || {
        let started = now_rfc3339();
        let clock = Instant::now();
        let mut ctx = PhaseContext::new(&rig, Path::new(""), declared);
        let result = (|| -> Result<()> {
            let config = &rig
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
            images.lock().unwrap().push((mode, image));
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
        conclude(&phases, record)
    })
}

/// The whole run's session measurements of a mode.
fn declare_whole_run(limits: &ModeLimits) -> (Declarations, SessionMeasurements) {
    let mut declared = Declarations::new();
    let whole = SessionMeasurements::declare(&mut declared, limits, None);
    (declared, whole)
}

/// Folds the per-scenario session measurements of one mode into whole-run ones.
fn whole_run_trial(
    rig: &Arc<RigFile>,
    phases: &Phases,
    mode: Mode,
    limits: ModeLimits,
    (declared, whole): (Declarations, SessionMeasurements),
) -> Trial {
    let name = format!("multirx::{}::whole_run", mode.as_str());
    let (rig, phases) = (rig.clone(), phases.clone());
    Trial::test(name.clone(), move || {
        let started = now_rfc3339();
        let mut ctx = PhaseContext::new(&rig, Path::new(""), declared);
        // Each whole-run measurement is the same measurement of every scenario of this mode,
        // which the scenario dimension tells apart.
        let [gap, fc_gap, losses] = multirx::session_specs(&limits, None)
            .map(|spec| Selector::like(&spec).has(Dimension::Scenario));
        let (gaps, fc_gaps, losses) = {
            let ran = phases.lock().unwrap();
            let values = |selector: &Selector| -> Vec<f64> {
                ran.iter()
                    .flat_map(|p| p.select(selector))
                    .filter_map(|m| m.value)
                    .collect()
            };
            (values(&gap), values(&fc_gap), values(&losses))
        };
        let count = gaps.len();
        let record = if count == 0 {
            let (measurements, _, _) = ctx.into_parts();
            PhaseRecord::skipped(&name, started, measurements, "no scenario of this mode ran")
        } else {
            ctx.log(format!("{count} scenarios"));
            let worst = |v: Vec<f64>| v.into_iter().fold(0.0, f64::max);
            whole.record(
                &mut ctx,
                worst(gaps),
                worst(fc_gaps),
                losses.into_iter().fold(0.0, |sum, v| sum + v),
            );
            let (measurements, log, _) = ctx.into_parts();
            let mut r = PhaseRecord::ran(&name, started, 0.0, measurements, None);
            r.log = log;
            r
        };
        conclude(&phases, record)
    })
}

/// Stores the phase and tells libtest-mimic how it went.
fn conclude(phases: &Phases, record: PhaseRecord) -> Result<(), Failed> {
    let verdict = match record.outcome {
        PhaseOutcome::Pass | PhaseOutcome::Skipped => Ok(()),
        PhaseOutcome::Fail => {
            let failing: Vec<String> = record
                .failing_measurements()
                .map(crate::report::junit::failure_line)
                .collect();
            Err(Failed::from(failing.join("; ")))
        }
        PhaseOutcome::Error => Err(Failed::from(record.error.clone().unwrap_or_default())),
    };
    for m in &record.measurements {
        if m.outcome != Outcome::Unset {
            println!(
                "    {} = {} [{}] {}",
                m.name,
                m.render_value(),
                m.limits.render(&m.unit),
                m.outcome
            );
        }
    }
    phases.lock().unwrap().push(record);
    verdict
}

fn devices(rig: &RigFile, images: &[(Mode, FirmwareImage)]) -> Vec<DeviceIdentity> {
    let Some(section) = &rig.multirx else {
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

fn git_commit() -> Option<String> {
    let out = std::process::Command::new("git")
        .args(["rev-parse", "HEAD"])
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}
