//! The real `rig` binary, run as a user runs it.

use std::path::{Path, PathBuf};
use std::process::Command;

const RIG: &str = env!("CARGO_BIN_EXE_rig");

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn rig(args: &[&str]) -> std::process::Output {
    Command::new(RIG)
        .args(args)
        .current_dir(repo())
        .output()
        .unwrap()
}

#[test]
fn check_accepts_the_shipped_rig_files() {
    for file in ["rigs/emulated.toml", "rigs/bench.example.toml"] {
        let out = rig(&["check", file]);
        assert!(
            out.status.success(),
            "{file}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn misspelt_key_is_reported_with_file_line_and_key_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo().join("rigs/emulated.toml"))
        .unwrap()
        .replace("receivers = [\"pty\"", "recievers = [\"pty\"");
    let line = text
        .lines()
        .position(|l| l.starts_with("recievers"))
        .unwrap()
        + 1;
    let path = dir.path().join("typo.toml");
    std::fs::write(&path, text).unwrap();
    let out = rig(&["run", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let expected = format!(
        "{}:{line}:1: multirx.ports.recievers: unknown field",
        path.display()
    );
    assert!(stderr.contains(&expected), "{stderr}");
}

#[test]
fn list_names_every_phase_in_both_modes() {
    let out = rig(&["run", "rigs/emulated.toml", "--list"]);
    assert!(out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    for phase in [
        "multirx::parallel::b_handover: test",
        "multirx::scan::a_idle_takeover: test",
        "multirx::scan::whole_run: test",
    ] {
        assert!(stdout.contains(phase), "{phase} missing:\n{stdout}");
    }
}

/// One real scenario end to end: ptys, the emulated device, Python receivers.
#[test]
fn handover_scenario_runs_and_writes_its_evidence() {
    let emulator = Path::new(RIG).with_file_name("multirx-emu");
    assert!(
        emulator.exists(),
        "{} missing: run `cargo test --workspace` (or `cargo build -p multirx-emulator`) first",
        emulator.display()
    );
    let dir = tempfile::tempdir().unwrap();
    let out = rig(&[
        "run",
        "rigs/emulated.toml",
        "--out",
        dir.path().to_str().unwrap(),
        "--filter",
        "multirx::parallel::b_handover",
        "--exact",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("results.json")).unwrap())
            .unwrap();
    let phase = &record["phases"][0];
    assert_eq!(phase["name"], "multirx::parallel::b_handover");
    let handover = phase["measurements"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"] == "multirx.parallel.handover_ms")
        .unwrap();
    assert_eq!(
        handover["dimensions"],
        serde_json::json!({"device": "multirx", "mode": "parallel"})
    );
    let ms = handover["value"].as_f64().unwrap();
    assert!(ms > 0.0 && ms <= 50.0, "{ms}");
    assert!(
        phase["attachments"]
            .as_array()
            .unwrap()
            .iter()
            .any(|a| a["name"] == "fc-frames")
    );
    assert!(dir.path().join("junit.xml").exists());
    assert!(stdout.contains("report: "), "{stdout}");
}
