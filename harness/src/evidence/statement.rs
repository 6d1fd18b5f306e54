//! in-toto Statements v1 (https://in-toto.io/Statement/v1) about the built artifacts: SLSA
//! provenance v1 for the build, and the in-toto test-result predicate v0.1 for the run. Their
//! subjects are the artifacts' SHA-256 digests from `build.json`, so a reviewer can tie an image
//! on a board (or a program) to the build and the run that judged it. They are signed as part of
//! the evidence folder's manifest (see [`super::manifest`]), not as DSSE envelopes.

use serde_json::{Value, json};

use super::build::BuildRecord;
use crate::record::{PhaseOutcome, RunRecord};

/// File names in the evidence folder.
pub const PROVENANCE_FILE: &str = "provenance.intoto.json";
pub const TEST_RESULT_FILE: &str = "test-result.intoto.json";

/// URI of the build type (what `buildDefinition.externalParameters` means).
const BUILD_TYPE: &str = "urn:c2-rig:rig-build:v1";

fn subjects(build: &BuildRecord) -> Vec<Value> {
    build
        .artifacts
        .iter()
        .map(|a| json!({ "name": a.name, "digest": { "sha256": a.sha256 } }))
        .collect()
}

/// The SLSA provenance of `build`.
pub fn provenance(build: &BuildRecord) -> Value {
    let configs: Vec<Value> = build
        .artifacts
        .iter()
        .filter_map(|a| {
            a.config.as_ref().map(
                |c| json!({ "artifact": a.name, "path": c.path, "digest": { "sha256": c.sha256 } }),
            )
        })
        .collect();
    json!({
        "_type": "https://in-toto.io/Statement/v1",
        "subject": subjects(build),
        "predicateType": "https://slsa.dev/provenance/v1",
        "predicate": {
            "buildDefinition": {
                "buildType": BUILD_TYPE,
                "externalParameters": {
                    "source": { "gitCommit": build.git_commit, "dirty": build.git_dirty },
                    "firmwareConfigs": configs,
                },
                "internalParameters": {
                    "rustflags": build.rustflags,
                    "SOURCE_DATE_EPOCH": build.source_date_epoch,
                    "cargoFlags": ["--release", "--locked"],
                },
                "resolvedDependencies": [
                    { "name": "source", "digest": { "gitCommit": build.git_commit } },
                    { "name": "rustc", "annotations": { "version": build.rustc } },
                    { "name": "cargo", "annotations": { "version": build.cargo } },
                    { "name": "Cargo.lock", "annotations": { "sbom": super::sbom::SBOM_FILE } },
                ],
            },
            "runDetails": {
                "builder": { "id": "urn:c2-rig:rig", "version": {
                    "rig": env!("CARGO_PKG_VERSION"),
                }},
                "metadata": { "startedOn": build.started, "finishedOn": build.finished },
            },
        },
    })
}

/// The test-result statement of `run` (rig file digest as its configuration). `partial` says
/// the run was a selection of the phases: never reported as PASSED then.
pub fn test_result(build: &BuildRecord, run: &RunRecord, partial: bool) -> Value {
    let mut passed = Vec::new();
    let mut warned = Vec::new();
    let mut failed = Vec::new();
    for p in &run.phases {
        match p.outcome {
            PhaseOutcome::Pass => passed.push(p.name.clone()),
            PhaseOutcome::Skipped => warned.push(p.name.clone()),
            PhaseOutcome::Fail | PhaseOutcome::Error | PhaseOutcome::Interrupted => {
                failed.push(p.name.clone())
            }
        }
    }
    let result = if !failed.is_empty() {
        "FAILED"
    } else if partial || !warned.is_empty() {
        "WARNED"
    } else {
        "PASSED"
    };
    json!({
        "_type": "https://in-toto.io/Statement/v1",
        "subject": subjects(build),
        "predicateType": "https://in-toto.io/attestation/test-result/v0.1",
        "predicate": {
            "result": result,
            "configuration": [{
                "name": run.rig.file.file_name().map(|f| f.to_string_lossy().into_owned()),
                "digest": { "sha256": run.rig.sha256 },
            }],
            "passedTests": passed,
            "warnedTests": warned,
            "failedTests": failed,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evidence::build::Artifact;
    use crate::record::tests::sample_record;

    fn build() -> BuildRecord {
        BuildRecord {
            schema: "rig-build/1".into(),
            git_commit: "0123".into(),
            git_dirty: false,
            source_date_epoch: 1,
            rustc: "rustc 1.95.0".into(),
            cargo: "cargo 1.95.0".into(),
            rustflags: vec![],
            started: "a".into(),
            finished: "b".into(),
            artifacts: vec![Artifact {
                name: "mux-samd21-default.elf".into(),
                kind: "firmware".into(),
                path: "artifacts/mux-samd21-default.elf".into(),
                sha256: "ab".repeat(32),
                size: 1,
                config: None,
            }],
        }
    }

    #[test]
    fn subjects_are_the_artifact_digests_and_a_failed_phase_fails_the_statement() {
        let p = provenance(&build());
        assert_eq!(p["subject"][0]["digest"]["sha256"], "ab".repeat(32));
        let t = test_result(&build(), &sample_record(), false);
        assert_eq!(t["predicate"]["result"], "FAILED");
        assert!(
            t["predicate"]["failedTests"]
                .as_array()
                .unwrap()
                .contains(&json!("link.bridge.bandwidth"))
        );
    }

    #[test]
    fn a_partial_run_is_never_passed() {
        let mut run = sample_record();
        run.phases.retain(|p| p.outcome == PhaseOutcome::Pass);
        assert_eq!(
            test_result(&build(), &run, false)["predicate"]["result"],
            "PASSED"
        );
        assert_eq!(
            test_result(&build(), &run, true)["predicate"]["result"],
            "WARNED"
        );
    }
}
