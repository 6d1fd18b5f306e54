//! The rig description: which ports, devices, fixtures and limits a run uses.
//!
//! One rig file per bench (or `rigs/emulated.toml` for CI); the scenarios are
//! the same everywhere, only this file changes. [`RigFile::load`] checks the
//! whole file before anything runs: unknown keys are rejected (a typo must not
//! silently fall back to a default), values are range-checked, paths are made
//! absolute relative to the rig file's folder, and every [`RigFileError`] names the
//! file, line and dotted key.
//!
//! This module reads what every rig has (`[rig]`, `[fixtures]`, `[radios]`, `[autopilots]`,
//! `[limits]`);
//! each device's section is its own module's (`rigfile.rs` in the device's folder), and the
//! device registry ([`crate::devices`]) says which top-level tables are devices.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::fs;
use std::io;
use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Deserializer};
use toml::de::DeTable;

use crate::measurement::Limits;

mod autopilots;
mod error;
mod radios;
mod schema;

pub use error::RigFileError;
pub(crate) use error::dotted;
pub(crate) use error::{Location, Locator};
use schema::RawFile;

/// Output folder used when the rig file names none, relative to the current
/// directory.
pub const DEFAULT_OUTPUT: &str = "rig-report";
/// Python interpreter used for fixtures when the rig file names none.
pub const DEFAULT_PYTHON: &str = "python3";
/// Fixture folder used when the rig file names none, relative to the rig file.
pub const DEFAULT_FIXTURES_DIR: &str = "../fixtures";
/// A loaded and checked rig file.
#[derive(Debug, Clone, PartialEq)]
pub struct RigFile {
    /// Absolute path of the rig file.
    pub path: PathBuf,
    /// `[rig]`.
    pub rig: RigSection,
    /// `[fixtures]`.
    pub fixtures: FixturesSection,
    /// `[radios]`: emulated radios by name, checked against the model.
    pub radios: BTreeMap<String, harness_radio::RadioSetup>,
    /// `[autopilots]`: what can play the flight controller, by name.
    pub autopilots: BTreeMap<String, crate::driver::autopilot::AutopilotSpec>,
    /// Each device's section, checked by the device's module.
    pub devices: crate::devices::Sections,
    /// `[limits]`: overrides of built-in SLA limits, by measurement name.
    pub limits: BTreeMap<String, Limits>,
    /// Where each `[limits]` key is, for [`RigFile::check_limit_names`].
    limit_locations: BTreeMap<String, Location>,
}

/// `[rig]`: what this rig is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RigSection {
    /// Short name, shown in reports (non-empty).
    pub name: String,
    /// What the rig is, for the reader of a report.
    pub description: String,
    /// Default output folder, absolute; `None` uses [`DEFAULT_OUTPUT`]
    /// (see [`RigFile::output_dir`]).
    pub output: Option<PathBuf>,
    /// Lock file of the bench (absolute): a run holds an exclusive `flock` on it, so two jobs
    /// never drive the same hardware at once (see `runner::lock`).
    pub lock: Option<PathBuf>,
}

/// `[fixtures]`: the Python programs that play peers (pymavlink, receivers).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FixturesSection {
    /// Interpreter: a bare name (`python3`) is looked up on `PATH`; anything
    /// with a `/` was resolved relative to the rig file.
    pub python: PathBuf,
    /// Absolute folder holding the fixture scripts.
    pub dir: PathBuf,
}

/// A serial line: a pty pair the rig makes, or a device path.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum PortSpec {
    /// `"pty"`: the rig creates a pty pair and hands one end to the device.
    Pty,
    /// A device path such as `/dev/ttyUSB0` (absolute after load).
    Path(PathBuf),
}

impl PortSpec {
    /// Parses `"pty"` or a device path. A path must contain a `/`, so that a
    /// misspelt `"PTY"` or a bare `"ttyUSB0"` is reported, not opened.
    pub fn parse(s: &str) -> Result<Self, String> {
        match s {
            "pty" => Ok(PortSpec::Pty),
            "" => {
                Err("empty port: expected \"pty\" or a device path such as \"/dev/ttyUSB0\"".into())
            }
            s if s.contains('/') => Ok(PortSpec::Path(PathBuf::from(s))),
            s => Err(format!(
                "port \"{s}\" is neither \"pty\" nor a device path (a path contains '/', e.g. \"/dev/{s}\")"
            )),
        }
    }
}

impl<'de> Deserialize<'de> for PortSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        PortSpec::parse(&s).map_err(serde::de::Error::custom)
    }
}

impl fmt::Display for PortSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PortSpec::Pty => f.write_str("pty"),
            PortSpec::Path(p) => write!(f, "{}", p.display()),
        }
    }
}

