//! End to end with an independent MAVLink implementation: the real `mavlora-bridge` and
//! `mavlora-router` binaries, a pymavlink flight controller on a pty
//! (`fixtures/mavlora_fc.py`), two pty pairs joined by a relay thread as the radio, and a
//! pymavlink ground station on the router's UDP port (`fixtures/mavlora_gcs.py`).
//! Needs `python3` with pymavlink 2.4 (fixtures/requirements.txt); fails, not skips, without.

mod common;
use common::{FcFixture, Guard, free_udp_port, radio_key, root};

use std::io::{Read, Write};

use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread;
use std::time::Duration;

use serde_json::Value;
use serialport::{SerialPort, TTYPort};

use mavlora::wire::{Frame, FrameReader, known};

/// Two pty pairs; a thread copies between their masters: the radio.
struct Radio {
    _slaves: (TTYPort, TTYPort),
    air: String,
    ground: String,
    stop: Arc<AtomicBool>,
    /// Frames that crossed, (signed, unsigned).
    seen: Arc<[AtomicU64; 2]>,
}

/// Copies bytes one way, counting the (signed, unsigned) frames that cross.
fn copy(mut from: TTYPort, mut to: TTYPort, stop: Arc<AtomicBool>, seen: Arc<[AtomicU64; 2]>) {
    thread::spawn(move || {
        let mut buf = [0u8; 512];
        let mut reader = FrameReader::new();
        while !stop.load(Ordering::Relaxed) {
            match from.read(&mut buf) {
                Ok(n) if n > 0 => {
                    let _ = to.write_all(&buf[..n]);
                    reader.push(&buf[..n]);
                    while let Some(rx) = reader.next_frame() {
                        let i = usize::from(!rx.frame.is_signed());
                        seen[i].fetch_add(1, Ordering::Relaxed);
                    }
                }
                _ => {}
            }
        }
    });
}

impl Radio {
    fn new() -> Self {
        let (mut a_master, a_slave) = TTYPort::pair().expect("pty pair");
        let (mut b_master, b_slave) = TTYPort::pair().expect("pty pair");
        a_master.set_timeout(Duration::from_millis(20)).unwrap();
        b_master.set_timeout(Duration::from_millis(20)).unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let a2 = a_master.try_clone_native().unwrap();
        let b2 = b_master.try_clone_native().unwrap();
        let seen = Arc::new([AtomicU64::new(0), AtomicU64::new(0)]);
        copy(a_master, b2, stop.clone(), seen.clone());
        copy(b_master, a2, stop.clone(), seen.clone());
        Self {
            seen,
            air: a_slave.name().unwrap(),
            ground: b_slave.name().unwrap(),
            _slaves: (a_slave, b_slave),
            stop,
        }
    }
}

