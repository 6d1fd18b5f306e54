//! The real `rig` binary, run as a user runs it.

use std::path::{Path, PathBuf};
use std::process::Command;

const RIG: &str = env!("CARGO_BIN_EXE_rig");

/// The tests that run real-time phases take turns: two at once on a loaded
/// machine miss the timing limits.
static REALTIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn realtime_turn() -> std::sync::MutexGuard<'static, ()> {
    REALTIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

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
    let _turn = realtime_turn();
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

/// Regression: a `--filter` that matched nothing exited 0 with PASS and zero phases.
#[test]
fn filter_matching_nothing_exits_2_names_the_filter_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let out = rig(&[
        "run",
        "rigs/emulated.toml",
        "--out",
        out_dir.to_str().unwrap(),
        "--filter",
        "no_such_phase",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("\"no_such_phase\""), "{stderr}");
    assert!(stderr.contains("--list"), "{stderr}");
    assert!(!out_dir.exists(), "nothing is written");
}

#[test]
fn help_lists_the_exit_codes() {
    let out = rig(&["--help"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    for code in ["  0 ", "  1 ", "  2 ", "130", "143"] {
        assert!(stdout.contains(code), "{code}:\n{stdout}");
    }
}

/// Processes whose environment holds `marker` (the rig's children inherit it).
fn processes_with(marker: &str) -> Vec<(u32, String)> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(environ) = std::fs::read(entry.path().join("environ")) else {
            continue;
        };
        if environ
            .split(|&b| b == 0)
            .any(|var| var == marker.as_bytes())
        {
            let cmdline = std::fs::read(entry.path().join("cmdline")).unwrap_or_default();
            let cmdline = String::from_utf8_lossy(&cmdline).replace('\0', " ");
            // A zombie (exited, not yet reaped) has an empty cmdline and runs nothing.
            if !cmdline.is_empty() {
                found.push((pid, cmdline));
            }
        }
    }
    found
}

/// `rig run rigs/emulated.toml --out dir --filter phase --exact`, with an environment marker
/// its children inherit (for [`processes_with`]); the command and the marker.
fn marked_run(dir: &Path, phase: &str) -> (Command, String) {
    let (mut command, marker) = marked_run_of(dir, phase);
    command.arg("--exact");
    (command, marker)
}

/// [`marked_run`] of every phase whose name contains `filter`.
fn marked_run_of(dir: &Path, filter: &str) -> (Command, String) {
    let marker = format!("RIG_TEST_RUN={}", dir.display());
    let (key, value) = marker.split_once('=').unwrap();
    let mut command = Command::new(RIG);
    command
        .args(["run", "rigs/emulated.toml", "--out", dir.to_str().unwrap()])
        .args(["--filter", filter])
        .env(key, value)
        .current_dir(repo());
    (command, marker)
}

/// What an interrupted run left: its output, its `results.json`, the programs it had started.
struct Interrupted {
    out: std::process::Output,
    record: serde_json::Value,
    started: Vec<(u32, String)>,
}

/// Starts `command` (marked with `marker`), waits until it runs at least `programs` programs
/// and `settle` more, sends `signal`, and collects what the run left; asserts that no program
/// it started outlives it.
fn interrupt(
    mut command: Command,
    marker: &str,
    dir: &Path,
    programs: usize,
    settle: std::time::Duration,
    signal: rustix::process::Signal,
) -> Interrupted {
    let child = command
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
    while processes_with(marker).len() < programs && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    std::thread::sleep(settle);
    let started: Vec<_> = processes_with(marker)
        .into_iter()
        .filter(|(pid, _)| *pid != child.id())
        .collect();
    assert!(
        started.len() >= programs,
        "the run started {started:?}, fewer than {programs} programs"
    );
    rustix::process::kill_process(
        rustix::process::Pid::from_raw(child.id() as i32).unwrap(),
        signal,
    )
    .unwrap();
    let out = child.wait_with_output().unwrap();
    let record =
        serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    std::thread::sleep(std::time::Duration::from_millis(500));
    let left = processes_with(marker);
    assert!(
        left.is_empty(),
        "still running after the rig exited (it started {started:?}): {left:?}"
    );
    Interrupted {
        out,
        record,
        started,
    }
}