impl RigFile {
    /// Reads and checks a rig file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, RigFileError> {
        let path = path.as_ref();
        let text = fs::read_to_string(path).map_err(|source| RigFileError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_str(&text, path)
    }

    /// Checks rig file text; `path` is where it came from: relative paths in
    /// the text are resolved against its folder, and errors name it. The
    /// MultiRX configs it names are read from disk.
    pub fn from_str(text: &str, path: impl AsRef<Path>) -> Result<Self, RigFileError> {
        Self::from_str_with(text, path, &|p| fs::read_to_string(p))
    }

    /// Like [`RigFile::from_str`], reading the files device sections name (a MultiRX config)
    /// with `read_config` (tests give files that are not on disk).
    pub fn from_str_with(
        text: &str,
        path: impl AsRef<Path>,
        read_config: &dyn Fn(&Path) -> io::Result<String>,
    ) -> Result<Self, RigFileError> {
        let given = path.as_ref();
        let syntax = |e: toml::de::Error, field: Option<String>| {
            let at = Location::of_offset(text, e.span().map_or(0, |s| s.start));
            RigFileError::Syntax {
                path: given.to_path_buf(),
                line: at.line,
                column: at.column,
                field,
                message: e.message().trim_end().to_owned(),
            }
        };
        let doc = DeTable::parse(text).map_err(|e| syntax(e, None))?;
        let loc = Locator::new(text, doc.get_ref());
        let located = |e: toml::de::Error| {
            let field = e.span().and_then(|s| loc.field_at(s.start));
            syntax(e, field)
        };
        let (shared, devices) = split_sections(&doc).map_err(|(key, span)| {
            let at = Location::of_offset(text, span.start);
            let mut known = SHARED_SECTIONS.to_vec();
            known.extend(crate::devices::SECTIONS);
            RigFileError::Syntax {
                path: given.to_path_buf(),
                line: at.line,
                column: at.column,
                field: Some(key.clone()),
                message: format!(
                    "unknown field `{key}`, expected one of {}",
                    known
                        .iter()
                        .map(|k| format!("`{k}`"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            }
        })?;
        let raw = RawFile::deserialize(toml::Deserializer::from(shared)).map_err(located)?;
        let raw_devices =
            crate::devices::RawSections::deserialize(toml::Deserializer::from(devices))
                .map_err(located)?;
        let file = absolute_file(given);
        let base = file.parent().map(Path::to_path_buf).unwrap_or_default();
        let check = Checker {
            given,
            loc: &loc,
            base: &base,
            read_config,
        };
        check.rig_file(raw, raw_devices, file)
    }

    /// The output folder: `rig.output`, else [`DEFAULT_OUTPUT`] in the
    /// current directory.
    pub fn output_dir(&self) -> PathBuf {
        self.rig
            .output
            .clone()
            .unwrap_or_else(|| PathBuf::from(DEFAULT_OUTPUT))
    }

    /// The limits for measurement `name`: the rig file's override, else the
    /// built-in ones.
    pub fn limits_for(&self, name: &str, builtin: Limits) -> Limits {
        self.limits.get(name).copied().unwrap_or(builtin)
    }

    /// Rejects `[limits]` keys that name no known measurement, since a
    /// misspelt override would otherwise leave the built-in limit in force
    /// without anyone noticing.
    pub fn check_limit_names<'a>(
        &self,
        known: impl IntoIterator<Item = &'a str>,
    ) -> Result<(), RigFileError> {
        let known: BTreeSet<&str> = known.into_iter().collect();
        match self.limits.keys().find(|k| !known.contains(k.as_str())) {
            None => Ok(()),
            Some(name) => {
                let at = self.limit_locations[name];
                Err(RigFileError::Invalid {
                    path: self.path.clone(),
                    line: at.line,
                    column: at.column,
                    field: dotted(&["limits", name]),
                    message: format!("no measurement is named \"{name}\""),
                })
            }
        }
    }
}

/// The top-level tables every rig file may have, whatever its devices.
const SHARED_SECTIONS: [&str; 5] = ["rig", "fixtures", "radios", "autopilots", "limits"];

type Table<'i> = toml::Spanned<DeTable<'i>>;

/// Splits the document into the shared tables and the devices' ones; a top-level key that is
/// neither is returned with its span.
fn split_sections<'i>(
    doc: &Table<'i>,
) -> Result<(Table<'i>, Table<'i>), (String, std::ops::Range<usize>)> {
    let (mut shared, mut devices) = (DeTable::new(), DeTable::new());
    for (key, value) in doc.get_ref() {
        let name: &str = key.get_ref();
        if SHARED_SECTIONS.contains(&name) {
            shared.insert(key.clone(), value.clone());
        } else if crate::devices::SECTIONS.contains(&name) {
            devices.insert(key.clone(), value.clone());
        } else {
            return Err((name.to_owned(), key.span()));
        }
    }
    Ok((
        toml::Spanned::new(doc.span(), shared),
        toml::Spanned::new(doc.span(), devices),
    ))
}

/// Turns the raw file into checked public types, or the first error; device modules check
/// their sections with it (`rigfile.rs` in each device's folder).
pub(crate) struct Checker<'a> {
    pub(crate) given: &'a Path,
    pub(crate) loc: &'a Locator<'a>,
    pub(crate) base: &'a Path,
    pub(crate) read_config: &'a dyn Fn(&Path) -> io::Result<String>,
}

