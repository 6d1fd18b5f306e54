//! Runs a rig's scenarios as libtest-mimic trials (so `cargo test`-style
//! filters, `--list` and `--exact` work), one phase record per trial, and
//! keeps the run record (`results.json`, with the reports rendered from it)
//! true at every moment: saved as `running` before the first phase, again as
//! each phase ends, and finalised at the end; a phase that panics is recorded
//! as an error; SIGINT or SIGTERM finalises it as `interrupted`, ends every
//! program the rig started and exits 128 + the signal's number.

use std::collections::BTreeMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use libtest_mimic::{Arguments, Failed, Trial};

use crate::driver::process;
use crate::measurement::Outcome;
use crate::record::{
    DeviceIdentity, PhaseOutcome, PhaseRecord, RigIdentity, RunOutcome, RunRecord, ToolIdentity,
    now_rfc3339,
};
use crate::report::ReportPaths;
use crate::rigfile::RigFile;
use live::{Finished, LiveRecord};
use side_by_side::SideBySide;

pub mod context;
pub mod interrupt;
pub mod live;
pub mod lock;
mod phase;
mod side_by_side;

pub use context::PhaseContext;
pub use phase::{Device, Phase, PhaseEnv, SideBySideGroup, phase_dir};

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

/// No phase is selected: nothing runs and nothing is written (exit code 2).
#[derive(Debug, thiserror::Error)]
#[error("{what}: nothing to run (`rig run {rig} --list` names the phases)")]
pub struct NothingSelected {
    /// What selected nothing: the filter, or the rig file.
    pub what: String,
    /// The rig file, for the hint.
    pub rig: String,
}

