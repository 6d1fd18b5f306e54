//! Values that pass a type check but not a range check, given to the real binaries: each is a
//! usage error (exit status 2) whose message names the option or the file and line, never a
//! panic (exit status 101) at run time.

use std::path::Path;

mod common;
use common::temp_dir;

/// Runs a binary `--unsigned` with `args` in `dir` to its end: exit code and stderr.
fn run(bin: &str, dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    common::run(bin, dir, &[&["--unsigned"], args].concat())
}

const ROUTER: &str = env!("CARGO_BIN_EXE_mavlora-router");
const BRIDGE: &str = env!("CARGO_BIN_EXE_mavlora-bridge");

#[test]
fn out_of_range_durations_on_the_command_line_are_usage_errors() {
    let dir = temp_dir("usage-flags");
    let radio = ["--radio", "/dev/null/none", "--udp-bind", "127.0.0.1:0"];
    for (flag, value, name) in [
        ("--status-interval", "-1", "status-interval"),
        ("--status-interval", "0", "status-interval"),
        ("--link-quality-period", "inf", "link-quality-period"),
        ("--link-quality-period", "NaN", "link-quality-period"),
        ("--gcs-heartbeat-period", "-5", "gcs-heartbeat-period"),
        ("--gcs-heartbeat-period", "1e300", "gcs-heartbeat-period"),
        ("--rate", "0", "rate"),
        ("--burst", "0", "burst"),
    ] {
        let arg = format!("{flag}={value}");
        let mut args = radio.to_vec();
        args.push(&arg);
        let (code, stderr) = run(ROUTER, &dir, &args);
        assert_eq!(code, Some(2), "router {arg}: {stderr}");
        assert!(
            stderr.contains(name),
            "router {arg} does not name it: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "router {arg}: {stderr}");
    }
    let (code, stderr) = run(
        BRIDGE,
        &dir,
        &[
            "--fc",
            "/dev/null/fc",
            "--radio",
            "/dev/null/none",
            "--status-interval=-1",
        ],
    );
    assert_eq!(code, Some(2), "bridge: {stderr}");
    assert!(stderr.contains("status-interval"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn out_of_range_values_in_a_config_file_name_the_file_line_and_key() {
    let dir = temp_dir("usage-config");
    std::fs::write(
        dir.join("router.toml"),
        "radio = \"/dev/null/none\"\nudp_bind = \"127.0.0.1:0\"\nstatus_interval = -1.0\n",
    )
    .unwrap();
    let (code, stderr) = run(ROUTER, &dir, &["--config", "router.toml"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("status_interval"), "{stderr}");
    assert!(stderr.contains("router.toml:3"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn profile_rates_too_small_to_schedule_name_the_file_and_line() {
    let dir = temp_dir("usage-profile");
    for (body, line) in [
        ("[defaults]\nradio = 1e-30\n", 2),
        ("[messages.ATTITUDE]\nstream_hz = 2\nradio = 1e-30\n", 3),
        ("[messages.ATTITUDE]\nstream_hz = 1e-30\n", 2),
    ] {
        std::fs::write(dir.join("profile.toml"), body).unwrap();
        let (code, stderr) = run(
            BRIDGE,
            &dir,
            &[
                "--fc",
                "/dev/null/fc",
                "--radio",
                "/dev/null/none",
                "--profile",
                "profile.toml",
            ],
        );
        assert_eq!(code, Some(2), "{body}: {stderr}");
        assert!(
            stderr.contains(&format!("profile.toml:{line}")),
            "{body}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{body}: {stderr}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
