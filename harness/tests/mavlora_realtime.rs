//! The real-time MavLora scenarios end to end: the real `mavlora-bridge` and
//! `mavlora-router`, pymavlink fixtures, the radio emulator on pty pairs.
//! Every measurement must pass. Needs `python3` with pymavlink 2.4 and
//! pyserial (fixtures/requirements.txt): fails, not skips, without.
//! One scenario at a time (a lock), so they do not share the CPU with each other.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::time::Instant;

use rig::measurement::Outcome;
use rig::rigfile::RigFile;
use rig::scenario::PhaseContext;
use rig::scenario::mavlora::realtime::{SessionDefaults, scenarios};

static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The MavLora programs are not binaries of this crate: built by
/// `cargo build -p mavlora --bins` into the same target folder; built here if missing.
fn defaults() -> SessionDefaults {
    match SessionDefaults::for_repo(&repo()) {
        Ok(d) => d,
        Err(_) => {
            let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
            let status = Command::new(cargo)
                .args(["build", "-p", "mavlora", "--bins"])
                .current_dir(repo())
                .status()
                .expect("cargo");
            assert!(status.success(), "cargo build -p mavlora --bins failed");
            SessionDefaults::for_repo(&repo()).expect("mavlora programs after building them")
        }
    }
}

fn run(scenario: &str) {
    let _serial = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let rig_path = dir.path().join("rig.toml");
    let text = format!(
        "[rig]\nname = \"realtime-test\"\n\n[fixtures]\npython = \"python3\"\ndir = \"{}\"\n",
        repo().join("fixtures").display()
    );
    std::fs::write(&rig_path, &text).unwrap();
    let rig = RigFile::from_str(&text, &rig_path).unwrap();
    let defaults = defaults();
    let s = scenarios()
        .into_iter()
        .find(|s| s.name == scenario)
        .unwrap_or_else(|| panic!("no scenario {scenario}"));
    let mut ctx = PhaseContext::new(&rig, &dir.path().join(scenario));
    for m in (s.measurements)() {
        ctx.declare(m);
    }
    let t0 = Instant::now();
    let result = (s.run)(&mut ctx, &defaults);
    let wall = t0.elapsed();
    let (measurements, log, files) = ctx.into_parts();
    for line in &log {
        eprintln!("{scenario}: {line}");
    }
    eprintln!("{scenario}: wall time {:.1} s", wall.as_secs_f64());
    if let Err(e) = result {
        panic!("{scenario} failed: {e:#}");
    }
    assert!(!measurements.is_empty());
    for m in &measurements {
        assert!(
            m.outcome.is_passing() && m.outcome != Outcome::Skipped,
            "{}: {} ({:?}, limits {})",
            m.name,
            m.render_value(),
            m.outcome,
            m.limits.render(&m.unit)
        );
    }
    // Evidence: every program's log was kept and exists.
    for program in ["bridge.log", "router.log", "fc.log", "gcs.log", "fc.json"] {
        assert!(
            files.iter().any(|(_, p, _)| p.ends_with(program) && p.exists()),
            "{program} not kept: {files:?}"
        );
    }
}

#[test]
fn table_ii_compact_and_limit_filter_bandwidth() {
    run("table_ii");
}

#[test]
fn mission_upload_over_lossy_sik_arrives_intact() {
    run("mission");
}

#[test]
fn c2_latency_over_lossy_sik() {
    run("c2_latency");
}

#[test]
fn every_scenario_declares_measurements_under_mavlora_pty() {
    for s in scenarios() {
        let ms = (s.measurements)();
        assert!(!ms.is_empty(), "{}", s.name);
        for m in ms {
            assert!(m.name.starts_with("mavlora.pty."), "{}", m.name);
        }
    }
}
