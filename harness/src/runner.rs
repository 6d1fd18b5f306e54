//! Runs a rig's scenarios as libtest-mimic trials (so `cargo test`-style
//! filters, `--list` and `--exact` work), one phase record per trial, then
//! writes the run record and the reports rendered from it.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::{Context, Result};
use libtest_mimic::{Arguments, Failed, Trial};

use crate::measurement::{Measurement, Outcome};
use crate::record::{
    Attachment, DeviceIdentity, PhaseOutcome, PhaseRecord, RigIdentity, RunOutcome, RunRecord,
    ToolIdentity, now_rfc3339, sha256_file,
};
use crate::report::{self, ReportPaths};
use crate::rigfile::{DeviceSetup, Mode, RigFile};
use crate::scenario::PhaseContext;
use crate::scenario::multirx::{self, Limits, Scenario};
use crate::strategy::multirx::MultirxSession;

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

/// Runs everything the rig file describes.
pub fn run(rig: RigFile, options: RunOptions) -> Result<RunResult> {
    let rig = Arc::new(rig);
    let phases: Phases = Arc::default();
    let out_dir = options.out_dir.clone();
    let mut trials = Vec::new();
    let mut known_names = Vec::new();
    if let Some(section) = &rig.multirx {
        for &mode in &section.modes {
            let limits = mode_limits(&rig, mode)?;
            for scenario in multirx::scenarios() {
                let mut declared = (scenario.measurements)(&limits);
                declared.extend(multirx::session_measurements(&limits, scenario.name));
                known_names.extend(declared.iter().map(|m| m.name.clone()));
                trials.push(scenario_trial(
                    &rig,
                    &phases,
                    &out_dir,
                    mode,
                    scenario,
                    limits.clone(),
                ));
            }
            known_names.extend(whole_run_measurements(&limits).into_iter().map(|m| m.name));
            trials.push(whole_run_trial(&rig, &phases, mode, limits));
        }
    }
    rig.check_limit_names(known_names.iter().map(String::as_str))?;

    let args = Arguments {
        filter: options.filter.clone(),
        exact: options.exact,
        list: options.list,
        // Scenarios time a real device: one at a time.
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
        devices: devices(&rig),
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

fn mode_limits(rig: &RigFile, mode: Mode) -> Result<Limits> {
    Ok(Limits::new(
        mode,
        &crate::strategy::multirx::load_config(rig, mode)?,
    ))
}

fn scenario_trial(
    rig: &Arc<RigFile>,
    phases: &Phases,
    out_dir: &Path,
    mode: Mode,
    scenario: Scenario,
    limits: Limits,
) -> Trial {
    let name = format!("multirx::{}::{}", mode.as_str(), scenario.name);
    let (rig, phases, out_dir) = (rig.clone(), phases.clone(), out_dir.to_path_buf());
    Trial::test(name.clone(), move || {
        let record = run_scenario(&rig, &out_dir, &name, mode, &scenario, &limits);
        conclude(&phases, record)
    })
}

fn run_scenario(
    rig: &RigFile,
    out_dir: &Path,
    name: &str,
    mode: Mode,
    scenario: &Scenario,
    limits: &Limits,
) -> PhaseRecord {
    let started = now_rfc3339();
    let clock = Instant::now();
    let dir = out_dir.join(name.replace("::", "."));
    let mut ctx = PhaseContext::new(rig, &dir);
    for m in (scenario.measurements)(limits) {
        ctx.declare(m);
    }
    for m in multirx::session_measurements(limits, scenario.name) {
        ctx.declare(m);
    }
    ctx.log(scenario.summary);
    let result = MultirxSession::start(rig, mode, scenario.options, &dir).and_then(|session| {
        let result = (scenario.run)(&session, &mut ctx, limits);
        let recorded = multirx::record_session(&session, &mut ctx, limits, scenario.name);
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
    });
    let error = result.err().map(|e| format!("{e:#}"));
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

fn whole_run_measurements(l: &Limits) -> Vec<Measurement> {
    vec![
        Measurement::new(l.name("max_output_gap_ms"), "ms")
            .describe(format!(
                "{}, over every scenario of this mode",
                multirx::OUTPUT_GAP
            ))
            .at_most(l.max_gap_ms()),
        Measurement::new(l.name("fc_max_gap_ms"), "ms")
            .describe(format!(
                "{}, over every scenario of this mode",
                multirx::FC_GAP
            ))
            .at_most(l.max_fc_gap_ms()),
        Measurement::new(l.name("rc_losses"), "")
            .describe("RC losses PX4 would have declared over every scenario of this mode")
            .equal_to(0.0),
    ]
}

/// Folds the per-scenario session measurements of one mode into whole-run ones.
fn whole_run_trial(rig: &Arc<RigFile>, phases: &Phases, mode: Mode, limits: Limits) -> Trial {
    let name = format!("multirx::{}::whole_run", mode.as_str());
    let (rig, phases) = (rig.clone(), phases.clone());
    Trial::test(name.clone(), move || {
        let started = now_rfc3339();
        let mut ctx = PhaseContext::new(&rig, Path::new(""));
        for m in whole_run_measurements(&limits) {
            ctx.declare(m);
        }
        let prefix = format!("multirx::{}::", mode.as_str());
        let (mut gap, mut fc_gap, mut losses, mut count) = (0.0f64, 0.0f64, 0.0, 0usize);
        for phase in phases
            .lock()
            .unwrap()
            .iter()
            .filter(|p| p.name.starts_with(&prefix))
        {
            for m in &phase.measurements {
                let Some(v) = m.value else { continue };
                if m.name.ends_with(".max_output_gap_ms") {
                    gap = gap.max(v);
                    count += 1;
                } else if m.name.ends_with(".fc_max_gap_ms") {
                    fc_gap = fc_gap.max(v);
                } else if m.name.ends_with(".rc_losses") {
                    losses += v;
                }
            }
        }
        let record = if count == 0 {
            let (measurements, _, _) = ctx.into_parts();
            PhaseRecord::skipped(&name, started, measurements, "no scenario of this mode ran")
        } else {
            ctx.log(format!("{count} scenarios"));
            ctx.record(&limits.name("max_output_gap_ms"), gap);
            ctx.record(&limits.name("fc_max_gap_ms"), fc_gap);
            ctx.record(&limits.name("rc_losses"), losses);
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

fn devices(rig: &RigFile) -> Vec<DeviceIdentity> {
    let Some(section) = &rig.multirx else {
        return Vec::new();
    };
    let (kind, description, digest) = match &section.device.setup {
        DeviceSetup::Emulated { program } => {
            let path = program.clone().or_else(|| {
                std::env::current_exe()
                    .ok()
                    .map(|e| e.with_file_name("multirx-emu"))
            });
            let digest = path.as_deref().and_then(|p| sha256_file(p).ok());
            (
                "emulated",
                format!("multirx-emu (multirx-core {})", env!("CARGO_PKG_VERSION")),
                digest,
            )
        }
        DeviceSetup::Board(board) => (
            "board",
            format!(
                "MultiRX SAMD21 board, chip {}, probe {}",
                board.chip, board.probe
            ),
            None,
        ),
    };
    vec![DeviceIdentity {
        role: "multirx".into(),
        kind: kind.into(),
        description,
        port: Some(section.ports.fc.to_string()),
        firmware_sha256: digest,
    }]
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