impl Checker<'_> {
    pub(crate) fn invalid(&self, at: &[&str], message: impl Into<String>) -> RigFileError {
        self.invalid_named(at, dotted(at), message)
    }

    pub(crate) fn invalid_named(
        &self,
        at: &[&str],
        field: String,
        message: impl Into<String>,
    ) -> RigFileError {
        let l = self.loc.locate(at);
        RigFileError::Invalid {
            path: self.given.to_path_buf(),
            line: l.line,
            column: l.column,
            field,
            message: message.into(),
        }
    }

    pub(crate) fn resolve(&self, p: &Path) -> PathBuf {
        normalize(&self.base.join(p))
    }

    /// A program name stays as is (found on `PATH`); a path is resolved.
    pub(crate) fn resolve_program(&self, p: &str) -> PathBuf {
        if p.contains('/') {
            self.resolve(Path::new(p))
        } else {
            PathBuf::from(p)
        }
    }

    fn rig_file(
        &self,
        raw: RawFile,
        raw_devices: crate::devices::RawSections,
        path: PathBuf,
    ) -> Result<RigFile, RigFileError> {
        if raw.rig.name.trim().is_empty() {
            return Err(self.invalid(&["rig", "name"], "empty; give the rig a short name"));
        }
        let rig = RigSection {
            name: raw.rig.name,
            description: raw.rig.description,
            output: raw.rig.output.map(|p| self.resolve(&p)),
            lock: raw.rig.lock.map(|p| self.resolve(&p)),
        };
        let python = match raw.fixtures.python.as_deref() {
            None => PathBuf::from(DEFAULT_PYTHON),
            Some("") => {
                return Err(self.invalid(&["fixtures", "python"], "empty; e.g. \"python3\""));
            }
            Some(p) => self.resolve_program(p),
        };
        let fixtures = FixturesSection {
            python,
            dir: self.resolve(
                raw.fixtures
                    .dir
                    .as_deref()
                    .unwrap_or(Path::new(DEFAULT_FIXTURES_DIR)),
            ),
        };
        let radios = self.radios(raw.radios)?;
        let autopilots = self.autopilots(raw.autopilots)?;
        let devices = raw_devices.check(self, &radios, &autopilots)?;
        let mut limit_locations = BTreeMap::new();
        for (name, limits) in &raw.limits {
            let at = ["limits", name.as_str()];
            if limits.is_empty() {
                return Err(self.invalid(
                    &at,
                    "no limit given; set min, max, marginal_min or marginal_max",
                ));
            }
            limits.validate().map_err(|e| self.invalid(&at, e))?;
            limit_locations.insert(name.clone(), self.loc.locate(&at));
        }
        Ok(RigFile {
            path,
            rig,
            fixtures,
            radios,
            autopilots,
            devices,
            limits: raw.limits,
            limit_locations,
        })
    }
}

/// The rig file's absolute path, with its folder's symlinks resolved when
/// the folder exists, so that `../fixtures` from a symlinked `rigs/` means
/// the folder next to the real one, as the shell would open it.
fn absolute_file(given: &Path) -> PathBuf {
    let abs = normalize(&std::path::absolute(given).unwrap_or_else(|_| given.to_path_buf()));
    match (abs.parent(), abs.file_name()) {
        (Some(dir), Some(name)) => fs::canonicalize(dir)
            .map(|dir| dir.join(name))
            .unwrap_or(abs),
        _ => abs,
    }
}

/// Removes `.` and folds `..` without touching the file system, so paths in
/// reports read `/work/main/fixtures`, not `/work/main/rigs/../fixtures`.
fn normalize(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => match out.components().next_back() {
                Some(Component::Normal(_)) => {
                    out.pop();
                }
                Some(Component::RootDir | Component::Prefix(_)) => {}
                _ => out.push(".."),
            },
            other => out.push(other),
        }
    }
    out
}

#[cfg(test)]
mod tests;