/// Regression: SIGTERM mid-phase exited 143 with the previous run's PASS still in
/// results.json, and the emulator and fixtures it started kept running.
#[test]
fn sigterm_mid_phase_records_interrupted_and_leaves_no_process_behind() {
    let _turn = realtime_turn();
    let emulator = Path::new(RIG).with_file_name("multirx-emu");
    assert!(
        emulator.exists(),
        "{} missing: run `cargo build -p multirx-emulator` first",
        emulator.display()
    );
    let dir = tempfile::tempdir().unwrap();
    // A previous run's verdict, which must not survive this run.
    std::fs::write(
        dir.path().join("results.json"),
        r#"{"outcome": "pass", "stale": true}"#,
    )
    .unwrap();
    let (command, marker) = marked_run(dir.path(), "multirx::parallel::c_loiter");
    // Once the phase has started its programs, stop the rig.
    let run = interrupt(
        command,
        &marker,
        dir.path(),
        3,
        std::time::Duration::from_millis(1500),
        rustix::process::Signal::TERM,
    );
    let stderr = String::from_utf8_lossy(&run.out.stderr);
    assert_eq!(run.out.status.code(), Some(143), "{stderr}");
    let record = &run.record;
    assert_eq!(record["outcome"], "interrupted", "{record:#}");
    let phases = record["phases"].as_array().unwrap();
    let last = phases.last().expect("the phase in progress is recorded");
    assert_eq!(last["name"], "multirx::parallel::c_loiter");
    assert_eq!(last["outcome"], "interrupted");
    let summary = std::fs::read_to_string(dir.path().join("summary.txt")).unwrap();
    assert!(summary.contains("INTERRUPTED"), "{summary}");
}

/// SIGINT while the real-time MavLora phases run side by side (their programs killed under
/// them end in errors a moment later): exit 130, the record `interrupted`, every phase in it
/// once and each running one `interrupted`, and no program left.
#[test]
fn sigint_during_realtime_phases_records_each_phase_once_as_interrupted() {
    let _turn = realtime_turn();
    for program in ["mavlora-bridge", "mavlora-router"] {
        let path = Path::new(RIG).with_file_name(program);
        assert!(
            path.exists(),
            "{} missing: run `cargo build -p mavlora --bins` first",
            path.display()
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let (command, marker) = marked_run_of(dir.path(), "mavlora::realtime::");
    // Several sessions up (each a bridge, a router and two fixtures), then a few seconds in.
    let run = interrupt(
        command,
        &marker,
        dir.path(),
        8,
        std::time::Duration::from_secs(3),
        rustix::process::Signal::INT,
    );
    let stderr = String::from_utf8_lossy(&run.out.stderr);
    assert_eq!(run.out.status.code(), Some(130), "{stderr}");
    let record = &run.record;
    assert_eq!(record["outcome"], "interrupted", "{record:#}");
    let phases = record["phases"].as_array().unwrap();
    let interrupted = phases
        .iter()
        .filter(|p| p["outcome"] == "interrupted")
        .count();
    assert!(
        interrupted >= 2,
        "side-by-side phases were running ({:?}): {record:#}",
        run.started
    );
    for phase in phases {
        assert!(
            ["interrupted", "pass"].contains(&phase["outcome"].as_str().unwrap()),
            "a phase ended by the interrupt is recorded as its error: {phase:#}"
        );
    }
    let mut names: Vec<&str> = phases.iter().map(|p| p["name"].as_str().unwrap()).collect();
    let count = names.len();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), count, "a phase recorded twice: {record:#}");
}

/// `rigs/emulated.toml` copied into `dir` with its paths made absolute and
/// the emulated device replaced by `program`.
fn emulated_rig_with_program(dir: &Path, program: &Path) -> PathBuf {
    let repo = repo();
    let text = std::fs::read_to_string(repo.join("rigs/emulated.toml"))
        .unwrap()
        .replace(
            "# program = \"../target/debug/multirx-emu\"",
            &format!("program = \"{}\"", program.display()),
        )
        .replace("\"../", &format!("\"{}/", repo.display()))
        .replace("\"multirx/", &format!("\"{}/rigs/multirx/", repo.display()));
    assert!(text.contains(&format!("program = \"{}\"", program.display())));
    let path = dir.join("rig.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// A hostile device: the real `multirx-emu`, but started with another
/// configuration than the one the rig hands it (what a board flashed by hand
/// with another config looks like).
fn impostor(dir: &Path, config: &Path) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let emulator = Path::new(RIG).with_file_name("multirx-emu");
    let script = dir.join("impostor.sh");
    std::fs::write(
        &script,
        format!(
            "#!/bin/sh\n# Swap the --config the rig passes for another one.\nargs=\"\"\nfor a in \"$@\"; do\n  if [ \"$prev\" = --config ]; then a='{}'; fi\n  args=\"$args '$a'\"\n  prev=\"$a\"\ndone\neval exec '{}' $args\n",
            config.display(),
            emulator.display()
        ),
    )
    .unwrap();
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    script
}

/// Before any phase drives MultiRX the rig reads its boot line; a device
/// running another config (so another build id too) fails the phase loudly,
/// naming what it reports and what the rig file expects.
#[test]
fn boot_check_fails_a_device_running_another_config_naming_both() {
    let _turn = realtime_turn();
    let dir = tempfile::tempdir().unwrap();
    let other = dir.path().join("other.toml");
    std::fs::write(
        &other,
        std::fs::read_to_string(repo().join("rigs/multirx/parallel.toml"))
            .unwrap()
            .replace("acquire_frames = 3", "acquire_frames = 4"),
    )
    .unwrap();
    let rig_file = emulated_rig_with_program(dir.path(), &impostor(dir.path(), &other));
    let out_dir = dir.path().join("out");
    let out = rig(&[
        "run",
        rig_file.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--filter",
        "multirx::parallel::b_handover",
        "--exact",
    ]);
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!out.status.success(), "{text}");
    let results = std::fs::read_to_string(out_dir.join("results.json")).unwrap();
    let hash = |path: &Path| {
        let text = std::fs::read_to_string(path).unwrap();
        multirx_core::Config::from_toml(&text)
            .unwrap()
            .identity_hash()
    };
    let (theirs, ours) = (
        hash(&other),
        hash(&repo().join("rigs/multirx/parallel.toml")),
    );
    assert_ne!(theirs, ours);
    for expected in [
        "MultiRX runs another image than the rig file names".to_string(),
        "device reports build".to_string(),
        format!("config {theirs:016x}"),
        "rig expects build".to_string(),
        format!("config {ours:016x}"),
        "config differs".to_string(),
        "parallel.toml".to_string(),
    ] {
        assert!(
            results.contains(&expected),
            "{expected:?} missing from results.json:\n{results}\n{text}"
        );
    }
}

