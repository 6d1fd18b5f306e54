//! The trace matrix: every requirement (`harness/requirements.toml`) → the measurements that
//! cover it → their outcome in a saved run.
//!
//! A requirement is [`TraceOutcome::Uncovered`] when nothing the rig measures covers it: it is
//! never counted as passed. The file is checked at load against the measurement names the rig
//! file's phases declare ([`Requirements::check`]), so a renamed measurement cannot silently
//! leave a requirement covered by nothing.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::measurement::Outcome;
use crate::record::RunRecord;

/// The reviewed requirements file, relative to the repository root.
pub const REQUIREMENTS_FILE: &str = "harness/requirements.toml";

/// Errors loading or checking the requirements file.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// The file cannot be read.
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Not valid TOML, or a field is missing or unknown.
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    /// Two requirements share an id.
    #[error("{path}:{line}: requirement id {id:?} is used twice")]
    DuplicateId {
        path: PathBuf,
        line: usize,
        id: String,
    },
    /// A covering pattern names a device the rig measures but matches none of its measurements.
    #[error(
        "{path}:{line}: requirement {id}: {pattern:?} matches no measurement that {rig} declares \
         (a typo, or a renamed measurement?)"
    )]
    UnknownMeasurement {
        path: PathBuf,
        line: usize,
        id: String,
        pattern: String,
        rig: String,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    requirement: Vec<RawRequirement>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRequirement {
    id: toml::Spanned<String>,
    text: String,
    source: String,
    #[serde(default)]
    covers: Option<String>,
    covered_by: Vec<toml::Spanned<String>>,
}

/// One requirement.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Requirement {
    pub id: String,
    pub text: String,
    /// Where it comes from (paper section, SORA criterion).
    pub source: String,
    /// What the covering measurements show of it (and what they do not).
    pub covers: Option<String>,
    /// Flat measurement names; `*` matches any run of characters.
    pub covered_by: Vec<String>,
    /// Line of each pattern in the file, for errors.
    #[serde(skip)]
    lines: Vec<usize>,
}

