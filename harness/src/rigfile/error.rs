//! Rig file errors, and finding the line and dotted field they are about.

use std::io;
use std::ops::Range;
use std::path::PathBuf;

use toml::de::{DeTable, DeValue};

/// Why a rig file was rejected. Each variant's message starts with
/// `file:line:column:` so editors and CI logs can jump to the spot.
#[derive(Debug, thiserror::Error)]
pub enum RigFileError {
    /// The file could not be read (missing, unreadable, not UTF-8).
    #[error("{}: cannot read rig file", path.display())]
    Read {
        /// Path as given.
        path: PathBuf,
        /// The underlying IO error.
        #[source]
        source: io::Error,
    },
    /// Not TOML, or TOML not of the rig file's shape: a missing required key,
    /// a value of the wrong type, or an unknown key (often a typo, e.g.
    /// `recievers`), which the message names.
    #[error("{}:{line}:{column}: {}{message}", path.display(), field.as_deref().map(|f| format!("{f}: ")).unwrap_or_default())]
    Syntax {
        /// Path as given.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column, in characters.
        column: usize,
        /// Dotted key the error is in, when it can be told.
        field: Option<String>,
        /// What the TOML parser or deserializer said.
        message: String,
    },
    /// Well-formed, but a value is out of range or contradicts another
    /// (e.g. seven receivers, a mode without a config, a board-only key on
    /// an emulated device, limits with `min > max`).
    #[error("{}:{line}:{column}: {field}: {message}", path.display())]
    Invalid {
        /// Path as given.
        path: PathBuf,
        /// 1-based line of the key concerned (or of its nearest table when
        /// the key is missing).
        line: usize,
        /// 1-based column, in characters.
        column: usize,
        /// Dotted key, e.g. `rig.name` or a device section's key.
        field: String,
        /// What is wrong and what is accepted.
        message: String,
    },
    /// A device config file the rig file names cannot be read; the
    /// location is the rig file's key that names it.
    #[error("{}:{line}:{column}: {field}: cannot read {}: {source}", path.display(), config.display())]
    ConfigRead {
        /// The rig file, as given.
        path: PathBuf,
        line: usize,
        column: usize,
        /// The dotted key that names the config.
        field: String,
        /// The config file.
        config: PathBuf,
        #[source]
        source: io::Error,
    },
    /// A device config file is refused by the device's own checks (bad TOML, a value the
    /// device cannot fly with, a config that does not fit the board); its error starts with
    /// the config file's line and key.
    #[error("{}:{source} ({field} in {})", config.display(), path.display())]
    Config {
        /// The rig file, as given.
        path: PathBuf,
        /// The dotted key that names the config.
        field: String,
        /// The config file.
        config: PathBuf,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// Line and column of a spot in the rig file, 1-based.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Location {
    pub line: usize,
    pub column: usize,
}

impl Location {
    pub fn of_offset(text: &str, offset: usize) -> Self {
        let offset = offset.min(text.len());
        let before = text.get(..offset).unwrap_or(text);
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        Location {
            line: before.matches('\n').count() + 1,
            column: before[line_start..].chars().count() + 1,
        }
    }
}

/// Finds where dotted keys are in the parsed document, so errors found after
/// deserializing can name the right line.
pub(crate) struct Locator<'a> {
    text: &'a str,
    doc: &'a DeTable<'a>,
}

impl<'a> Locator<'a> {
    pub fn new(text: &'a str, doc: &'a DeTable<'a>) -> Self {
        Locator { text, doc }
    }

    /// Location of the key at `path`; if it is absent, of the nearest table
    /// on the way to it that is present (its `[header]`), else the file start.
    pub fn locate(&self, path: &[&str]) -> Location {
        let mut table = self.doc;
        let mut best: Range<usize> = 0..0;
        for (i, seg) in path.iter().enumerate() {
            let Some((key, value)) = table.iter().find(|(k, _)| k.get_ref() == seg) else {
                break;
            };
            if i + 1 == path.len() {
                best = key.span();
                break;
            }
            // A `[header]` table's value span is the header; an implicit one
            // (`a` in `[a.b]`) has the key's span.
            best = value.span();
            match value.get_ref() {
                DeValue::Table(t) => table = t,
                _ => break,
            }
        }
        Location::of_offset(self.text, best.start)
    }

    /// Dotted path of the innermost key whose key or value contains `offset`.
    pub fn field_at(&self, offset: usize) -> Option<String> {
        let mut path = Vec::new();
        let mut best = None;
        walk(self.doc, offset, &mut path, &mut best);
        best.map(|(_, field)| field)
    }
}

fn walk<'a>(
    table: &'a DeTable<'a>,
    offset: usize,
    path: &mut Vec<&'a str>,
    best: &mut Option<(usize, String)>,
) {
    let contains = |r: Range<usize>| r.contains(&offset);
    for (key, value) in table.iter() {
        path.push(key.get_ref());
        if (contains(key.span()) || contains(value.span()))
            && best.as_ref().is_none_or(|(depth, _)| *depth < path.len())
        {
            *best = Some((path.len(), dotted(path)));
        }
        if let DeValue::Table(t) = value.get_ref() {
            walk(t, offset, path, best);
        }
        path.pop();
    }
}

/// Joins keys with dots, quoting keys that themselves contain a dot or
/// space (`limits."dut.fast.handover_ms"`), as TOML would.
pub(crate) fn dotted(path: &[&str]) -> String {
    path.iter()
        .map(|k| {
            if !k.is_empty()
                && k.chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            {
                (*k).to_owned()
            } else {
                format!("\"{k}\"")
            }
        })
        .collect::<Vec<_>>()
        .join(".")
}
