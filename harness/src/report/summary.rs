//! A plain-ASCII table of a [`RunRecord`] for the terminal and
//! `summary.txt`: each phase with its outcome, each measurement with value,
//! limits and outcome in aligned columns, and a closing count.
//!
//! Failing outcomes are upper case (`FAIL`, `UNSET`) so they stand out
//! without colour, which a log file or CI console may not keep.

use std::fmt::Write as _;
use std::io;
use std::path::{Path, PathBuf};

use crate::measurement::{Measurement, Outcome};
use crate::record::{PhaseOutcome, PhaseRecord, RESULTS_FILE, RunOutcome, RunRecord};

use super::JUNIT_FILE;

/// File name of the summary inside an output folder.
pub const SUMMARY_FILE: &str = "summary.txt";

/// Renders `record` as `summary.txt` in `dir` and returns its path.
pub fn write_summary(record: &RunRecord, dir: &Path) -> io::Result<PathBuf> {
    super::write_report(dir, SUMMARY_FILE, &render_summary(record, dir))
}

/// Renders the summary; `dir` is the output folder named in the last line.
pub fn render_summary(record: &RunRecord, dir: &Path) -> String {
    let mut out = String::new();
    let commit = record
        .tool
        .git_commit
        .as_deref()
        .map(|c| format!(" ({c})"))
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "rig {} from {}; {} {}{}",
        record.rig.name,
        record.rig.file.display(),
        record.tool.name,
        record.tool.version,
        commit
    );
    let _ = writeln!(
        out,
        "run {} to {}: {}",
        record.started,
        record.ended,
        record.outcome.as_str().to_ascii_uppercase()
    );
    match record.outcome {
        RunOutcome::Running => {
            let _ = writeln!(
                out,
                "NOT FINISHED: the rig was still running (or died) when this was saved"
            );
        }
        RunOutcome::Interrupted => {
            let _ = writeln!(
                out,
                "NOT FINISHED: the rig was stopped; phases after the interrupted one did not run"
            );
        }
        _ => {}
    }
    out.push('\n');

    let rows: Vec<&Measurement> = record.phases.iter().flat_map(|p| &p.measurements).collect();
    let width = |f: &dyn Fn(&Measurement) -> String| {
        rows.iter().map(|m| f(m).chars().count()).max().unwrap_or(0)
    };
    let widths = [
        width(&|m| m.name.clone()),
        width(&Measurement::render_value),
        width(&|m| m.limits.render(&m.unit)),
    ];
    const INDENT: &str = "         ";
    for phase in &record.phases {
        write_phase_line(&mut out, phase);
        if let Some(text) = &phase.error {
            let label = match phase.outcome {
                PhaseOutcome::Skipped => "skipped",
                PhaseOutcome::Interrupted => "interrupted",
                _ => "error",
            };
            for (i, line) in text.lines().enumerate() {
                let lead = if i == 0 { label } else { "      " };
                let _ = writeln!(out, "{INDENT}{lead}: {line}");
            }
        }
        for m in &phase.measurements {
            let outcome = match m.outcome {
                Outcome::Fail | Outcome::Unset => m.outcome.as_str().to_ascii_uppercase(),
                other => other.as_str().to_owned(),
            };
            let mut line = format!(
                "{INDENT}{:w0$}  {:w1$}  {:w2$}  {outcome}",
                m.name,
                m.render_value(),
                m.limits.render(&m.unit),
                w0 = widths[0],
                w1 = widths[1],
                w2 = widths[2],
            );
            if let Some(note) = &m.note
                && !(m.outcome == Outcome::Skipped && phase.error.as_ref() == Some(note))
            {
                let _ = write!(line, "  ({note})");
            }
            out.push_str(line.trim_end());
            out.push('\n');
        }
    }
    for section in crate::devices::summary_sections(record) {
        out.push('\n');
        out.push_str(&section);
    }
    out.push('\n');
    out.push_str(&closing_line(record, dir));
    out.push('\n');
    out
}

fn write_phase_line(out: &mut String, phase: &PhaseRecord) {
    let outcome = phase.outcome.as_str().to_ascii_uppercase();
    if phase.outcome == PhaseOutcome::Skipped {
        let _ = writeln!(out, "{outcome:<8} {}", phase.name);
    } else {
        let _ = writeln!(
            out,
            "{outcome:<8} {}  ({:.2} s)",
            phase.name, phase.duration_s
        );
    }
}

/// `rig: 14 phases, 13 passed, 1 failed; report: DIR/results.json, DIR/junit.xml`,
/// with errored and skipped counts added when there are any.
pub fn closing_line(record: &RunRecord, dir: &Path) -> String {
    let count = |o: PhaseOutcome| record.phases.iter().filter(|p| p.outcome == o).count();
    let n = record.phases.len();
    let mut line = format!(
        "rig: {n} phase{}, {} passed, {} failed",
        if n == 1 { "" } else { "s" },
        count(PhaseOutcome::Pass),
        count(PhaseOutcome::Fail)
    );
    for (o, word) in [
        (PhaseOutcome::Error, "errored"),
        (PhaseOutcome::Skipped, "skipped"),
        (PhaseOutcome::Interrupted, "interrupted"),
    ] {
        let c = count(o);
        if c > 0 {
            let _ = write!(line, ", {c} {word}");
        }
    }
    let _ = write!(
        line,
        "; report: {}, {}",
        dir.join(RESULTS_FILE).display(),
        dir.join(JUNIT_FILE).display()
    );
    line
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::tests::sample_record;

    #[test]
    fn columns_align_and_last_line_counts() {
        let text = render_summary(&sample_record(), Path::new("out"));
        assert!(text.is_ascii(), "{text}");
        let rows: Vec<&str> = text
            .lines()
            .filter(|l| {
                let t = l.trim_start();
                l.starts_with("         ") && !t.starts_with("error:") && !t.starts_with("skipped:")
            })
            .collect();
        assert_eq!(rows.len(), 6, "{text}");
        let col = |needle: &str| -> Vec<usize> {
            rows.iter()
                .map(|r| r.find(needle).unwrap_or_else(|| panic!("{needle} in {r}")))
                .collect()
        };
        let limits = col("x ");
        assert!(limits.iter().all(|&c| c == limits[0]), "{text}");
        assert!(
            text.contains("link.pty.sik_64k.bytes_per_s  1200 B/s  x <= 951 B/s"),
            "{text}"
        );
        assert!(text.contains("UNSET"), "{text}");
        assert!(text.contains("marginal"), "{text}");
        assert!(text.contains("error: router exited"), "{text}");
        assert!(text.contains("skipped: scan not in mux.modes"), "{text}");
        assert_eq!(
            text.lines().last().unwrap(),
            "rig: 4 phases, 1 passed, 1 failed, 1 errored, 1 skipped; \
             report: out/results.json, out/junit.xml"
        );
    }

    #[test]
    fn closing_line_without_errors_or_skips() {
        let mut r = sample_record();
        r.phases.truncate(2);
        assert_eq!(
            closing_line(&r, Path::new("/tmp/o")),
            "rig: 2 phases, 1 passed, 1 failed; report: /tmp/o/results.json, /tmp/o/junit.xml"
        );
    }
}