/// The loaded requirements file.
#[derive(Debug, Clone)]
pub struct Requirements {
    pub path: PathBuf,
    pub requirements: Vec<Requirement>,
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

impl Requirements {
    /// Reads and parses `path`.
    pub fn load(path: &Path) -> Result<Self, TraceError> {
        let text = std::fs::read_to_string(path).map_err(|source| TraceError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(path, &text)
    }

    /// Parses the text of a requirements file (`path` is for messages).
    pub fn parse(path: &Path, text: &str) -> Result<Self, TraceError> {
        let raw: RawFile = toml::from_str(text).map_err(|e| TraceError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        let mut requirements: Vec<Requirement> = Vec::new();
        for r in raw.requirement {
            let line = line_of(text, r.id.span().start);
            let id = r.id.into_inner();
            if requirements.iter().any(|q| q.id == id) {
                return Err(TraceError::DuplicateId {
                    path: path.to_owned(),
                    line,
                    id,
                });
            }
            let lines = r
                .covered_by
                .iter()
                .map(|p| line_of(text, p.span().start))
                .collect();
            requirements.push(Requirement {
                id,
                text: r.text,
                source: r.source,
                covers: r.covers,
                covered_by: r.covered_by.into_iter().map(|p| p.into_inner()).collect(),
                lines,
            });
        }
        Ok(Requirements {
            path: path.to_owned(),
            requirements,
        })
    }

    /// Checks every pattern against the measurement names `rig` declares: a pattern whose
    /// device (first segment) the rig measures must match one of them.
    pub fn check(&self, declared: &[String], rig: &str) -> Result<(), TraceError> {
        for r in &self.requirements {
            for (pattern, &line) in r.covered_by.iter().zip(&r.lines) {
                let device = pattern.split('.').next().unwrap_or("");
                let rig_measures_device =
                    declared.iter().any(|n| n.split('.').next() == Some(device));
                if rig_measures_device && !declared.iter().any(|n| glob(pattern, n)) {
                    return Err(TraceError::UnknownMeasurement {
                        path: self.path.clone(),
                        line,
                        id: r.id.clone(),
                        pattern: pattern.clone(),
                        rig: rig.to_owned(),
                    });
                }
            }
        }
        Ok(())
    }
}

/// `*` matches any run of characters (dots included); everything else literally.
pub fn glob(pattern: &str, name: &str) -> bool {
    let mut parts = pattern.split('*');
    let first = parts.next().unwrap_or("");
    let Some(mut rest) = name.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    let Some((last, middle)) = parts.split_last() else {
        return rest.is_empty();
    };
    for part in middle {
        match rest.find(part) {
            Some(i) => rest = &rest[i + part.len()..],
            None => return false,
        }
    }
    rest.len() >= last.len() && rest.ends_with(last)
}

/// A requirement's standing in one run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TraceOutcome {
    /// Every covering measurement the rig declares ran and passed (marginal counts as pass).
    Pass,
    /// A covering measurement failed or was never recorded.
    Fail,
    /// Some covering measurements did not run (a `--filter`, a skipped phase): no verdict.
    Partial,
    /// Nothing this rig measures covers it.
    Uncovered,
}

impl TraceOutcome {
    pub fn as_str(self) -> &'static str {
        match self {
            TraceOutcome::Pass => "PASS",
            TraceOutcome::Fail => "FAIL",
            TraceOutcome::Partial => "PARTIAL",
            TraceOutcome::Uncovered => "UNCOVERED",
        }
    }
}

/// One covering measurement in the matrix.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Covering {
    /// Flat measurement name.
    pub measurement: String,
    /// The phase that recorded it, when it ran.
    pub phase: Option<String>,
    /// `pass`, `fail`, `marginal`, `skipped`, `unset`, or `not run` when the run has no record
    /// of it (a phase left out by `--filter`).
    pub outcome: String,
}

/// One row of the matrix.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TraceRow {
    pub requirement: Requirement,
    pub covering: Vec<Covering>,
    pub outcome: TraceOutcome,
}

