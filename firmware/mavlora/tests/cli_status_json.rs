//! `--status-json` with the real binaries on ptys: the file holds the start line, status lines
//! while the program runs (read here while it runs, as the rig does) and the stop line, every
//! line whole and of schema `c2-status/1`; its counters are the frames the test drove through.
//! A path that cannot be created ends the program with status 1, naming it. Nothing here
//! reads the log.

use std::io::{Read, Write};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mavlink::MavlinkVersion;
use serialport::{SerialPort as _, TTYPort};

use mavlora::dialect::{ATTITUDE_DATA, HEARTBEAT_DATA, MavMessage, MavParamType, PARAM_VALUE_DATA};
use mavlora::wire::{FrameReader, Sender};

mod common;
use common::status_json::{self, counter};
use common::{Guard, free_port, pty_pair, temp_dir};

const BRIDGE: &str = env!("CARGO_BIN_EXE_mavlora-bridge");
const ROUTER: &str = env!("CARGO_BIN_EXE_mavlora-router");

/// The radio link's counters, on both programs' lines (STATUS-JSON.md).
const RADIO_COUNTERS: &[&str] = &[
    "radio_rx",
    "radio_lost",
    "radio_bad_crc",
    "radio_tx",
    "radio_tx_bytes",
    "radio_queue_dropped_commands",
    "radio_queue_dropped_transfers",
    "radio_queue_dropped_status",
    "radio_queue_dropped_telemetry",
    "radio_queue_dropped_params",
    "radio_offered_bytes",
    "radio_written_bytes",
    "radio_dropped_bytes",
    "radio_write_failures",
    "radio_partials_dropped",
    "radio_opens",
    "radio_refused_opens",
    "rejected_unsigned",
    "rejected_bad_signature",
    "rejected_reflected",
    "rejected_replayed",
    "rejected_stale",
    "rejected_ahead",
    "rejected_unproven",
    "radio_tx_unsigned",
    "inbox_dropped",
    "inbox_dropped_priority",
    "inbox_peak_bytes",
];

const BRIDGE_COUNTERS: &[&str] = &[
    "fc_rx",
    "fc_tx",
    "fc_dropped_bytes",
    "fc_write_failures",
    "fc_partials_dropped",
    "fc_opens",
    "fc_refused_opens",
    "filtered",
    "rate_limited",
    "replaced",
    "compact_batches",
    "compact_merged",
    "compact_samples_dropped",
    "config_acks",
    "fc_reboots",
    "missions",
    "command_acks_replayed",
    "command_copies_dropped",
    "command_acks_repeated",
    "commands_refused_after_restart",
    "commands_untagged",
    "fc_own_commands_dropped",
    "unlisted_dropped",
    "unlisted_dropped_bytes",
];

const ROUTER_COUNTERS: &[&str] = &[
    "gcs_rx",
    "gcs_tx",
    "udp_datagrams",
    "udp_partials_dropped",
    "tcp_refused",
    "tcp_dropped_bytes",
    "tcp_partials_dropped",
    "expanded",
    "compact_undecodable",
    "heartbeats_thinned",
    "missions_accepted",
    "missions_failed",
    "mission_repairs",
    "command_resends",
    "command_blind_resends",
    "command_copies",
    "command_ground_retries_dropped",
    "commands_queued",
    "command_late_acks",
    "commands_abandoned",
    "gcs_not_v1",
    "commands_refused_after_restart",
    "command_foreign_acks",
    "ground_rejected",
    "param_lists_cached",
    "param_cache_misses",
    "param_cache_checks",
];

fn all(radio: &[&'static str], own: &[&'static str]) -> Vec<&'static str> {
    radio.iter().chain(own).copied().collect()
}

/// Starts `bin` unsigned on `ports`, its radio budget out of the way, a status line every
/// 0.2 s to `json`.
fn start(bin: &'static str, ports: &[&str], json: &Path) -> Guard {
    start_with(bin, ports, &[], json)
}

fn start_with(bin: &'static str, ports: &[&str], extra: &[&str], json: &Path) -> Guard {
    let child = Command::new(bin)
        .arg("--unsigned")
        .args(ports)
        .args(extra)
        .args(["--rate", "400000", "--burst", "40000"])
        .args(["--status-interval", "0.2", "--status-json"])
        .arg(json)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    Guard(Some(child), bin)
}

/// Reads `port` until `count` parameter values (alone, or packed by the bridge) have arrived
/// (or 10 s pass): how many did, and in how many frames.
fn read_param_values(port: &mut TTYPort, count: usize) -> (usize, u64) {
    let deadline = Instant::now() + Duration::from_secs(10);
    let (mut reader, mut buf, mut seen, mut frames) = (FrameReader::new(), [0u8; 4096], 0, 0);
    while seen < count && Instant::now() < deadline {
        if let Ok(n) = port.read(&mut buf) {
            reader.push(&buf[..n]);
            while let Some(rx) = reader.next_frame() {
                let values = common::param_values(&rx.frame).len();
                seen += values;
                frames += u64::from(values > 0);
            }
        }
    }
    (seen, frames)
}

