//! Reports rendered from a saved [`RunRecord`]: `junit.xml` for CI
//! dashboards ([`junit`]) and `summary.txt` for people ([`summary`]).
//!
//! [`write_all`] saves the record first and renders from the copy it reads
//! back, so the reports can never say more, or other, than the evidence.

use std::io;
use std::path::{Path, PathBuf};

use crate::record::{RunRecord, write_atomically};

pub mod junit;
pub mod summary;

pub use junit::{JUNIT_FILE, render_junit, write_junit};
pub use summary::{SUMMARY_FILE, render_summary, write_summary};

/// Paths of the files [`write_all`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReportPaths {
    /// The record, `results.json`.
    pub results: PathBuf,
    /// JUnit XML, `junit.xml`.
    pub junit: PathBuf,
    /// Plain-text summary, `summary.txt`.
    pub summary: PathBuf,
}

/// Saves `record` as `results.json` in `dir`, then renders `junit.xml` and
/// `summary.txt` from the saved copy.
pub fn write_all(record: &RunRecord, dir: &Path) -> io::Result<ReportPaths> {
    let results = record.save(dir)?;
    rerender(&results)
}

/// Renders `junit.xml` and `summary.txt` next to an existing `results.json`
/// (e.g. to regenerate reports from archived evidence).
pub fn rerender(results: &Path) -> io::Result<ReportPaths> {
    let record = RunRecord::load(results)?;
    let dir = results.parent().unwrap_or(Path::new("."));
    let junit = write_junit(&record, dir)?;
    let summary = write_summary(&record, dir)?;
    Ok(ReportPaths {
        results: results.to_path_buf(),
        junit,
        summary,
    })
}

/// Writes a rendered report into `dir` under `name`, atomically.
fn write_report(dir: &Path, name: &str, text: &str) -> io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join(name);
    write_atomically(&path, text.as_bytes())?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::RESULTS_FILE;
    use crate::record::tests::sample_record;

    fn paths_in(dir: &Path) -> ReportPaths {
        ReportPaths {
            results: dir.join(RESULTS_FILE),
            junit: dir.join(JUNIT_FILE),
            summary: dir.join(SUMMARY_FILE),
        }
    }

    #[test]
    fn write_all_writes_three_files_from_the_saved_record() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("rig-report");
        let paths = write_all(&sample_record(), &out).unwrap();
        assert_eq!(paths, paths_in(&out));
        for p in [&paths.results, &paths.junit, &paths.summary] {
            assert!(p.is_file(), "{} missing", p.display());
        }
        let summary = std::fs::read_to_string(&paths.summary).unwrap();
        assert!(
            summary.contains("link.pty.sik_64k.bytes_per_s"),
            "{summary}"
        );
        let xml = std::fs::read_to_string(&paths.junit).unwrap();
        assert!(
            xml.contains("link.pty.sik_64k.bytes_per_s = 1200 B/s"),
            "{xml}"
        );
    }

    #[test]
    fn rerender_uses_the_file_not_memory() {
        let dir = tempfile::tempdir().unwrap();
        let paths = write_all(&sample_record(), dir.path()).unwrap();
        let mut edited = RunRecord::load(&paths.results).unwrap();
        edited.rig.name = "bench-7".into();
        edited.save(dir.path()).unwrap();
        rerender(&paths.results).unwrap();
        let xml = std::fs::read_to_string(&paths.junit).unwrap();
        assert!(xml.contains("bench-7"), "{xml}");
    }
}
