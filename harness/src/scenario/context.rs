//! What a scenario writes into while it runs: its measurements (declared up
//! front so an SLA never measured shows as unset), log lines and evidence files.

use std::path::{Path, PathBuf};

use crate::measurement::Measurement;
use crate::rigfile::RigFile;

/// A file kept as evidence: label, path, media type.
pub type Evidence = (String, PathBuf, String);

pub struct PhaseContext<'a> {
    pub rig: &'a RigFile,
    /// This phase's own folder inside the output folder.
    pub dir: PathBuf,
    measurements: Vec<Measurement>,
    log: Vec<String>,
    files: Vec<Evidence>,
}

impl<'a> PhaseContext<'a> {
    pub fn new(rig: &'a RigFile, dir: &Path) -> Self {
        PhaseContext {
            rig,
            dir: dir.to_path_buf(),
            measurements: Vec::new(),
            log: Vec::new(),
            files: Vec::new(),
        }
    }

    /// Declares a measurement; a `[limits]` entry in the rig file replaces its limits.
    pub fn declare(&mut self, m: Measurement) {
        let limits = self.rig.limits_for(&m.name, m.limits);
        self.measurements.push(m.with_limits(limits));
    }

    /// Records the value of a declared measurement.
    ///
    /// # Panics
    /// If `name` was not declared: a scenario bug, not a device failure.
    pub fn record(&mut self, name: &str, value: f64) {
        let m = self
            .measurements
            .iter_mut()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("measurement {name} recorded but never declared"));
        let outcome = m.record(value);
        let line = format!("{name} = {} ({outcome})", m.render_value());
        tracing::info!("{line}");
        self.log.push(line);
    }

    /// Adds a remark to a declared measurement (e.g. how it was measured).
    pub fn annotate(&mut self, name: &str, note: &str) {
        if let Some(m) = self.measurements.iter_mut().find(|m| m.name == name) {
            m.annotate(note);
        }
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
        (self.measurements, self.log, self.files)
    }

    pub fn measurements(&self) -> &[Measurement] {
        &self.measurements
    }
}
