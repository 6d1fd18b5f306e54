//! The run record as the run goes: saved (with the reports rendered from it) when the run
//! opens, after each phase, and when it is finalised or interrupted. Once interrupted it is
//! final: a phase that ends after the signal (its programs killed under it) is not added, and
//! the run's end does not overwrite it.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use anyhow::{Context, Result};

use crate::record::{DeviceIdentity, PhaseRecord, RunOutcome, RunRecord, now_rfc3339};
use crate::report::{self, ReportPaths};

/// Locks `mutex` even if a phase panicked while holding it: the data is a
/// list that a panic leaves whole.
pub(crate) fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The run record as it grows, shared by the trials and the interrupt handler.
#[derive(Clone)]
pub struct LiveRecord(Arc<Live>);

struct Live {
    out_dir: PathBuf,
    state: Mutex<LiveState>,
}

struct LiveState {
    record: RunRecord,
    /// The phases running now, in the order they began: name, start (RFC 3339) and clock.
    /// Several when phases run side by side.
    running: Vec<(String, String, Instant)>,
    /// Saved to disk as it changes: after [`LiveRecord::open`], until final.
    saving: bool,
    /// The signal that interrupted the run, once one has.
    interrupted: Option<&'static str>,
}

/// How [`LiveRecord::finish`] found the run.
pub enum Finished {
    /// The run ended by itself; the record is final and saved.
    Ended(Box<(RunRecord, ReportPaths)>),
    /// A signal interrupted it first: the record was finalised then, and the interrupt
    /// handler ends the process.
    Interrupted,
}

impl LiveRecord {
    /// A record of a run that has not started: nothing is saved until [`LiveRecord::open`].
    pub(crate) fn new(record: RunRecord, out_dir: &Path) -> Self {
        LiveRecord(Arc::new(Live {
            out_dir: out_dir.to_path_buf(),
            state: Mutex::new(LiveState {
                record,
                running: Vec::new(),
                saving: false,
                interrupted: None,
            }),
        }))
    }

    /// Starts the run: saves the record as `running`, replacing any earlier
    /// run's, so what is in the folder is never mistaken for this run's verdict.
    pub(crate) fn open(&self) -> Result<()> {
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

    /// A phase starts: if the run is interrupted before it ends, it is recorded as interrupted.
    pub(crate) fn begin(&self, name: &str) {
        let mut state = lock(&self.0.state);
        if !state.running.iter().any(|(n, _, _)| n == name) {
            state
                .running
                .push((name.to_owned(), now_rfc3339(), Instant::now()));
        }
    }

    /// A phase ended: kept, and the record (still `running`) saved. After an interrupt the
    /// record is final and the phase is dropped: it ended because its programs were killed.
    pub(crate) fn push(&self, phase: PhaseRecord) {
        let mut state = lock(&self.0.state);
        if state.interrupted.is_some() {
            return;
        }
        state.running.retain(|(n, _, _)| *n != phase.name);
        state.record.phases.push(phase);
        if state.saving {
            state.record.ended = now_rfc3339();
            if let Err(e) = report::write_all(&state.record, &self.0.out_dir) {
                eprintln!("rig: warning: cannot save the run record: {e}");
            }
        }
    }

    /// Reads the phases ended so far.
    pub fn with_phases<R>(&self, f: impl FnOnce(&[PhaseRecord]) -> R) -> R {
        f(&lock(&self.0.state).record.phases)
    }

    /// The run ended: the outcome is judged from the phases (an error if the
    /// trial runner saw a failure no phase recorded), the record saved for good.
    /// If a signal came first, the record stays as the interrupt left it.
    pub(crate) fn finish(
        &self,
        devices: Vec<DeviceIdentity>,
        runner_failed: bool,
    ) -> Result<Finished> {
        let mut state = lock(&self.0.state);
        if state.interrupted.is_some() {
            return Ok(Finished::Interrupted);
        }
        let record = &mut state.record;
        record.devices = devices;
        record.ended = now_rfc3339();
        record.outcome = match RunOutcome::from_phases(&record.phases) {
            RunOutcome::Pass if runner_failed => RunOutcome::Error,
            outcome => outcome,
        };
        let paths = report::write_all(record, &self.0.out_dir)?;
        state.saving = false;
        Ok(Finished::Ended(Box::new((state.record.clone(), paths))))
    }

    /// The rig was stopped by `signal`: every phase in progress is recorded as interrupted
    /// (once) and the record saved as `interrupted`; nothing is saved after.
    pub(crate) fn interrupt(
        &self,
        devices: Vec<DeviceIdentity>,
        signal: &'static str,
    ) -> Result<ReportPaths> {
        let mut state = lock(&self.0.state);
        state.saving = false;
        state.interrupted = Some(signal);
        let why = format!("interrupted by {signal}");
        for (name, started, clock) in std::mem::take(&mut state.running) {
            let phase =
                PhaseRecord::interrupted(name, started, clock.elapsed().as_secs_f64(), why.clone());
            state.record.phases.push(phase);
        }
        let record = &mut state.record;
        record.devices = devices;
        record.ended = now_rfc3339();
        record.outcome = RunOutcome::Interrupted;
        Ok(report::write_all(record, &self.0.out_dir)?)
    }
}
