//! Runs a rig's scenarios as libtest-mimic trials (so `cargo test`-style
//! filters, `--list` and `--exact` work), one phase record per trial, and
//! keeps the run record (`results.json`, with the reports rendered from it)
//! true at every moment: saved as `running` before the first phase, again as
//! each phase ends, and finalised at the end; a phase that panics is recorded
//! as an error; SIGINT or SIGTERM finalises it as `interrupted`, ends every
//! program the rig started and exits 128 + the signal's number.

use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use libtest_mimic::{Arguments, Failed, Trial};

use crate::driver::process;
use crate::driver::program::MULTIRX_EMU;
use crate::measurement::{Declarations, Dimension, Handle, Outcome, Selector, Spec};
use crate::record::{
    Attachment, DeviceIdentity, PhaseOutcome, PhaseRecord, RigIdentity, RunOutcome, RunRecord,
    ToolIdentity, now_rfc3339, sha256_file,
};
use crate::report::{self, ReportPaths};
use crate::rigfile::{BoardSetup, DeviceKind, DeviceSetup, Mode, RigFile};
use crate::scenario::PhaseContext;
use crate::scenario::multirx::{self, ModeLimits, Scenario, SessionFigures, SessionMeasurements};
use crate::strategy::firmware::{self, FirmwareImage};
use crate::strategy::multirx::MultirxSession;
use side_by_side::SideBySide;

pub mod interrupt;
pub mod lock;
mod mavlora;
mod side_by_side;

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

/// Firmware images flashed during the run, for the device identities.
type Images = Arc<Mutex<Vec<(Mode, FirmwareImage)>>>;

/// Locks `mutex` even if a phase panicked while holding it: the data is a
/// list that a panic leaves whole.
fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The run record as it grows, shared by the trials: saved (with the reports)
/// when the run opens, after each phase, and when it is finalised.
#[derive(Clone)]
pub(crate) struct Phases(Arc<Live>);

struct Live {
    out_dir: PathBuf,
    state: Mutex<LiveState>,
}

struct LiveState {
    record: RunRecord,
    /// The phase running now: name, start (RFC 3339) and its clock.
    current: Option<(String, String, Instant)>,
    /// Saved to disk as it changes: after [`Phases::open`], until final.
    saving: bool,
}

impl Phases {
    /// A record of a run that has not started: nothing is saved until [`Phases::open`].
    fn new(record: RunRecord, out_dir: &Path) -> Self {
        Phases(Arc::new(Live {
            out_dir: out_dir.to_path_buf(),
            state: Mutex::new(LiveState {
                record,
                current: None,
                saving: false,
            }),
        }))
    }

    /// Starts the run: saves the record as `running`, replacing any earlier
    /// run's, so what is in the folder is never mistaken for this run's verdict.
    fn open(&self) -> Result<()> {
        let mut state = lock(&self.0.state);
        state.record.started = now_rfc3339();
        state.record.ended = state.record.started.clone();
        state.record.outcome = RunOutcome::Running;
        report::write_all(&state.record, &self.0.out_dir).with_context(|| {
            format!(
                "cannot write the run record in {}",
                self.0.out_dir.display()
            )
        })?;
        state.saving = true;
        Ok(())
    }

    /// A phase starts: if the run is interrupted now, this phase is the one interrupted.
    fn begin(&self, name: &str) {
        lock(&self.0.state).current = Some((name.to_owned(), now_rfc3339(), Instant::now()));
    }

    /// A phase ended: kept, and the record (still `running`) saved.
    fn push(&self, phase: PhaseRecord) {
        let mut state = lock(&self.0.state);
        state.current = None;
        state.record.phases.push(phase);
        if state.saving {
            state.record.ended = now_rfc3339();
            if let Err(e) = report::write_all(&state.record, &self.0.out_dir) {
                eprintln!("rig: warning: cannot save the run record: {e}");
            }
        }
    }

    /// Reads the phases ended so far.
    fn with_phases<R>(&self, f: impl FnOnce(&[PhaseRecord]) -> R) -> R {
        f(&lock(&self.0.state).record.phases)
    }

    /// The run ended: the outcome is judged from the phases (an error if the
    /// trial runner saw a failure no phase recorded), the record saved for good.
    fn finish(
        &self,
        devices: Vec<DeviceIdentity>,
        runner_failed: bool,
    ) -> Result<(RunRecord, ReportPaths)> {
        let mut state = lock(&self.0.state);
        let record = &mut state.record;
        record.devices = devices;
        record.ended = now_rfc3339();
        record.outcome = match RunOutcome::from_phases(&record.phases) {
            RunOutcome::Pass if runner_failed => RunOutcome::Error,
            outcome => outcome,
        };
        let paths = report::write_all(record, &self.0.out_dir)?;
        state.saving = false;
        Ok((state.record.clone(), paths))
    }