/// Runs every phase `devices` have for the rig file.
pub fn run(
    rig: Arc<RigFile>,
    devices: Vec<Box<dyn Device>>,
    options: RunOptions,
) -> Result<RunResult> {
    let out_dir = options.out_dir.clone();
    let live = LiveRecord::new(
        new_record(&rig, git_commit(), identities(&devices))?,
        &out_dir,
    );
    let Plan {
        trials,
        known_names,
        groups,
    } = plan(&rig, &devices, &live, &out_dir)?;
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
    for group in groups.values() {
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
    live.open()?;
    let devices = Arc::new(devices);
    {
        let (live, devices) = (live.clone(), devices.clone());
        interrupt::on_interrupt(move |signal, name| {
            eprintln!("\nrig: {name}: recording the run as interrupted, stopping its programs");
            match live.interrupt(identities(&devices), name) {
                Ok(paths) => eprintln!("rig: interrupted; report: {}", paths.results.display()),
                Err(e) => eprintln!("rig: error: cannot save the interrupted record: {e:#}"),
            }
            process::kill_all(Duration::from_millis(300));
            std::process::exit(128 + signal);
        })
        .context("cannot handle SIGINT/SIGTERM")?;
    }
    let conclusion = libtest_mimic::run(&args, trials);
    match live.finish(identities(&devices), conclusion.has_failed())? {
        Finished::Ended(ended) => {
            let (record, paths) = *ended;
            Ok(RunResult {
                record: Some(record),
                paths: Some(paths),
            })
        }
        // The phases ended because a signal killed their programs: the interrupt handler
        // has saved the record and ends the process with the signal's exit code.
        Finished::Interrupted => interrupt::wait_for_exit(),
    }
}

/// The record of a run of `rig` that has not started.
fn new_record(
    rig: &RigFile,
    commit: Option<String>,
    devices: Vec<DeviceIdentity>,
) -> Result<RunRecord> {
    Ok(RunRecord {
        tool: ToolIdentity::this_build(commit),
        rig: RigIdentity::of_file(rig.rig.name.clone(), &rig.path)?,
        devices,
        started: String::new(),
        ended: String::new(),
        outcome: RunOutcome::Running,
        phases: Vec::new(),
    })
}

/// Every device's identity, in the registry's order.
fn identities(devices: &[Box<dyn Device>]) -> Vec<DeviceIdentity> {
    devices.iter().flat_map(|d| d.identities()).collect()
}

/// What a rig file asks to run.
struct Plan {
    /// Every phase, as a trial.
    trials: Vec<Trial>,
    /// The flat names of the measurements they declare.
    known_names: Vec<String>,
    /// The groups of phases that run side by side, by name.
    groups: BTreeMap<&'static str, Arc<SideBySide>>,
}

/// Every phase of every device, as trials.
fn plan(
    rig: &Arc<RigFile>,
    devices: &[Box<dyn Device>],
    live: &LiveRecord,
    out_dir: &Path,
) -> Result<Plan> {
    let env = PhaseEnv {
        rig: rig.clone(),
        out_dir: out_dir.to_path_buf(),
        live: live.clone(),
    };
    let mut trials = Vec::new();
    let mut known_names = Vec::new();
    let mut groups: BTreeMap<&'static str, Arc<SideBySide>> = BTreeMap::new();
    for device in devices {
        for phase in device.phases()? {
            known_names.extend(phase.declared);
            let name = phase.name;
            let (body, env) = (phase.body, env.clone());
            let trial: Box<dyn FnOnce() -> PhaseRecord + Send> = match phase.side_by_side {
                None => Box::new(move || body(&env)),
                Some(group) => {
                    let phase = name.clone();
                    // The phase counts as running from when a worker starts it.
                    let job = move || {
                        env.live.begin(&phase);
                        body(&env)
                    };
                    let group = groups
                        .entry(group.name)
                        .or_insert_with(|| SideBySide::new(group.width));
                    Box::new(group.add(name.clone(), job))
                }
            };
            trials.push(phase_trial(live, name, trial));
        }
    }
    Ok(Plan {
        trials,
        known_names,
        groups,
    })
}

/// The flat names of every measurement the phases of `devices` declare (the trace matrix
/// checks its requirements against them). Runs nothing and writes nothing.
pub fn declared_names(rig: &Arc<RigFile>, devices: &[Box<dyn Device>]) -> Result<Vec<String>> {
    let live = LiveRecord::new(new_record(rig, None, Vec::new())?, Path::new(""));
    let mut names = plan(rig, devices, &live, Path::new(""))?.known_names;
    names.sort();
    names.dedup();
    Ok(names)
}

/// One trial: the phase `body` runs with the run told it started, and its
/// record is kept even if it panics (as an error naming the panic).
fn phase_trial(
    live: &LiveRecord,
    name: String,
    body: impl FnOnce() -> PhaseRecord + Send + 'static,
) -> Trial {
    let live = live.clone();
    Trial::test(name.clone(), move || run_guarded(&live, &name, body))
}

fn run_guarded(
    live: &LiveRecord,
    name: &str,
    body: impl FnOnce() -> PhaseRecord,
) -> Result<(), Failed> {
    let started = now_rfc3339();
    let clock = Instant::now();
    live.begin(name);
    let record = catch_unwind(AssertUnwindSafe(body)).unwrap_or_else(|payload| {
        PhaseRecord::ran(
            name,
            started,
            clock.elapsed().as_secs_f64(),
            Vec::new(),
            Some(phase::panicked(payload.as_ref())),
        )
    });
    conclude(live, record)
}

/// Stores the phase and tells libtest-mimic how it went.
fn conclude(live: &LiveRecord, record: PhaseRecord) -> Result<(), Failed> {
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
    live.push(record);
    verdict
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

    fn open_run(dir: &Path) -> LiveRecord {
        let mut record = sample_record();
        record.phases.clear();
        let phases = LiveRecord::new(record, dir);
        phases.open().unwrap();
        phases
    }

    fn ended(finished: Finished) -> RunRecord {
        match finished {
            Finished::Ended(ended) => ended.0,
            Finished::Interrupted => panic!("the run was not interrupted"),
        }
    }

    fn saved(dir: &Path) -> RunRecord {
        RunRecord::load(&dir.join(crate::record::RESULTS_FILE)).unwrap()
    }

    /// Each saved phase's name and outcome.
    fn outcomes(record: &RunRecord) -> Vec<(&str, PhaseOutcome)> {
        record
            .phases
            .iter()
            .map(|p| (p.name.as_str(), p.outcome))
            .collect()
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
        let record = ended(phases.finish(Vec::new(), false).unwrap());
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
        let record = ended(phases.finish(Vec::new(), true).unwrap());
        assert_eq!(record.outcome, RunOutcome::Error);
    }

    #[test]
    fn a_failure_only_the_trial_runner_saw_makes_the_run_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let phases = open_run(dir.path());
        let record = ended(phases.finish(Vec::new(), true).unwrap());
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
        assert_eq!(
            outcomes(&record),
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

    #[test]
    fn an_interrupt_records_each_running_phase_once_and_the_run_never_ends_otherwise() {
        let dir = tempfile::tempdir().unwrap();
        let phases = open_run(dir.path());
        // Two phases side by side, one of them begun twice (its trial and its worker).
        phases.begin("a");
        phases.begin("b");
        phases.begin("a");
        phases.interrupt(Vec::new(), "SIGINT").unwrap();
        // Their programs killed, both end in errors after the signal: not recorded.
        for name in ["a", "b"] {
            phases.push(PhaseRecord::ran(
                name,
                now_rfc3339(),
                0.0,
                Vec::new(),
                Some("the fixture closed its output".into()),
            ));
        }
        assert!(matches!(
            phases.finish(Vec::new(), true).unwrap(),
            Finished::Interrupted
        ));
        let record = saved(dir.path());
        assert_eq!(record.outcome, RunOutcome::Interrupted);
        assert_eq!(
            outcomes(&record),
            [
                ("a", PhaseOutcome::Interrupted),
                ("b", PhaseOutcome::Interrupted)
            ]
        );
    }
}