/// Frames the flight controller sends (priority traffic: never replaced by a newer sample).
const FC_FRAMES: u64 = 20;
/// Frames the ground sends over the radio.
const RADIO_FRAMES: u64 = 10;

#[test]
fn bridge_status_json_counts_what_went_through_from_start_to_stop() {
    let dir = temp_dir("status-bridge");
    let json = dir.join("bridge.jsonl");
    let (mut fc, fc_slave) = pty_pair();
    let (mut radio, radio_slave) = pty_pair();
    radio.set_timeout(Duration::from_millis(100)).unwrap();
    let ports = [
        "--fc",
        &fc_slave.name().unwrap(),
        "--radio",
        &radio_slave.name().unwrap(),
    ];
    let mut bridge = start(BRIDGE, &ports, &json);
    // Both ports open, as its status says: bytes written now reach it whole.
    let up = status_json::wait_for(&json, |l| {
        counter(l, "fc_opens") >= 1 && counter(l, "radio_opens") >= 1
    });
    assert!(up.is_some(), "no status line with both ports open in 10 s");

    let mut autopilot = Sender::new(1, 1, MavlinkVersion::V2);
    for n in 0..FC_FRAMES {
        let f = autopilot.frame(&MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: n as f32,
            param_count: FC_FRAMES as u16,
            param_index: n as u16,
            param_id: (*b"MARK\0\0\0\0\0\0\0\0\0\0\0\0").into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        }));
        fc.write_all(f.as_bytes()).unwrap();
    }
    let (through, frames) = read_param_values(&mut radio, FC_FRAMES as usize);
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    for _ in 0..RADIO_FRAMES {
        let hb = ground.frame(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        radio.write_all(hb.as_bytes()).unwrap();
    }
    let read_all = status_json::wait_for(&json, |l| counter(l, "radio_rx") >= RADIO_FRAMES);
    let pid = bridge.0.as_ref().unwrap().id();
    assert!(
        bridge.terminate(),
        "the bridge did not stop cleanly on SIGTERM"
    );

    assert_eq!(through, FC_FRAMES as usize, "frames through to the radio");
    assert!(
        read_all.is_some(),
        "radio frames never counted while running"
    );
    let counters = all(RADIO_COUNTERS, BRIDGE_COUNTERS);
    let lines = status_json::check(
        &json,
        "mavlora-bridge",
        &counters,
        &["radio_queued_bytes"],
        true,
    );
    let start = &lines[0];
    assert_eq!(start["pid"], pid, "{start}");
    assert_eq!(start["options"]["signing"], "OFF", "{start}");
    assert_eq!(start["options"]["rate"], 400_000, "{start}");
    let stop = lines.last().unwrap();
    assert_eq!(stop["exit_code"], 0, "{stop}");
    assert!(stop["error"].is_null(), "{stop}");
    assert_eq!(stop["signing"], "OFF", "{stop}");
    assert!(
        stop["peer_loss"].is_null() || stop["peer_loss"].is_f64(),
        "{stop}"
    );
    // What the test drove through, exactly.
    assert_eq!(counter(stop, "fc_rx"), FC_FRAMES, "{stop}");
    assert_eq!(counter(stop, "radio_rx"), RADIO_FRAMES, "{stop}");
    // the values went packed, several to a frame
    assert!(counter(stop, "radio_tx") >= frames, "{stop}");
    // Unsigned: every frame on the radio is counted so.
    assert_eq!(
        counter(stop, "radio_tx_unsigned"),
        counter(stop, "radio_tx"),
        "{stop}"
    );
    // Stopped, the radio port's bytes add up.
    let queued = stop["gauges"]["radio_queued_bytes"].as_u64().unwrap();
    assert_eq!(
        counter(stop, "radio_offered_bytes"),
        counter(stop, "radio_written_bytes") + counter(stop, "radio_dropped_bytes") + queued,
        "{stop}"
    );
    assert_eq!(
        counter(stop, "radio_offered_bytes"),
        counter(stop, "radio_tx_bytes"),
        "{stop}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bridge_status_json_counts_unlisted_telemetry_it_dropped_by_message_id() {
    // A compact profile drops telemetry it does not list; the status says how much, of which
    // message ids, so an operator sees what a new autopilot version sends (issue 22, item F).
    let dir = temp_dir("status-unlisted");
    let json = dir.join("bridge.jsonl");
    let profile = dir.join("drop.toml");
    std::fs::write(
        &profile,
        "[defaults]\nunlisted = \"drop\"\n[messages.HEARTBEAT]\nradio = \"pass\"\n",
    )
    .unwrap();
    let (mut fc, fc_slave) = pty_pair();
    let (_radio, radio_slave) = pty_pair();
    let ports = [
        "--fc",
        &fc_slave.name().unwrap(),
        "--radio",
        &radio_slave.name().unwrap(),
    ];
    let profile_arg = profile.to_str().unwrap();
    let mut bridge = start_with(BRIDGE, &ports, &["--profile", profile_arg], &json);
    let up = status_json::wait_for(&json, |l| counter(l, "fc_opens") >= 1);
    assert!(up.is_some(), "no status line with the port open in 10 s");
    let mut autopilot = Sender::new(1, 1, MavlinkVersion::V2);
    let attitude = autopilot.frame(&MavMessage::ATTITUDE(ATTITUDE_DATA {
        roll: 0.1,
        ..Default::default()
    }));
    let len = attitude.as_bytes().len() as u64;
    fc.write_all(attitude.as_bytes()).unwrap();
    for _ in 1..FC_FRAMES {
        let f = autopilot.frame(&MavMessage::ATTITUDE(ATTITUDE_DATA {
            roll: 0.1,
            ..Default::default()
        }));
        fc.write_all(f.as_bytes()).unwrap();
    }
    let dropped = status_json::wait_for(&json, |l| counter(l, "unlisted_dropped") >= FC_FRAMES);
    assert!(bridge.terminate(), "the bridge did not stop cleanly");
    let line = dropped.expect("the drops counted within 10 s");
    assert_eq!(counter(&line, "unlisted_dropped"), FC_FRAMES, "{line}");
    assert_eq!(counter(&line, "unlisted_dropped_30"), FC_FRAMES, "{line}");
    assert_eq!(
        counter(&line, "unlisted_dropped_bytes"),
        FC_FRAMES * len,
        "{line}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Ground frames the test sends over UDP from allowed system 255, and one from system 66.
const GROUND_FRAMES: u64 = 5;

#[test]
fn router_status_json_counts_radio_and_ground_frames_and_rejections() {
    let dir = temp_dir("status-router");
    let json = dir.join("router.jsonl");
    let (mut radio, radio_slave) = pty_pair();
    radio.set_timeout(Duration::from_millis(100)).unwrap();
    let gcs = UdpSocket::bind("127.0.0.1:0").unwrap();
    gcs.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let port = free_port();
    let ports = [
        "--radio",
        &radio_slave.name().unwrap(),
        "--udp",
        &gcs.local_addr().unwrap().to_string(),
        "--udp-bind",
        &format!("127.0.0.1:{port}"),
    ];
    let mut router = start(ROUTER, &ports, &json);
    let up = status_json::wait_for(&json, |l| counter(l, "radio_opens") >= 1);
    assert!(up.is_some(), "no status line with the radio open in 10 s");

    let mut vehicle = Sender::new(1, 1, MavlinkVersion::V2);
    let burst: Vec<u8> = (0..RADIO_FRAMES)
        .flat_map(|t| {
            let m = MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: t as u32,
                ..Default::default()
            });
            vehicle.frame(&m).as_bytes().to_vec()
        })
        .collect();
    radio.write_all(&burst).unwrap();
    let mut pilot = Sender::new(255, 190, MavlinkVersion::V2);
    let mut intruder = Sender::new(66, 190, MavlinkVersion::V2);
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
    for _ in 0..GROUND_FRAMES {
        gcs.send_to(pilot.frame(&hb).as_bytes(), ("127.0.0.1", port))
            .unwrap();
    }
    gcs.send_to(intruder.frame(&hb).as_bytes(), ("127.0.0.1", port))
        .unwrap();
    let counted = status_json::wait_for(&json, |l| {
        counter(l, "radio_rx") >= RADIO_FRAMES && counter(l, "gcs_rx") > GROUND_FRAMES
    });
    assert!(
        router.terminate(),
        "the router did not stop cleanly on SIGTERM"
    );

    assert!(counted.is_some(), "frames never counted while running");
    let counters = all(RADIO_COUNTERS, ROUTER_COUNTERS);
    let gauges = ["radio_queued_bytes", "tcp_clients"];
    let lines = status_json::check(&json, "mavlora-router", &counters, &gauges, true);
    assert_eq!(lines[0]["options"]["udp_bind"], format!("127.0.0.1:{port}"));
    let stop = lines.last().unwrap();
    assert_eq!(stop["exit_code"], 0, "{stop}");
    assert!(stop["error"].is_null(), "{stop}");
    assert_eq!(counter(stop, "radio_rx"), RADIO_FRAMES, "{stop}");
    assert!(counter(stop, "gcs_tx") >= RADIO_FRAMES, "{stop}");
    // Every ground frame read, the intruder's rejected.
    assert_eq!(counter(stop, "gcs_rx"), GROUND_FRAMES + 1, "{stop}");
    assert_eq!(counter(stop, "ground_rejected"), 1, "{stop}");
    assert_eq!(
        counter(stop, "radio_tx_unsigned"),
        counter(stop, "radio_tx"),
        "{stop}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Regression guard for a reader following a program that is killed: every line it wrote is
/// whole, there is no stop line, and the last status is the last line with counters.
#[test]
fn a_killed_router_leaves_only_whole_lines() {
    let dir = temp_dir("status-killed");
    let json = dir.join("router.jsonl");
    let (_radio, radio_slave) = pty_pair();
    let mut child = Command::new(ROUTER)
        .arg("--unsigned")
        .args(["--radio", &radio_slave.name().unwrap()])
        .args(["--udp-bind", "127.0.0.1:0", "--status-interval", "0.1"])
        .arg("--status-json")
        .arg(&json)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let enough = status_json::wait_for(&json, |_| status_json::read(&json).len() >= 6);
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(enough.is_some(), "fewer than 5 status lines in 10 s");
    let counters = all(RADIO_COUNTERS, ROUTER_COUNTERS);
    let gauges = ["radio_queued_bytes", "tcp_clients"];
    let lines = status_json::check(&json, "mavlora-router", &counters, &gauges, false);
    assert!(lines.iter().all(|l| l["kind"] != "stop"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs `bin --unsigned` with `args` to its end: exit code and stderr.
fn run(bin: &str, dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    common::run(bin, dir, &[&["--unsigned"], args].concat())
}

/// Paths no status file can be created at: in a folder that does not exist, under a regular
/// file, and in a folder without write permission (unless the test runs as root, which may
/// write there anyway).
fn uncreatable(dir: &Path) -> Vec<PathBuf> {
    use std::os::unix::fs::PermissionsExt as _;
    let file = dir.join("a-file");
    std::fs::write(&file, "").unwrap();
    let mut paths = vec![
        dir.join("no-such-folder").join("status.jsonl"),
        file.join("status.jsonl"),
    ];
    let locked = dir.join("read-only");
    std::fs::create_dir_all(&locked).unwrap();
    std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o500)).unwrap();
    if std::fs::write(locked.join("probe"), "").is_err() {
        paths.push(locked.join("status.jsonl"));
    }
    paths
}

#[test]
fn a_status_path_that_cannot_be_created_is_an_error_naming_it() {
    let dir = temp_dir("status-uncreatable");
    for path in uncreatable(&dir) {
        let p = path.to_str().unwrap();
        let radio = ["--radio", "/dev/null/none", "--status-json", p];
        for (bin, extra) in [
            (ROUTER, &["--udp-bind", "127.0.0.1:0"][..]),
            (BRIDGE, &["--fc", "/dev/null/fc"][..]),
        ] {
            let args: Vec<&str> = radio.iter().chain(extra).copied().collect();
            let (code, stderr) = run(bin, &dir, &args);
            assert_eq!(code, Some(1), "{bin} {p}: {stderr}");
            assert!(stderr.contains(p), "{bin} does not name {p}: {stderr}");
            assert!(!stderr.contains("panicked"), "{bin} {p}: {stderr}");
            assert!(!path.exists(), "{p} exists");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_program_that_fails_after_the_start_line_says_why_in_its_stop_line() {
    let dir = temp_dir("status-fails");
    let json = dir.join("router.jsonl");
    let p = json.to_str().unwrap();
    // A ground key that does not exist: the router ends before it runs.
    let args = [
        "--radio",
        "/dev/null/none",
        "--udp-bind",
        "127.0.0.1:0",
        "--ground-key",
        "/dev/null/no-key",
        "--status-json",
        p,
    ];
    let (code, stderr) = run(ROUTER, &dir, &args);
    assert_eq!(code, Some(1), "{stderr}");
    let lines = status_json::read(&json);
    let kinds: Vec<&str> = lines.iter().map(|l| l["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["start", "stop"], "{lines:?}");
    let stop = &lines[1];
    assert_eq!(stop["exit_code"], 1, "{stop}");
    assert!(
        stop["error"]
            .as_str()
            .is_some_and(|e| e.contains("/dev/null/no-key")),
        "{stop}"
    );
    assert!(stop.get("counters").is_none(), "{stop}");
    // The start line says where the ground signer's replay state would live.
    let options = &lines[0]["options"];
    assert_eq!(options["ground_signing"], "on", "{options}");
    assert_eq!(
        options["ground_signing_state"], "/dev/null/no-key.ground-state",
        "{options}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
