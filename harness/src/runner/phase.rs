//! What a device module hands the runner: its [`Phase`]s, each a name, the measurements it
//! may record and a body that turns into a [`PhaseRecord`]. The runner knows no device; a
//! device knows no trial runner.

use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::Result;

use super::context::PhaseContext;
use super::live::LiveRecord;
use crate::measurement::Declarations;
use crate::record::{Attachment, DeviceIdentity, PhaseRecord, now_rfc3339};
use crate::rigfile::RigFile;

/// A device under test, as the runner sees it.
pub trait Device: Send + Sync {
    /// Every phase the rig file asks of this device, in the order they run.
    fn phases(&self) -> Result<Vec<Phase>>;

    /// What is under test, for the record; asked again when the run ends (a phase may have
    /// flashed a new image).
    fn identities(&self) -> Vec<DeviceIdentity>;
}

type Body = Box<dyn FnOnce(&PhaseEnv) -> PhaseRecord + Send>;

/// One phase of a run.
pub struct Phase {
    pub(crate) name: String,
    /// The flat names of the measurements it may record (the `[limits]` check, the trace
    /// matrix).
    pub(crate) declared: Vec<String>,
    pub(crate) side_by_side: Option<SideBySideGroup>,
    pub(crate) body: Body,
}

/// Phases that spend their time waiting on the wall clock and share nothing (no device,
/// no port) may run side by side, at most `width` of one group at once.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SideBySideGroup {
    pub name: &'static str,
    pub width: usize,
}

/// What a phase's body is given when it runs.
#[derive(Clone)]
pub struct PhaseEnv {
    pub rig: Arc<RigFile>,
    /// The run's output folder; each phase writes in its own folder below it.
    pub out_dir: PathBuf,
    pub(crate) live: LiveRecord,
}

impl PhaseEnv {
    /// Reads the phases ended so far in this run.
    pub fn with_phases<R>(&self, f: impl FnOnce(&[PhaseRecord]) -> R) -> R {
        self.live.with_phases(f)
    }
}

impl Phase {
    /// A phase that takes the `measurements` it declared, runs `body` with the phase's context
    /// (its folder is [`phase_dir`]), and turns what it recorded, logged and attached into its
    /// record; an error or a panic makes it an `error` phase that keeps all of that.
    pub fn measured(
        name: String,
        summary: impl Into<String>,
        measurements: Declarations,
        body: impl FnOnce(&mut PhaseContext) -> Result<()> + Send + 'static,
    ) -> Phase {
        let declared = names(&measurements);
        let summary = summary.into();
        let phase = name.clone();
        Phase {
            name,
            declared,
            side_by_side: None,
            body: Box::new(move |env: &PhaseEnv| {
                run_phase(&env.rig, &env.out_dir, &phase, &summary, measurements, body)
            }),
        }
    }

    /// A phase that makes its own record (e.g. from the phases before it) with the
    /// `measurements` it declared.
    pub fn custom(
        name: String,
        measurements: Declarations,
        body: impl FnOnce(&PhaseEnv, Declarations) -> PhaseRecord + Send + 'static,
    ) -> Phase {
        Phase {
            name,
            declared: names(&measurements),
            side_by_side: None,
            body: Box::new(move |env: &PhaseEnv| body(env, measurements)),
        }
    }

    /// Lets this phase run side by side with the other selected phases of `group`.
    pub fn side_by_side(mut self, group: SideBySideGroup) -> Phase {
        self.side_by_side = Some(group);
        self
    }

    /// The phase's name: `device::suite::scenario`.
    pub fn name(&self) -> &str {
        &self.name
    }
}

/// The flat names of declared measurements.
fn names(declared: &Declarations) -> Vec<String> {
    declared
        .measurements()
        .iter()
        .map(|m| m.name.clone())
        .collect()
}

/// A phase's own folder in the output folder: `device::suite::scenario` →
/// `device.suite.scenario`.
pub fn phase_dir(out_dir: &Path, name: &str) -> PathBuf {
    out_dir.join(name.replace("::", "."))
}

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

/// The error a panicking phase is recorded with.
pub(crate) fn panicked(payload: &(dyn Any + Send)) -> String {
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".to_owned());
    format!("panicked: {message}")
}