    /// The rig was stopped by `signal`: the phase in progress is recorded as
    /// interrupted and the record saved as `interrupted`; nothing is saved after.
    fn interrupt(&self, devices: Vec<DeviceIdentity>, signal: &str) -> Result<ReportPaths> {
        let mut state = lock(&self.0.state);
        state.saving = false;
        let why = format!("interrupted by {signal}");
        if let Some((name, started, clock)) = state.current.take() {
            let phase = PhaseRecord::interrupted(name, started, clock.elapsed().as_secs_f64(), why);
            state.record.phases.push(phase);
        }
        let record = &mut state.record;
        record.devices = devices;
        record.ended = now_rfc3339();
        record.outcome = RunOutcome::Interrupted;
        Ok(report::write_all(record, &self.0.out_dir)?)
    }
}

/// No phase is selected: nothing runs and nothing is written (exit code 2).
#[derive(Debug, thiserror::Error)]
#[error("{what}: nothing to run (`rig run {rig} --list` names the phases)")]
pub struct NothingSelected {
    /// What selected nothing: the filter, or the rig file.
    pub what: String,
    /// The rig file, for the hint.
    pub rig: String,
}

/// Runs everything the rig file describes.
pub fn run(rig: RigFile, options: RunOptions) -> Result<RunResult> {
    let rig = Arc::new(rig);
    let out_dir = options.out_dir.clone();
    let phases = Phases::new(
        RunRecord {
            tool: ToolIdentity::this_build(git_commit()),
            rig: RigIdentity::of_file(rig.rig.name.clone(), &rig.path)?,
            devices: devices(&rig, &[]),
            started: String::new(),
            ended: String::new(),
            outcome: RunOutcome::Running,
            phases: Vec::new(),
        },
        &out_dir,
    );
    let images: Images = Arc::default();
    let Plan {
        trials,
        known_names,
        groups,
    } = plan(&rig, &phases, &out_dir, &images)?;
    rig.check_limit_names(known_names.iter().map(String::as_str))?;

    let args = Arguments {
        filter: options.filter.clone(),
        exact: options.exact,
        list: options.list,
        // Scenarios time real devices and processes: one at a time (and on the
        // main thread, which the children's PR_SET_PDEATHSIG is tied to).
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
    let selected: Vec<&str> = trials
        .iter()
        .filter(|t| !args.is_filtered_out(t))
        .map(Trial::name)
        .collect();
    for group in &groups {
        group.select(selected.iter().copied());
    }
    if selected.is_empty() {
        return Err(NothingSelected {
            what: match &options.filter {
                Some(f) => format!(
                    "--filter {f:?}{} matches no phase of {}",
                    if options.exact { " --exact" } else { "" },
                    rig.path.display()
                ),
                None => format!("{} describes no phase", rig.path.display()),
            },
            rig: rig.path.display().to_string(),
        }
        .into());
    }
    // Held until the run's record is final: no other run drives this bench meanwhile.
    let _bench = match &rig.rig.lock {
        Some(path) => Some(lock::BenchLock::acquire(path)?.0),
        None => None,
    };
    std::fs::create_dir_all(&out_dir)
        .with_context(|| format!("cannot create output folder {}", out_dir.display()))?;
    phases.open()?;
    {
        let (phases, rig, images) = (phases.clone(), rig.clone(), images.clone());
        interrupt::on_interrupt(move |signal, name| {
            eprintln!("\nrig: {name}: recording the run as interrupted, stopping its programs");
            let devices = devices(&rig, &lock(&images));
            match phases.interrupt(devices, name) {
                Ok(paths) => eprintln!("rig: interrupted; report: {}", paths.results.display()),
                Err(e) => eprintln!("rig: error: cannot save the interrupted record: {e:#}"),
            }
            process::kill_all(Duration::from_millis(300));
            std::process::exit(128 + signal);
        })
        .context("cannot handle SIGINT/SIGTERM")?;
    }
    let conclusion = libtest_mimic::run(&args, trials);
    let devices = devices(&rig, &lock(&images));
    let (record, paths) = phases.finish(devices, conclusion.has_failed())?;
    Ok(RunResult {
        record: Some(record),
        paths: Some(paths),
    })
}

/// What a rig file asks to run.
struct Plan {
    /// Every phase, as a trial.
    trials: Vec<Trial>,
    /// The flat names of the measurements they declare.
    known_names: Vec<String>,
    /// The groups of phases that run side by side.
    groups: Vec<Arc<SideBySide>>,
}

/// Every phase the rig file describes.
fn plan(rig: &Arc<RigFile>, phases: &Phases, out_dir: &Path, images: &Images) -> Result<Plan> {
    let mut trials = Vec::new();
    let mut known_names = Vec::new();
    if let Some(section) = &rig.multirx {
        for &mode in &section.modes {
            let limits = mode_limits(rig, mode)?;
            if let DeviceSetup::Board(board) = &section.device.setup
                && board.flash
            {
                let flash = declare_flash(mode);
                known_names.extend(names(&flash.0));
                trials.push(flash_trial(rig, phases, images, mode, board.clone(), flash));
            }
            let mut scenarios = multirx::scenarios();
            if matches!(section.device.setup, DeviceSetup::Emulated { .. }) {
                scenarios.extend(multirx::emulated_only());
            }
            for scenario in scenarios {
                let plan = ScenarioPlan::declare(&scenario, &limits);
                known_names.extend(names(&plan.declared));
                trials.push(scenario_trial(
                    rig,
                    phases,
                    out_dir,
                    mode,
                    scenario,
                    limits.clone(),
                    plan,
                ));
            }
            let whole_run = declare_whole_run(&limits);
            known_names.extend(names(&whole_run.0));
            trials.push(whole_run_trial(rig, phases, mode, limits, whole_run));
        }
    }
    let realtime = SideBySide::new(mavlora::REALTIME_SIDE_BY_SIDE);
    known_names.extend(mavlora::add_trials(
        rig,
        phases,
        out_dir,
        &realtime,
        &mut trials,
    ));
    Ok(Plan {
        trials,
        known_names,
        groups: vec![realtime],
    })
}

/// The flat names of every measurement the phases of `rig` declare (the trace matrix checks its
/// requirements against them). Runs nothing and writes nothing.
pub fn declared_names(rig: RigFile) -> Result<Vec<String>> {
    let rig = Arc::new(rig);
    let phases = Phases::new(
        RunRecord {
            tool: ToolIdentity::this_build(None),
            rig: RigIdentity::of_file(rig.rig.name.clone(), &rig.path)?,
            devices: Vec::new(),
            started: String::new(),
            ended: String::new(),
            outcome: RunOutcome::Running,
            phases: Vec::new(),
        },
        Path::new(""),
    );
    let mut names = plan(&rig, &phases, Path::new(""), &Images::default())?.known_names;
    names.sort();
    names.dedup();
    Ok(names)
}

/// One trial: the phase `body` runs with the run told it started, and its
/// record is kept even if it panics (as an error naming the panic).
fn phase_trial(
    phases: &Phases,
    name: String,
    body: impl FnOnce() -> PhaseRecord + Send + 'static,
) -> Trial {
    let phases = phases.clone();
    Trial::test(name.clone(), move || run_guarded(&phases, &name, body))
}

fn run_guarded(
    phases: &Phases,
    name: &str,
    body: impl FnOnce() -> PhaseRecord,
) -> Result<(), Failed> {
    let started = now_rfc3339();
    let clock = Instant::now();
    phases.begin(name);
    let record = catch_unwind(AssertUnwindSafe(body)).unwrap_or_else(|payload| {
        PhaseRecord::ran(
            name,
            started,
            clock.elapsed().as_secs_f64(),
            Vec::new(),
            Some(panicked(payload.as_ref())),
        )
    });
    conclude(phases, record)
}

/// The error a panicking phase is recorded with.
fn panicked(payload: &(dyn Any + Send)) -> String {
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".to_owned());
    format!("panicked: {message}")
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
    let device = rig
        .multirx
        .as_ref()
        .map_or(DeviceKind::Emulated, |m| m.device.kind());
    Ok(ModeLimits::new(mode, &loaded.config, device))
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
    let (rig, out_dir) = (rig.clone(), out_dir.to_path_buf());
    phase_trial(phases, name.clone(), move || {
        run_scenario(&rig, &out_dir, &name, mode, &scenario, &limits, plan)
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
    // A panic keeps what the phase recorded, logged and attached so far.
    let error = match catch_unwind(AssertUnwindSafe(|| body(&mut ctx))) {
        Ok(result) => result.err().map(|e| format!("{e:#}")),
        Err(payload) => Some(panicked(payload.as_ref())),
    };
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
    let (rig, images) = (rig.clone(), images.clone());
    phase_trial(phases, name.clone(), move || {
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
fn whole_run_trial(
    rig: &Arc<RigFile>,
    phases: &Phases,
    mode: Mode,
    limits: ModeLimits,
    (declared, whole): (Declarations, SessionMeasurements),
) -> Trial {
    let name = format!("multirx::{}::whole_run", mode.as_str());
    let (rig, ran) = (rig.clone(), phases.clone());
    phase_trial(phases, name.clone(), move || {
        let started = now_rfc3339();
        let mut ctx = PhaseContext::new(&rig, Path::new(""), declared);
        // Each whole-run measurement is the same measurement of every scenario of this mode,
        // which the scenario dimension tells apart.
        let [gap, fc_gap, losses] = multirx::session_specs(&limits, None)
            .map(|spec| Selector::like(&spec).has(Dimension::Scenario));
        let hold = multirx::host_hold_spec(&limits, None)
            .map(|spec| Selector::like(&spec).has(Dimension::Scenario));
        let (gaps, fc_gaps, losses, holds) = ran.with_phases(|ran| {
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
        PhaseOutcome::Error | PhaseOutcome::Interrupted => {
            Err(Failed::from(record.error.clone().unwrap_or_default()))
        }
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
    phases.push(record);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::tests::sample_record;

    fn open_run(dir: &Path) -> Phases {
        let mut record = sample_record();
        record.phases.clear();
        let phases = Phases::new(record, dir);
        phases.open().unwrap();
        phases
    }

    fn saved(dir: &Path) -> RunRecord {
        RunRecord::load(&dir.join(crate::record::RESULTS_FILE)).unwrap()
    }

    #[test]
    fn the_record_says_running_from_the_start_and_after_each_phase() {
        let dir = tempfile::tempdir().unwrap();
        let phases = open_run(dir.path());
        assert_eq!(saved(dir.path()).outcome, RunOutcome::Running);
        run_guarded(&phases, "p1", || {
            PhaseRecord::ran("p1", now_rfc3339(), 0.0, Vec::new(), None)
        })
        .unwrap();
        let record = saved(dir.path());
        assert_eq!(record.outcome, RunOutcome::Running);
        assert_eq!(record.phases.len(), 1);
        let summary = std::fs::read_to_string(dir.path().join("summary.txt")).unwrap();
        assert!(summary.contains(": RUNNING"), "{summary}");
        assert!(!summary.contains(": PASS"), "{summary}");
        let (record, _) = phases.finish(Vec::new(), false).unwrap();
        assert_eq!(record.outcome, RunOutcome::Pass);
        assert_eq!(saved(dir.path()).outcome, RunOutcome::Pass);
    }

    #[test]
    fn a_panicking_phase_is_recorded_as_an_error_and_the_run_does_not_pass() {
        let dir = tempfile::tempdir().unwrap();
        let phases = open_run(dir.path());
        let verdict = run_guarded(&phases, "boom", || panic!("the fixture went away"));
        assert!(verdict.is_err());
        let record = saved(dir.path());
        assert_eq!(record.phases.len(), 1, "the panicking phase is recorded");
        let phase = &record.phases[0];
        assert_eq!(phase.name, "boom");
        assert_eq!(phase.outcome, PhaseOutcome::Error);
        assert_eq!(
            phase.error.as_deref(),
            Some("panicked: the fixture went away")
        );
        let (record, _) = phases.finish(Vec::new(), true).unwrap();
        assert_eq!(record.outcome, RunOutcome::Error);
    }

    #[test]
    fn a_failure_only_the_trial_runner_saw_makes_the_run_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let phases = open_run(dir.path());
        let (record, _) = phases.finish(Vec::new(), true).unwrap();
        assert_eq!(record.outcome, RunOutcome::Error);
    }

    #[test]
    fn an_interrupt_keeps_the_phases_done_and_marks_the_one_in_progress() {
        let dir = tempfile::tempdir().unwrap();
        let phases = open_run(dir.path());
        run_guarded(&phases, "done", || {
            PhaseRecord::ran("done", now_rfc3339(), 0.0, Vec::new(), None)
        })
        .unwrap();
        phases.begin("in_progress");
        phases.interrupt(Vec::new(), "SIGTERM").unwrap();
        let record = saved(dir.path());
        assert_eq!(record.outcome, RunOutcome::Interrupted);
        let outcomes: Vec<_> = record
            .phases
            .iter()
            .map(|p| (p.name.as_str(), p.outcome))
            .collect();
        assert_eq!(
            outcomes,
            [
                ("done", PhaseOutcome::Pass),
                ("in_progress", PhaseOutcome::Interrupted)
            ]
        );
        // A phase that ends after the interrupt does not overwrite the final record.
        phases.push(PhaseRecord::ran(
            "late",
            now_rfc3339(),
            0.0,
            Vec::new(),
            None,
        ));
        assert_eq!(saved(dir.path()).phases.len(), 2);
        let summary = std::fs::read_to_string(dir.path().join("summary.txt")).unwrap();
        assert!(summary.contains(": INTERRUPTED"), "{summary}");
        assert!(summary.contains("interrupted by SIGTERM"), "{summary}");
    }
}
