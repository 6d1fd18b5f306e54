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

/// Values of the right type that name no usable setting (issue 22 item 21): each is refused
/// at start naming its option, never run with.
#[test]
fn ids_bauds_and_client_limits_that_cannot_work_are_usage_errors() {
    let dir = temp_dir("usage-limits");
    let radio = ["--radio", "/dev/null/none", "--udp-bind", "127.0.0.1:0"];
    let fc = ["--fc", "/dev/null/fc", "--radio", "/dev/null/none"];
    let cases: [(&str, &[&str], &[&str], &str); 6] = [
        (
            ROUTER,
            &radio,
            &["--tcp-listen", "127.0.0.1:0", "--tcp-max-clients", "0"],
            "tcp-max-clients",
        ),
        (ROUTER, &radio, &["--allow-sysid", "255,0"], "allow-sysid"),
        (ROUTER, &radio, &["--radio-baud", "0"], "radio-baud"),
        (BRIDGE, &fc, &["--system-id", "255"], "system-id"),
        (BRIDGE, &fc, &["--system-id", "0"], "system-id"),
        (BRIDGE, &fc, &["--fc-baud", "0"], "fc-baud"),
    ];
    for (bin, ports, extra, name) in cases {
        let args = [ports, extra].concat();
        let (code, stderr) = run(bin, &dir, &args);
        assert_eq!(code, Some(2), "{bin} {extra:?}: {stderr}");
        assert!(
            stderr.contains(name),
            "{bin} {extra:?} does not name it: {stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A profile, config or key path that leads to a device or a FIFO is refused at once, naming
/// the path: `/dev/zero` was read for 1 GB, a FIFO key hung start-up with no word.
#[cfg(unix)]
#[test]
fn files_that_are_devices_or_fifos_are_refused_at_once_naming_them() {
    let dir = temp_dir("usage-files");
    let fifo = dir.join("radio.key");
    assert!(
        std::process::Command::new("mkfifo")
            .args(["-m", "600"])
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let fifo = fifo.to_str().unwrap();
    let fc = ["--fc", "/dev/null/fc", "--radio", "/dev/null/none"];
    for (flag, path) in [
        ("--profile", "/dev/zero"),
        ("--config", "/dev/zero"),
        ("--key", fifo),
    ] {
        let started = std::time::Instant::now();
        let args = [&fc[..], &[flag, path]].concat();
        let (code, stderr) = if flag == "--key" {
            common::run(BRIDGE, &dir, &args)
        } else {
            run(BRIDGE, &dir, &args)
        };
        assert!(
            matches!(code, Some(c) if c != 0),
            "{flag} {path}: {code:?} {stderr}"
        );
        assert!(
            started.elapsed().as_secs() < 5,
            "{flag} {path} took {:?}",
            started.elapsed()
        );
        assert!(
            stderr.contains(path),
            "{flag}: the path is not named: {stderr}"
        );
        assert!(stderr.contains("not a regular file"), "{flag}: {stderr}");
    }
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
