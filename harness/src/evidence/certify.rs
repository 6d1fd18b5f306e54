//! `rig certify`: build → (flash, on board rigs, by the run) → the suite → the evidence folder.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};

use super::build::{BuildOptions, repo_root};
use super::trace::{self, REQUIREMENTS_FILE, Requirements, TraceOutcome, TraceRow};
use super::{html, manifest, sbom, statement};
use crate::record::{PhaseOutcome, RESULTS_FILE, RunOutcome, RunRecord, sha256_file};
use crate::rigfile::RigFile;
use crate::runner;

/// Build options for a rig file: one firmware image per mode config it names.
pub fn build_options(
    rig: Option<&RigFile>,
    out_dir: PathBuf,
    target_dir: PathBuf,
    host: bool,
) -> Result<BuildOptions> {
    let cwd = std::env::current_dir()?;
    let repo = repo_root(&cwd)?;
    let firmware_configs = rig
        .map(crate::devices::firmware_configs)
        .unwrap_or_default();
    Ok(BuildOptions {
        out_dir: cwd.join(out_dir),
        target_dir: cwd.join(target_dir),
        repo,
        firmware_configs,
        host,
    })
}

/// File names in the evidence folder.
pub const CERTIFY_FILE: &str = "certify.json";
pub const TRACE_FILE: &str = "trace.json";

/// The verdict of a certification run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum Verdict {
    /// Every phase ran and passed, every requirement is covered and its measurements passed.
    Pass,
    /// A phase or a covering measurement failed or errored.
    Fail,
    /// Nothing failed, but the run does not show every requirement met: a `--filter`ed run, a
    /// requirement nothing covers, a skipped or interrupted phase.
    Partial,
}

impl Verdict {
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::Partial => "PARTIAL",
        }
    }

    /// `rig certify`'s exit code: 0 pass, 1 fail, 3 partial.
    pub fn exit_code(self) -> u8 {
        match self {
            Verdict::Pass => 0,
            Verdict::Fail => 1,
            Verdict::Partial => 3,
        }
    }

    /// Judges a run and its trace matrix; `why` says what decided it.
    pub fn judge(run: &RunRecord, trace: &[TraceRow], filter: Option<&str>) -> (Self, String) {
        let failed: Vec<&str> = trace
            .iter()
            .filter(|r| r.outcome == TraceOutcome::Fail)
            .map(|r| r.requirement.id.as_str())
            .collect();
        let uncovered: Vec<&str> = trace
            .iter()
            .filter(|r| matches!(r.outcome, TraceOutcome::Uncovered | TraceOutcome::Partial))
            .map(|r| r.requirement.id.as_str())
            .collect();
        let bad_phases = run
            .phases
            .iter()
            .filter(|p| matches!(p.outcome, PhaseOutcome::Fail | PhaseOutcome::Error))
            .count();
        if bad_phases > 0
            || !failed.is_empty()
            || run.outcome != RunOutcome::Pass
                && run.outcome != RunOutcome::Interrupted
                && run.outcome != RunOutcome::Running
        {
            return (
                Verdict::Fail,
                format!(
                    "{bad_phases} phase(s) failed or errored; requirements failed: {}",
                    if failed.is_empty() {
                        "none".into()
                    } else {
                        failed.join(", ")
                    }
                ),
            );
        }
        let mut why = Vec::new();
        if let Some(f) = filter {
            why.push(format!("only the phases matching --filter {f:?} ran"));
        }
        if matches!(run.outcome, RunOutcome::Interrupted | RunOutcome::Running) {
            why.push(format!("the run is {}", run.outcome.as_str()));
        }
        if run.phases.iter().any(|p| p.outcome != PhaseOutcome::Pass) {
            why.push("a phase was skipped or interrupted".into());
        }
        if !uncovered.is_empty() {
            why.push(format!(
                "requirements not shown by this run (uncovered or partly run): {}",
                uncovered.join(", ")
            ));
        }
        if why.is_empty() {
            (
                Verdict::Pass,
                "every phase passed and every requirement is covered by passing measurements"
                    .into(),
            )
        } else {
            (
                Verdict::Partial,
                format!("nothing failed, but {}", why.join("; ")),
            )
        }
    }
}

/// What `rig certify` decided, saved as `certify.json` (the page is rendered from it).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CertifyRecord {
    pub verdict: Verdict,
    /// Why, in a sentence.
    pub why: String,
    /// The rig file, as given on the command line.
    pub rig_file: String,
    /// `--filter`, when the run was a selection of phases.
    pub filter: Option<String>,
    pub exact: bool,
    /// The requirements file and its digest.
    pub requirements_file: String,
    pub requirements_sha256: String,
    /// Exit code of the `rig run` that ran the suite.
    pub run_exit_code: i32,
}