impl Drop for Radio {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

#[test]
fn pymavlink_telemetry_and_fifty_item_mission_through_bridge_and_router() {
    let dir = std::env::temp_dir().join(format!("mavlora-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fc_summary = dir.join("fc.json");
    let tlog = dir.join("router.tlog");
    // the radio link is signed end to end; the flight controller and ground station are not
    let key = radio_key(&dir, 0x2a);

    // kept until the end: the fixture reports events on it
    let FcFixture {
        guard: mut fc,
        port: fc_port,
        out: fc_out,
    } = FcFixture::start(&fc_summary, &[]);

    let radio = Radio::new();
    let udp_port = free_udp_port();
    let mut router = Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
                .args(["--radio", &radio.ground])
                .args(["--udp", &format!("127.0.0.1:{udp_port}")])
                .args(["--udp-bind", "127.0.0.1:0", "--status-interval", "2"])
                .arg("--tlog")
                .arg(&tlog)
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
                .args(["--fc", &fc_port, "--radio", &radio.air, "--compact"])
                .arg("--profile")
                .arg(root().join("firmware/mavlora/profiles/px4-compact.toml"))
                .args(["--status-interval", "2"])
                .arg("--key")
                .arg(&key)
                .spawn()
                .unwrap(),
        ),
        "bridge",
    );

    let gcs = Command::new("python3")
        .arg(root().join("fixtures/mavlora_gcs.py"))
        .args(["--udp", &format!("127.0.0.1:{udp_port}")])
        .args(["--listen", "6", "--items", "50", "--upload-timeout", "30"])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&gcs.stdout);
    let report: Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| {
        panic!(
            "gcs output: {e}: {out} {}",
            String::from_utf8_lossy(&gcs.stderr)
        )
    });
    eprintln!(
        "gcs counts {} upload {:.2} s items sent {}",
        report["counts"], report["upload_s"], report["items_sent"]
    );

    // Telemetry: the standard messages, decoded by pymavlink, at the expected rates.
    let count = |name: &str| report["counts"][name].as_u64().unwrap_or(0);
    assert!(count("GLOBAL_POSITION_INT") >= 12, "{}", report["counts"]);
    for name in ["HEARTBEAT", "SYS_STATUS", "GPS_RAW_INT", "VFR_HUD"] {
        assert!(count(name) >= 3, "{name}: {}", report["counts"]);
    }
    let pos = &report["samples"]["GLOBAL_POSITION_INT"];
    let lat = pos["lat"].as_i64().unwrap();
    assert!(
        (553_700_000 - 200_000..553_700_000 + 200_000).contains(&lat),
        "{pos}"
    );
    assert_eq!(pos["relative_alt"].as_i64(), Some(50_000), "{pos}");
    assert_eq!(
        report["samples"]["HEARTBEAT"]["autopilot"].as_i64(),
        Some(12),
        "PX4"
    );

    // Mission: accepted, and arrived intact at the flight controller.
    assert_eq!(
        report["result"].as_i64(),
        Some(0),
        "MAV_MISSION_ACCEPTED: {report}"
    );

    // The flight controller reboots (4 s of silence, default rates): the bridge must notice
    // and configure the stream rates again.
    let fc_pid = fc.0.as_ref().unwrap().id().to_string();
    Command::new("kill")
        .args(["-USR1", &fc_pid])
        .status()
        .unwrap();
    thread::sleep(Duration::from_secs(6));
    assert!(fc.terminate(), "fc fixture exit status");
    drop(fc_out);
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(&fc_summary).unwrap()).unwrap();
    let sent = report["mission"].as_array().unwrap();
    let got = summary["mission"].as_array().unwrap();
    assert_eq!(got.len(), 50);
    for (g, s) in got.iter().zip(sent) {
        for key in ["seq", "command", "frame", "x", "y", "autocontinue"] {
            assert_eq!(g[key], s[key], "{key} of item {}", s["seq"]);
        }
        let dz = g["z"].as_f64().unwrap() - s["z"].as_f64().unwrap();
        assert!(dz.abs() < 1e-6, "z of item {}", s["seq"]);
    }
    // The bridge configured the stream rates from the profile, at start and after the reboot.
    assert_eq!(summary["reboots"].as_u64(), Some(1));
    let rounds = summary["position_rate_sets"].as_u64().unwrap();
    assert_eq!(rounds, 2, "configured {rounds} times");
    assert_eq!(
        summary["rates"]["ATTITUDE"].as_f64(),
        Some(0.0),
        "{summary}"
    );
    assert_eq!(
        summary["intervals_set"]["ATTITUDE"].as_f64(),
        Some(0.0),
        "{summary}"
    );
    let pos_hz = summary["intervals_set"]["GLOBAL_POSITION_INT"]
        .as_f64()
        .unwrap();
    assert!((pos_hz - 3.0).abs() < 0.01, "{pos_hz}");

    // Clean shutdown on SIGTERM, and a tlog whose every frame checks.
    assert!(bridge.terminate(), "bridge exit status");
    assert!(router.terminate(), "router exit status");
    let bytes = std::fs::read(&tlog).unwrap();
    let (mut at, mut frames) = (0, 0);
    while at < bytes.len() {
        let ts = u64::from_be_bytes(bytes[at..at + 8].try_into().unwrap());
        assert!(ts > 1_600_000_000_000_000, "timestamp {ts} at {at}");
        let start = at + 8;
        let len = match bytes[start] {
            0xFD => {
                12 + usize::from(bytes[start + 1]) + if bytes[start + 2] & 1 != 0 { 13 } else { 0 }
            }
            0xFE => 8 + usize::from(bytes[start + 1]),
            other => panic!("no frame at {start}: {other:#x}"),
        };
        let frame = Frame::new_checked(&bytes[start..start + len]).unwrap();
        let extra = known::crc_extra(frame.message_id()).expect("known id");
        assert!(frame.crc_matches(extra), "frame at {start}");
        frames += 1;
        at = start + len;
    }
    assert!(frames > 100, "{frames} frames in the tlog");
    let signed = radio.seen[0].load(Ordering::Relaxed);
    let unsigned = radio.seen[1].load(Ordering::Relaxed);
    // Every frame on the radio is signed; not vacuously: at least the mission crossed it
    // (its count, its 50 items packed in a few frames, the poll behind them, the ack) and
    // seconds of telemetry (compact and paced, so the count follows the budget, not the
    // test).
    assert!(
        signed >= 10 && unsigned == 0,
        "radio frames signed {signed}, unsigned {unsigned}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A pymavlink ground station on `udp_port` sends `DO_SET_MODE` as `COMMAND_INT` once per
/// sub mode in `sub_modes`, each after the last one's ack (1.5 s retries, 5 tries); the
/// results, `null` for none.
fn ground_set_modes_int(udp_port: u16, sub_modes: &str) -> Value {
    const SCRIPT: &str = r#"
import json, sys, time
from pymavlink import mavutil
m = mavutil.mavlink_connection("udpin:" + sys.argv[1], source_system=255, source_component=190)
m.wait_heartbeat(timeout=10)
results = []
for sub in sys.argv[2].split(","):
    result = None
    for _ in range(5):
        m.mav.command_int_send(1, 1, 0, 176, 0, 0, 1.0, 4.0, float(sub), 0, 0, 0, 0)
        until = time.monotonic() + 1.5
        while result is None and time.monotonic() < until:
            a = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.1)
            if a is not None and a.command == 176:
                result = a.result
        if result is not None:
            break
    results.append(result)
print(json.dumps(results))
"#;
    let out = Command::new("python3")
        .args(["-c", SCRIPT, &format!("127.0.0.1:{udp_port}"), sub_modes])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.trim()).unwrap_or_else(|e| {
        panic!(
            "ground: {e}: {text} {}",
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// The real bridge and router and a pymavlink autopilot and ground station: each
/// `COMMAND_INT` the ground sends runs once on the autopilot, the same one again after its
/// ack (loiter, mission, loiter) and after a router restart too. Before, an identical
/// `COMMAND_INT` within the bridge's 13.5 s hold was answered from its cache (so was the
/// restarted router's first, whose generation the bridge still held): the autopilot ran
/// one of the three, and not the fourth.
#[test]
fn pymavlink_command_ints_run_each_time_even_identical_and_after_a_router_restart() {
    let dir = std::env::temp_dir().join(format!("mavlora-e2e-int-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fc_summary = dir.join("fc.json");
    let FcFixture {
        guard: mut fc,
        port: fc_port,
        out: _fc_out,
    } = FcFixture::start(&fc_summary, &[]);
    let radio = Radio::new();
    let udp_port = free_udp_port();
    let router = || {
        Guard(
            Some(
                Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
                    .args(["--radio", &radio.ground])
                    .args(["--udp", &format!("127.0.0.1:{udp_port}")])
                    .args(["--udp-bind", "127.0.0.1:0", "--unsigned"])
                    .spawn()
                    .unwrap(),
            ),
            "router",
        )
    };
    let mut first = router();
    let mut bridge = Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-bridge"))
                .args(["--fc", &fc_port, "--radio", &radio.air, "--unsigned"])
                .arg("--profile")
                .arg(root().join("firmware/mavlora/profiles/px4-normal.toml"))
                .spawn()
                .unwrap(),
        ),
        "bridge",
    );
    let accepted = serde_json::json!([0, 0, 0]);
    assert_eq!(ground_set_modes_int(udp_port, "3,4,3"), accepted);
    assert!(first.terminate(), "router exit status");
    let mut second = router();
    assert_eq!(ground_set_modes_int(udp_port, "3"), serde_json::json!([0]));

    assert!(fc.terminate(), "fc fixture exit status");
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(&fc_summary).unwrap()).unwrap();
    assert_eq!(summary["commands"]["176"].as_u64(), Some(4), "{summary}");
    assert!(bridge.terminate(), "bridge exit status");
    assert!(second.terminate(), "router exit status");
    let _ = std::fs::remove_dir_all(&dir);
}