/// The same rig with the real `multirx-emu` as `program`: the boot check passes.
#[test]
fn boot_check_passes_the_device_the_rig_file_names() {
    let _turn = realtime_turn();
    let dir = tempfile::tempdir().unwrap();
    let emulator = Path::new(RIG).with_file_name("multirx-emu");
    let rig_file = emulated_rig_with_program(dir.path(), &emulator);
    let out_dir = dir.path().join("out");
    let out = rig(&[
        "run",
        rig_file.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--filter",
        "multirx::parallel::a_idle_takeover",
        "--exact",
    ]);
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // The boot line's figure is recorded against the 50 ms limit.
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("results.json")).unwrap())
            .unwrap();
    let first_frame = record["phases"][0]["measurements"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| {
            m["name"]
                .as_str()
                .is_some_and(|n| n.ends_with("boot_to_first_frame_ms"))
        })
        .unwrap_or_else(|| panic!("no boot_to_first_frame_ms in {record:#}"));
    assert_eq!(first_frame["outcome"], "pass", "{first_frame:#}");
    let ms = first_frame["value"].as_f64().unwrap();
    assert!((0.0..=50.0).contains(&ms), "{ms}");
}

/// A receiver fixture the host holds past the device's 60 ms silence timeout really
/// silences the link, and the device rightly gives the pilot up: the fault phase must not
/// call that a device failure. Here the fixture is stopped (SIGSTOP) for 120 ms every
/// 0.5 s, so every fault window sees a held stimulus: the window runs again once, then the
/// phase ends in an error that says the host broke the link, with no verdict on the device.
#[test]
fn a_held_receiver_fixture_is_an_error_of_the_rig_not_a_device_failure() {
    let _turn = realtime_turn();
    let dir = tempfile::tempdir().unwrap();
    let (mut command, marker) = marked_run(dir.path(), "multirx::parallel::fault_receiver_flood");
    let mut child = command
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let pilot = || {
        processes_with(&marker)
            .into_iter()
            .find(|(_, cmd)| cmd.contains("sbus_receiver.py") && cmd.contains("--name rx0 "))
            .map(|(pid, _)| rustix::process::Pid::from_raw(pid as i32).unwrap())
    };
    let mut holds = 0;
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        std::thread::sleep(std::time::Duration::from_millis(380));
        if let Some(pid) = pilot() {
            let _ = rustix::process::kill_process(pid, rustix::process::Signal::STOP);
            std::thread::sleep(std::time::Duration::from_millis(120));
            let _ = rustix::process::kill_process(pid, rustix::process::Signal::CONT);
            holds += 1;
        }
    };
    assert!(holds > 10, "the pilot's fixture was held {holds} times");
    assert_eq!(status.code(), Some(1));
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("results.json")).unwrap())
            .unwrap();
    let phase = &record["phases"][0];
    assert_eq!(phase["name"], "multirx::parallel::fault_receiver_flood");
    assert_eq!(phase["outcome"], "error", "{phase:#}");
    let error = phase["error"].as_str().unwrap_or_default();
    assert!(
        error.contains("the host, not the device, broke the link"),
        "{error}"
    );
    let log = phase["log"].to_string();
    assert!(
        log.contains("window 1: the host held the receiver fixture"),
        "{log}"
    );
}