/// `rig certify`'s command line.
#[derive(Debug, Clone)]
pub struct CertifyOptions {
    pub rig: PathBuf,
    pub out_dir: PathBuf,
    pub key: Option<PathBuf>,
    pub filter: Option<String>,
    pub exact: bool,
    pub target_dir: PathBuf,
}

fn write_json(path: &Path, value: &impl Serialize) -> Result<()> {
    let mut json = serde_json::to_vec_pretty(value)?;
    json.push(b'\n');
    std::fs::write(path, json).with_context(|| format!("cannot write {}", path.display()))
}

/// build → the suite (run by the *built* rig, which flashes board rigs as its rig file says) →
/// the evidence folder, sealed (and signed with `key`). Returns the verdict.
pub fn certify(options: &CertifyOptions) -> Result<CertifyRecord> {
    let rig = std::sync::Arc::new(RigFile::load(&options.rig)?);
    let key = options
        .key
        .as_deref()
        .map(manifest::load_signing_key)
        .transpose()?;
    let repo = repo_root(&std::env::current_dir()?)?;
    let requirements_path = repo.join(REQUIREMENTS_FILE);
    let requirements = Requirements::load(&requirements_path)?;
    let declared = runner::declared_names(&rig, &crate::devices::of_rig(&rig))?;
    requirements.check(&declared, &options.rig.display().to_string())?;

    let out = std::env::current_dir()?.join(&options.out_dir);
    if out.exists() && std::fs::read_dir(&out)?.next().is_some() {
        bail!(
            "{}: not empty: an evidence folder must hold this run's files only (give a new --out)",
            out.display()
        );
    }
    std::fs::create_dir_all(&out)?;

    // 1. Build.
    let build_options = build_options(Some(&rig), out.clone(), options.target_dir.clone(), true)?;
    let build = super::build::build(&build_options)?;
    let rig_bin = build
        .host("rig")
        .context("the build made no rig program")?
        .path
        .clone();

    // 2. The suite, run by the rig just built (with its bridge, router and emulator beside it).
    eprintln!("rig certify: running the suite with {}", rig_bin.display());
    let mut cmd = std::process::Command::new(&rig_bin);
    cmd.arg("run").arg(&rig.path).arg("--out").arg(&out);
    if let Some(f) = &options.filter {
        cmd.args(["--filter", f]);
        if options.exact {
            cmd.arg("--exact");
        }
    }
    let status = cmd
        .status()
        .with_context(|| format!("cannot run {}", rig_bin.display()))?;
    let run_exit_code = status.code().unwrap_or(-1);
    if !matches!(run_exit_code, 0 | 1) {
        bail!(
            "the suite did not run ({} exited with {status}): no evidence",
            rig_bin.display()
        );
    }
    let run = RunRecord::load(&out.join(RESULTS_FILE))?;

    // 3. Trace, verdict, inputs, SBOM, statements.
    let trace = trace::matrix(&requirements, &declared, &run);
    let (verdict, why) = Verdict::judge(&run, &trace, options.filter.as_deref());
    let inputs = out.join("inputs");
    std::fs::create_dir_all(&inputs)?;
    std::fs::copy(
        &rig.path,
        inputs.join(rig.path.file_name().context("rig file has no name")?),
    )?;
    for (name, path) in crate::devices::input_files(&rig) {
        std::fs::copy(&path, inputs.join(name))?;
    }
    std::fs::copy(&requirements_path, inputs.join("requirements.toml"))?;
    let record = CertifyRecord {
        verdict,
        why,
        rig_file: options.rig.display().to_string(),
        filter: options.filter.clone(),
        exact: options.exact,
        requirements_file: REQUIREMENTS_FILE.into(),
        requirements_sha256: sha256_file(&requirements_path)?,
        run_exit_code,
    };
    write_json(&out.join(CERTIFY_FILE), &record)?;
    write_json(&out.join(TRACE_FILE), &trace)?;
    let sbom = sbom::sbom(
        &repo,
        &repo.join(crate::devices::FIRMWARE.dir),
        &build.git_commit,
        &build.finished,
    )?;
    write_json(&out.join(sbom::SBOM_FILE), &sbom)?;
    write_json(
        &out.join(statement::PROVENANCE_FILE),
        &statement::provenance(&build),
    )?;
    write_json(
        &out.join(statement::TEST_RESULT_FILE),
        &statement::test_result(&build, &run, options.filter.is_some()),
    )?;

    // 4. The page, from the files just saved; then seal everything.
    let page = html::render(&out, crate::devices::html_figures)?;
    std::fs::write(out.join(html::REPORT_FILE), page)?;
    manifest::seal(&out, key.as_ref())?;
    Ok(record)
}
