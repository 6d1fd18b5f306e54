//! The real binaries refuse to run the radio leg unsigned unless told, and refuse key files
//! that others may read or that are not 64 hex characters, naming the file.

use std::os::unix::fs::PermissionsExt as _;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

const ROUTER: &str = env!("CARGO_BIN_EXE_mavlora-router");
const BRIDGE: &str = env!("CARGO_BIN_EXE_mavlora-bridge");

mod common;
use common::{run, temp_dir};

#[test]
fn without_key_or_unsigned_both_binaries_refuse_to_start() {
    let dir = temp_dir("signing-nokey");
    let router = ["--radio", "/dev/null/none", "--udp-bind", "127.0.0.1:0"];
    let (code, stderr) = run(ROUTER, &dir, &router);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("--key") && stderr.contains("--unsigned"),
        "{stderr}"
    );
    let bridge = ["--fc", "/dev/null/fc", "--radio", "/dev/null/none"];
    let (code, stderr) = run(BRIDGE, &dir, &bridge);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("--key") && stderr.contains("--unsigned"),
        "{stderr}"
    );
    // a config file can say it too, and the status line shows it
    std::fs::write(
        dir.join("router.toml"),
        "unsigned = true\nstatus_interval = 0.2\n",
    )
    .unwrap();
    let mut args = router.to_vec();
    args.extend(["--config", "router.toml"]);
    let (_, stderr) = run_for(ROUTER, &dir, &args, Duration::from_millis(1500));
    assert!(stderr.contains("signing=OFF"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs a binary for `wait`, then stops it; its stderr.
fn run_for(bin: &str, dir: &Path, args: &[&str], wait: Duration) -> (Option<i32>, String) {
    let mut child = Command::new(bin)
        .args(args)
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(wait);
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn readable_truncated_and_raw_keys_are_refused_naming_the_file() {
    let dir = temp_dir("signing-badkey");
    let key = dir.join("radio.key");
    let args = [
        "--radio",
        "/dev/null/none",
        "--udp-bind",
        "127.0.0.1:0",
        "--key",
        "radio.key",
    ];
    std::fs::write(&key, format!("{}\n", "2a".repeat(32))).unwrap();
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o644)).unwrap();
    let (code, stderr) = run(ROUTER, &dir, &args);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("radio.key") && stderr.contains("0644"),
        "{stderr}"
    );
    for (contents, says) in [
        (&"2a".repeat(31)[..], "62 characters"),
        (&"*".repeat(32)[..], "column 1"),
    ] {
        std::fs::write(&key, contents).unwrap();
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).unwrap();
        let (code, stderr) = run(ROUTER, &dir, &args);
        assert_eq!(code, Some(1), "{stderr}");
        assert!(
            stderr.contains("radio.key") && stderr.contains(says),
            "{stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
