//! MAVSDK (PyPI `mavsdk` 4.1, the C++ library in its native binding: an unmodified ground
//! station) waiting for the vehicle's home through the real `mavlora-router` and
//! `mavlora-bridge` in compact mode (`px4-compact.toml --compact`, a signed radio of two pty
//! pairs), with the PX4-like flight controller (`fixtures/mavlora_fc.py`: HOME_POSITION at
//! 0.5 Hz, the same bytes each time, and at once on `MAV_CMD_REQUEST_MESSAGE`, as PX4 1.16
//! SITL does). MAVSDK counts home as ok only once a HOME_POSITION arrives and until then
//! asks for one every 2 s (`fixtures/mavsdk_health.py`). Invariants:
//!
//! - `telemetry.health().is_home_position_ok` becomes true within 10 s of MAVSDK finding the
//!   vehicle, and `telemetry.home()` is the flight controller's home;
//! - MAVSDK starts 4 s after the bridge, when the first home has gone by: it gets one only by
//!   asking;
//! - the radio carries few HOME_POSITION frames: the first home (a change) before MAVSDK
//!   starts, then the answers to its requests, not the autopilot's 0.5 Hz stream (at most
//!   one before and three after).
//!
//! Needs `python3` with pymavlink 2.4 and mavsdk 4.1 (`fixtures/requirements.txt`): without
//! them the test fails, it never skips.

mod common;
use common::{FcFixture, Guard, free_udp_port, pty_pair, radio_key, root};

use std::collections::BTreeMap;
use std::io::{BufRead, Read, Write};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use mavlora::wire::{FrameReader, ids};
use serde_json::Value;
use serialport::{SerialPort, TTYPort};

/// Frames that crossed the radio one way, by message id.
type Seen = Arc<Mutex<BTreeMap<u32, u64>>>;

/// Copies bytes one way (the radio), counting the frames by message id.
fn copy(mut from: TTYPort, mut to: TTYPort, stop: Arc<AtomicBool>, seen: Seen) {
    thread::spawn(move || {
        let mut buf = [0u8; 512];
        let mut reader = FrameReader::new();
        while !stop.load(Ordering::Relaxed) {
            if let Ok(n) = from.read(&mut buf)
                && n > 0
            {
                let _ = to.write_all(&buf[..n]);
                reader.push(&buf[..n]);
                while let Some(rx) = reader.next_frame() {
                    *seen
                        .lock()
                        .unwrap()
                        .entry(rx.frame.message_id())
                        .or_default() += 1;
                }
            }
        }
    });
}

#[test]
fn mavsdk_sees_home_position_ok_through_compact_router_and_bridge() {
    let dir = std::env::temp_dir().join(format!("mavlora-mavsdk-home-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let key = radio_key(&dir, 0x4d);
    let fc_summary = dir.join("fc.json");

    let FcFixture {
        guard: mut fc,
        port: fc_port,
        out: fc_out,
    } = FcFixture::start(&fc_summary, &[]);
    thread::spawn(move || fc_out.lines().map_while(Result::ok).for_each(drop));

    let (mut a_master, a_slave) = pty_pair();
    let (mut b_master, b_slave) = pty_pair();
    a_master.set_timeout(Duration::from_millis(20)).unwrap();
    b_master.set_timeout(Duration::from_millis(20)).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (down, up): (Seen, Seen) = Default::default();
    let (a2, b2) = (
        a_master.try_clone_native().unwrap(),
        b_master.try_clone_native().unwrap(),
    );
    copy(a_master, b2, stop.clone(), down.clone());
    copy(b_master, a2, stop.clone(), up.clone());

    let gcs_port = free_udp_port();
    let mut router = Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
                .args(["--radio", &b_slave.name().unwrap()])
                .args(["--udp", &format!("127.0.0.1:{gcs_port}")])
                .args(["--udp-bind", &format!("127.0.0.1:{}", free_udp_port())])
                .args(["--link-quality-period", "1"])
                .arg("--key")
                .arg(&key)
                .spawn()
                .unwrap(),
        ),
        "router",
    );
    let mut bridge = Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-bridge"))
                .args(["--fc", &fc_port, "--radio", &a_slave.name().unwrap()])
                .arg("--profile")
                .arg(root().join("firmware/mavlora/profiles/px4-compact.toml"))
                .arg("--compact")
                .args(["--link-quality-period", "1"])
                .arg("--key")
                .arg(&key)
                .spawn()
                .unwrap(),
        ),
        "bridge",
    );

    // MAVSDK starts after the vehicle's first home went by to nobody (an application started
    // later, a ground station restarted): it has to ask.
    thread::sleep(Duration::from_secs(4));
    let before = down
        .lock()
        .unwrap()
        .get(&ids::HOME_POSITION)
        .copied()
        .unwrap_or(0);
    let out = Command::new("python3")
        .arg(root().join("fixtures/mavsdk_health.py"))
        .args(["--udp", &format!("127.0.0.1:{gcs_port}")])
        .args(["--timeout", "10", "--connect-timeout", "20"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .output()
        .expect("python3");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(router.terminate(), "router exit status");
    assert!(bridge.terminate(), "bridge exit status");
    assert!(fc.terminate(), "fc fixture exit status");
    stop.store(true, Ordering::Relaxed);
    let _ = std::fs::remove_dir_all(&dir);

    let down = down.lock().unwrap().clone();
    let up = up.lock().unwrap().clone();
    let homes = down.get(&ids::HOME_POSITION).copied().unwrap_or(0);
    let commands = up.get(&ids::COMMAND_LONG).copied().unwrap_or(0)
        + up.get(&ids::COMMAND_INT).copied().unwrap_or(0);
    eprintln!(
        "mavsdk_health.py (exit {:?}):\n{stdout}{stderr}\nradio: {homes} HOME_POSITION down \
         ({before} before MAVSDK started), {commands} commands up",
        out.status.code()
    );
    let events: Vec<Value> = stdout
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    let home = events
        .iter()
        .find(|e| e["event"] == "home")
        .unwrap_or_else(|| panic!("MAVSDK never had is_home_position_ok (see above)"));
    assert_eq!(out.status.code(), Some(0));
    assert!(home["seconds"].as_f64().unwrap() <= 10.0, "{home}");
    // the fixture's home: 55.37 N, 10.39 E, 10 m
    let lat = home["latitude_deg"].as_f64().unwrap();
    let lon = home["longitude_deg"].as_f64().unwrap();
    assert!(
        (lat - 55.37).abs() < 1e-6 && (lon - 10.39).abs() < 1e-6,
        "{home}"
    );
    assert!(
        before <= 1,
        "{before} HOME_POSITION frames before MAVSDK asked"
    );
    assert!(
        (1..=3).contains(&(homes - before)),
        "{} HOME_POSITION frames on the radio for MAVSDK",
        homes - before
    );
}