/// Builds the matrix from a saved record; `declared` are the names the rig's phases declare
/// (so that a measurement left out of the run shows as `not run`, not as absent).
pub fn matrix(reqs: &Requirements, declared: &[String], record: &RunRecord) -> Vec<TraceRow> {
    reqs.requirements
        .iter()
        .map(|r| {
            let mut names: Vec<&String> = declared
                .iter()
                .filter(|n| r.covered_by.iter().any(|p| glob(p, n)))
                .collect();
            names.sort();
            names.dedup();
            let covering: Vec<Covering> = names
                .into_iter()
                .map(|name| {
                    let found = record
                        .phases
                        .iter()
                        .flat_map(|p| p.measurements.iter().map(move |m| (p, m)))
                        .find(|(_, m)| &m.name == name);
                    match found {
                        Some((p, m)) => Covering {
                            measurement: name.clone(),
                            phase: Some(p.name.clone()),
                            outcome: m.outcome.as_str().to_owned(),
                        },
                        None => Covering {
                            measurement: name.clone(),
                            phase: None,
                            outcome: "not run".into(),
                        },
                    }
                })
                .collect();
            let outcome = if covering.is_empty() {
                TraceOutcome::Uncovered
            } else if covering.iter().any(|c| {
                c.outcome == Outcome::Fail.as_str() || c.outcome == Outcome::Unset.as_str()
            }) {
                TraceOutcome::Fail
            } else if covering.iter().all(|c| {
                c.outcome == Outcome::Pass.as_str() || c.outcome == Outcome::Marginal.as_str()
            }) {
                TraceOutcome::Pass
            } else {
                TraceOutcome::Partial
            };
            TraceRow {
                requirement: r.clone(),
                covering,
                outcome,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::tests::sample_record;

    #[test]
    fn glob_matches_segments_and_runs() {
        assert!(glob("mux.*.handover_ms", "mux.scan.handover_ms"));
        assert!(!glob("mux.*.handover_ms", "mux.scan.handover_silent_ms"));
        assert!(glob("mux.*.b_handover.*", "mux.scan.b_handover.rc_losses"));
        assert!(glob("a", "a") && !glob("a", "ab") && !glob("a*", "b"));
    }

    #[test]
    fn the_repository_file_loads_and_matches_the_emulated_rig() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("requirements.toml");
        let reqs = Requirements::load(&path).unwrap();
        for id in [
            "R1",
            "R2",
            "A",
            "B",
            "C",
            "D",
            "E",
            "F",
            "MultiRX-A",
            "MultiRX-D",
        ] {
            assert!(reqs.requirements.iter().any(|r| r.id == id), "{id} missing");
        }
        let rig = std::sync::Arc::new(
            crate::rigfile::RigFile::load(
                Path::new(env!("CARGO_MANIFEST_DIR")).join("../rigs/emulated.toml"),
            )
            .unwrap(),
        );
        let declared = crate::runner::declared_names(&rig, &crate::devices::of_rig(&rig)).unwrap();
        reqs.check(&declared, "rigs/emulated.toml").unwrap();
    }

    #[test]
    fn a_pattern_matching_nothing_is_an_error_naming_file_and_line() {
        let text = "[[requirement]]\nid = \"X\"\ntext = \"t\"\nsource = \"s\"\n\
                    covered_by = [\n  \"mux.*.handover_ms\",\n  \"mux.*.handover_msec\",\n]\n";
        let reqs = Requirements::parse(Path::new("req.toml"), text).unwrap();
        let declared = vec!["mux.scan.handover_ms".to_owned()];
        let err = reqs.check(&declared, "rig.toml").unwrap_err().to_string();
        assert!(err.starts_with("req.toml:7: requirement X"), "{err}");
        // A device the rig does not measure at all is not an error: the row is uncovered there.
        let bench_only = vec!["flash.parallel.bytes".to_owned()];
        reqs.check(&bench_only, "bench.toml").unwrap();
    }

    #[test]
    fn uncovered_is_never_pass_and_a_missing_measurement_is_not_run() {
        let text = "[[requirement]]\nid = \"D\"\ntext = \"t\"\nsource = \"s\"\ncovered_by = []\n\
                    [[requirement]]\nid = \"B\"\ntext = \"t\"\nsource = \"s\"\n\
                    covered_by = [\"mux.*.handover_ms\"]\n\
                    [[requirement]]\nid = \"T\"\ntext = \"t\"\nsource = \"s\"\n\
                    covered_by = [\"link.*.bytes_per_s\"]\n";
        let reqs = Requirements::parse(Path::new("req.toml"), text).unwrap();
        let record = sample_record();
        let declared: Vec<String> = vec![
            "mux.parallel.handover_ms".into(),
            "mux.scan.handover_ms".into(),
            "mux.lost.handover_ms".into(),
            "link.pty.sik_64k.bytes_per_s".into(),
        ];
        let rows = matrix(&reqs, &declared, &record);
        assert_eq!(rows[0].outcome, TraceOutcome::Uncovered);
        assert_eq!(rows[1].outcome, TraceOutcome::Partial, "{:?}", rows[1]);
        assert_eq!(rows[1].covering[0].outcome, "not run");
        assert_eq!(rows[2].outcome, TraceOutcome::Fail);
    }

    #[test]
    fn duplicate_ids_are_rejected() {
        let text = "[[requirement]]\nid = \"X\"\ntext = \"t\"\nsource = \"s\"\ncovered_by = []\n\
                    [[requirement]]\nid = \"X\"\ntext = \"t\"\nsource = \"s\"\ncovered_by = []\n";
        let err = Requirements::parse(Path::new("r.toml"), text)
            .unwrap_err()
            .to_string();
        assert_eq!(err, "r.toml:7: requirement id \"X\" is used twice");
    }
}
