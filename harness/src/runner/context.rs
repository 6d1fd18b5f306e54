//! What a scenario writes into while it runs: its measurements (declared up
//! front, so an SLA never measured shows as unset, and recorded through their
//! handles), log lines and evidence files.

use std::path::{Path, PathBuf};

use crate::measurement::{Declarations, Handle, Measurement};
use crate::rigfile::RigFile;

/// A file kept as evidence: label, path, media type.
pub type Evidence = (String, PathBuf, String);

pub struct PhaseContext<'a> {
    pub rig: &'a RigFile,
    /// This phase's own folder inside the output folder.
    pub dir: PathBuf,
    measurements: Declarations,
    log: Vec<String>,
    files: Vec<Evidence>,
}

impl<'a> PhaseContext<'a> {
    /// A phase with the measurements it declared; a `[limits]` entry in the
    /// rig file replaces a measurement's built-in limits.
    pub fn new(rig: &'a RigFile, dir: &Path, mut measurements: Declarations) -> Self {
        measurements.override_limits(|name, builtin| rig.limits_for(name, builtin));
        PhaseContext {
            rig,
            dir: dir.to_path_buf(),
            measurements,
            log: Vec::new(),
            files: Vec::new(),
        }
    }

    /// Records the value of a declared measurement.
    ///
    /// # Panics
    /// If `m` was declared for another phase: a scenario bug, not a device
    /// failure.
    pub fn record(&mut self, m: Handle, value: f64) {
        let m = self.measurements.record(m, value);
        let line = format!("{} = {} ({})", m.name, m.render_value(), m.outcome);
        tracing::info!("{line}");
        self.log.push(line);
    }

    /// Adds a remark to a declared measurement (e.g. how it was measured).
    pub fn annotate(&mut self, m: Handle, note: &str) {
        self.measurements.annotate(m, note);
    }

    pub fn log(&mut self, line: impl Into<String>) {
        let line = line.into();
        tracing::debug!("{line}");
        self.log.push(line);
    }

    /// Keeps a file as evidence.
    pub fn attach(&mut self, name: impl Into<String>, path: PathBuf, media_type: &str) {
        self.files.push((name.into(), path, media_type.to_string()));
    }

    pub fn into_parts(self) -> (Vec<Measurement>, Vec<String>, Vec<Evidence>) {
        (self.measurements.into_measurements(), self.log, self.files)
    }

    pub fn measurements(&self) -> &[Measurement] {
        self.measurements.measurements()
    }
}
