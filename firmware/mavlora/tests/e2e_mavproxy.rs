//! MAVProxy (PyPI `MAVProxy`, an unmodified ground station none of us wrote) commanding the
//! vehicle through the real `mavlora-router` and `mavlora-bridge` (a signed link, and the
//! link monitoring any ground station shows): the pymavlink flight controller
//! (`fixtures/mavlora_fc.py`), a signed radio of two pty pairs, and `mavproxy.py` on the
//! router's UDP port, the way an operator runs it (`--master=udpout:...`). Once MAVProxy
//! reports the vehicle, the test types a command on its stdin, as an operator would at its
//! prompt (`long DO_SET_MODE 29 4 3`: PX4's AUTO.LOITER, what pymavlink's own PX4 mode
//! table sends). Invariants, read from MAVProxy's own telemetry log
//! (`fixtures/tlog_summary.py`) and the flight controller's summary:
//!
//! - MAVProxy gets the vehicle's HEARTBEAT (system 1) at ~1 Hz and its telemetry through the
//!   bridge's profile (position at >= 2 Hz; attitude, which the profile drops, never);
//! - `RADIO_STATUS` from the vehicle's radio (1/68) at >= 0.5 Hz the whole time the link is
//!   up: no gap over 2 s between the vehicle's first and last message;
//! - every `COMMAND_LONG` MAVProxy sent (its command and those it sends by itself) reached
//!   the autopilot exactly as many times as MAVProxy sent it, and was acked to MAVProxy
//!   exactly that many times; the typed one once, acked ACCEPTED, and the vehicle's
//!   HEARTBEAT shows the new mode afterwards;
//! - router and bridge exit 0 on SIGTERM.
//!
//! Needs `mavproxy.py` (1.8.75, `fixtures/requirements-mavproxy.txt`, installed by
//! `ci/setup.sh`) and `python3` with pymavlink 2.4: without them the test fails, it never
//! skips. MAVProxy keeps its state and logs in a temporary directory (its `HOME` too).

mod common;
use common::{FcFixture, Guard, free_udp_port, pty_pair, radio_key, root};

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

use serde_json::Value;
use serialport::{SerialPort, TTYPort};

/// MAVProxy's default modules but `terrain` (numpy; it downloads SRTM tiles from the
/// internet on demand) and `adsb` (Pillow): the minimal install has neither, and the same MAVProxy
/// must run on every machine.
const MAVPROXY_MODULES: &str = "log,signing,wp,rally,fence,ftp,param,relay,tuneopt,arm,mode,\
                                calibration,rc,auxopt,misc,cmdlong,battery,output,layout";
/// `MAV_CMD_DO_SET_MODE` to PX4 AUTO.LOITER: base mode 29 (custom mode enabled, auto),
/// main mode 4 (AUTO), sub mode 3 (LOITER).
const COMMAND: &str = "long DO_SET_MODE 29 4 3";
const DO_SET_MODE: u64 = 176;
/// The fixture's HEARTBEAT custom mode before (AUTO.MISSION) and after (AUTO.LOITER).
const MODE_MISSION: u64 = 0x0404_0000;
const MODE_LOITER: u64 = 0x0304_0000;
/// How long the link is watched after MAVProxy saw the vehicle.
const WATCH: Duration = Duration::from_secs(12);

/// Copies bytes one way: the radio.
fn copy(mut from: TTYPort, mut to: TTYPort, stop: Arc<AtomicBool>) {
    thread::spawn(move || {
        let mut buf = [0u8; 512];
        while !stop.load(Ordering::Relaxed) {
            if let Ok(n) = from.read(&mut buf)
                && n > 0
            {
                let _ = to.write_all(&buf[..n]);
            }
        }
    });
}

/// Sends each line of `from` on `lines`.
fn forward_lines(from: impl Read + Send + 'static, lines: mpsc::Sender<String>) {
    thread::spawn(move || {
        for line in BufReader::new(from).lines().map_while(Result::ok) {
            if lines.send(line).is_err() {
                return;
            }
        }
    });
}

/// Waits until a line containing `what` arrives (true) or `deadline` passes (false),
/// keeping every line in `transcript`.
fn wait_for(
    lines: &mpsc::Receiver<String>,
    transcript: &mut Vec<String>,
    what: &str,
    deadline: Instant,
) -> bool {
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match lines.recv_timeout(left) {
            Ok(line) => {
                let found = line.contains(what);
                transcript.push(line);
                if found {
                    return true;
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => return false,
            Err(mpsc::RecvTimeoutError::Disconnected) => return false,
        }
    }
    false
}

/// `tlog_summary.py`'s entry for one sender's message type, if any.
fn stream<'a>(log: &'a Value, sender: &str, kind: &str) -> Option<&'a Value> {
    log["senders"][sender].get(kind)
}

fn f(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} in {v}"))
}

#[test]
fn mavproxy_ground_station_commands_the_vehicle_once_and_sees_the_link() {
    let started = Instant::now();
    let dir = std::env::temp_dir().join(format!("mavlora-mavproxy-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let version = Command::new("mavproxy.py")
        .arg("--version")
        .env("HOME", &dir)
        .output()
        .unwrap_or_else(|e| {
            let _ = std::fs::remove_dir_all(&dir);
            panic!(
                "mavproxy.py cannot be run ({e}): run ci/setup.sh (it installs \
                 fixtures/requirements-mavproxy.txt)"
            )
        });
    let version = String::from_utf8_lossy(&version.stdout);
    assert!(
        version.contains("MAVProxy Version"),
        "mavproxy.py --version said {version:?}: run ci/setup.sh"
    );
    eprintln!("{}", version.trim());

    let key = radio_key(&dir, 0x5c);
    let fc_summary = dir.join("fc.json");
    let tlog = dir.join("gcs.tlog");

    let FcFixture {
        guard: mut fc,
        port: fc_port,
        out: fc_out,
    } = FcFixture::start(&fc_summary, &[]);
    // read on, so its last line (the summary) finds the pipe open and it exits 0
    thread::spawn(move || fc_out.lines().map_while(Result::ok).for_each(drop));

    let (mut a_master, a_slave) = pty_pair();
    let (mut b_master, b_slave) = pty_pair();
    a_master.set_timeout(Duration::from_millis(20)).unwrap();
    b_master.set_timeout(Duration::from_millis(20)).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (a2, b2) = (
        a_master.try_clone_native().unwrap(),
        b_master.try_clone_native().unwrap(),
    );
    copy(a_master, b2, stop.clone());
    copy(b_master, a2, stop.clone());

    // MAVProxy talks first (udpout to the router's port); until then the router sends to a
    // port nobody listens on, never to a ground station that may run on this host (14550).
    let (router_port, nowhere) = (free_udp_port(), free_udp_port());
    let mut router = Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
                .args(["--radio", &b_slave.name().unwrap()])
                .args(["--udp", &format!("127.0.0.1:{nowhere}")])
                .args(["--udp-bind", &format!("127.0.0.1:{router_port}")])
                // a 1 s keep-alive: a real-time test cannot wait for LoRa's 9 s
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
                .arg(root().join("firmware/mavlora/profiles/px4-normal.toml"))
                .args(["--link-quality-period", "1"])
                .arg("--key")
                .arg(&key)
                .spawn()
                .unwrap(),
        ),
        "bridge",
    );

    // Not `--non-interactive`: MAVProxy then ignores stdin, and `--cmd` runs before the
    // vehicle is seen. Its prompt reads a pipe here, no terminal; EOF makes it quit.
    let mut gcs = Guard(
        Some(
            Command::new("mavproxy.py")
                .arg(format!("--master=udpout:127.0.0.1:{router_port}"))
                .arg("--state-basedir")
                .arg(&dir)
                .arg("--logfile")
                .arg(&tlog)
                .arg(format!("--default-modules={MAVPROXY_MODULES}"))
                // its log writer flushes only with this: at exit the unflushed tail is lost
                .arg("--cmd=set flushlogs 1")
                .current_dir(&dir)
                .env("HOME", &dir)
                .env("PYTHONUNBUFFERED", "1")
                .env_remove("DISPLAY")
                .stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .expect("mavproxy.py"),
        ),
        "mavproxy",
    );
    let (tx, lines) = mpsc::channel();
    let child = gcs.0.as_mut().unwrap();
    forward_lines(child.stdout.take().unwrap(), tx.clone());
    forward_lines(child.stderr.take().unwrap(), tx);
    let mut stdin = child.stdin.take().unwrap();
    let mut transcript = Vec::new();

    let seen = wait_for(
        &lines,
        &mut transcript,
        "Detected vehicle 1:1",
        Instant::now() + Duration::from_secs(20),
    );
    assert!(
        seen,
        "MAVProxy did not see the vehicle within 20 s:\n{}",
        transcript.join("\n")
    );
    let seen_at = Instant::now();
    eprintln!(
        "MAVProxy saw the vehicle {:.1} s after the start",
        started.elapsed().as_secs_f64()
    );
    // the operator reads the vehicle's state for a second, then types the command
    thread::sleep(Duration::from_secs(1));
    writeln!(stdin, "{COMMAND}")
        .and_then(|()| stdin.flush())
        .unwrap_or_else(|e| panic!("MAVProxy's stdin: {e}:\n{}", transcript.join("\n")));
    let acked = wait_for(
        &lines,
        &mut transcript,
        "Got COMMAND_ACK: DO_SET_MODE: ACCEPTED",
        Instant::now() + Duration::from_secs(10),
    );
    // the rest of the window: the link stays up, RADIO_STATUS keeps coming
    while let Some(left) = (seen_at + WATCH).checked_duration_since(Instant::now()) {
        match lines.recv_timeout(left) {
            Ok(line) => transcript.push(line),
            Err(_) => thread::sleep(left.min(Duration::from_millis(100))),
        }
    }
    drop(stdin);
    let child = gcs.0.as_mut().unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while child.try_wait().unwrap().is_none() && Instant::now() < deadline {
        transcript.extend(lines.try_iter());
        thread::sleep(Duration::from_millis(50));
    }
    // MAVProxy always exits 1 after unloading its modules: its status says nothing.
    let quit = child.try_wait().unwrap().is_some();
    drop(gcs);
    transcript.extend(lines.try_iter());
    let transcript = transcript.join("\n");
    assert!(quit, "MAVProxy did not quit on EOF:\n{transcript}");
    assert!(router.terminate(), "router exit status");
    assert!(bridge.terminate(), "bridge exit status");
    assert!(fc.terminate(), "fc fixture exit status");
    stop.store(true, Ordering::Relaxed);
    eprintln!("MAVProxy said:\n{transcript}");
    assert!(
        acked,
        "MAVProxy did not report the DO_SET_MODE ack (see above)"
    );

    let out = Command::new("python3")
        .arg(root().join("fixtures/tlog_summary.py"))
        .arg(&tlog)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "tlog_summary.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let log: Value = serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("{e}: {text}"));
    let fc_said: Value =
        serde_json::from_str(&std::fs::read_to_string(&fc_summary).unwrap()).unwrap();

    // The vehicle: its HEARTBEAT at PX4's 1 Hz, its position at the profile's 3 Hz (>= 2),
    // what the profile drops never.
    let hb = stream(&log, "1/1", "HEARTBEAT")
        .unwrap_or_else(|| panic!("MAVProxy got no HEARTBEAT from system 1: {log}"));
    let (up_from, up_to) = (
        f(hb, "first"),
        log["senders"]["1/1"]
            .as_object()
            .unwrap()
            .values()
            .map(|s| f(s, "last"))
            .fold(0.0, f64::max),
    );
    let up = up_to - up_from;
    assert!(up >= 8.0, "the link was up {up:.1} s only: {log}");
    assert!(
        f(hb, "count") >= (up * 0.7).floor() && f(hb, "max_gap") <= 2.5,
        "vehicle HEARTBEAT: {hb}"
    );
    let pos = stream(&log, "1/1", "GLOBAL_POSITION_INT").expect("GLOBAL_POSITION_INT");
    assert!(
        f(pos, "count") / up >= 2.0 && f(pos, "max_gap") <= 1.0,
        "position below 2 Hz: {pos}"
    );
    assert!(stream(&log, "1/1", "SYS_STATUS").is_some(), "SYS_STATUS");
    assert!(
        stream(&log, "1/1", "ATTITUDE").is_none(),
        "ATTITUDE reached the ground although the profile drops it"
    );

    // RADIO_STATUS from the vehicle's radio at >= 0.5 Hz while the link is up
    let rs = stream(&log, "1/68", "RADIO_STATUS")
        .unwrap_or_else(|| panic!("MAVProxy got no RADIO_STATUS from 1/68: {log}"));
    let (rs_first, rs_last) = (f(rs, "first"), f(rs, "last"));
    assert!(
        rs_first - up_from <= 3.0,
        "first RADIO_STATUS {:.2} s after the vehicle's first HEARTBEAT",
        rs_first - up_from
    );
    assert!(
        f(rs, "max_gap") <= 2.0 && up_to - rs_last <= 2.0,
        "RADIO_STATUS below 0.5 Hz: {rs}, vehicle heard until {up_to}"
    );
    assert!(f(rs, "count") >= (up / 2.0).floor(), "{rs}");
    eprintln!(
        "MAVProxy heard the vehicle for {up:.1} s: {} HEARTBEAT, {} GLOBAL_POSITION_INT, {} \
         RADIO_STATUS",
        hb["count"], pos["count"], rs["count"]
    );

    // Every command MAVProxy sent reached the autopilot as often as it was sent, and was
    // acked to MAVProxy as often.
    let sent: Vec<&Value> = log["commands"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["sender"] == "255/230")
        .collect();
    let mut by_id: BTreeMap<u64, usize> = BTreeMap::new();
    for c in &sent {
        *by_id.entry(c["command"].as_u64().unwrap()).or_default() += 1;
    }
    let executed = &fc_said["commands"];
    for (id, n) in &by_id {
        let at_fc = executed[id.to_string()].as_u64().unwrap_or(0) as usize;
        assert_eq!(
            at_fc, *n,
            "command {id}: MAVProxy sent it {n} times, the autopilot executed it {at_fc} \
             times (fc: {executed}, sent: {sent:?})"
        );
        let acks = log["acks"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|a| a["command"] == *id && a["sender"] == "1/1" && a["target_system"] == 255)
            .count();
        assert_eq!(acks, *n, "command {id}: {n} sent, {acks} acks: {log}");
    }
    eprintln!("MAVProxy's commands: {by_id:?}; executed by the autopilot: {executed}");

    // The typed command: once, ACCEPTED, and the vehicle is in the new mode afterwards.
    let typed: Vec<&&Value> = sent
        .iter()
        .filter(|c| c["command"] == DO_SET_MODE)
        .collect();
    assert_eq!(typed.len(), 1, "DO_SET_MODE sent: {typed:?}");
    assert_eq!(typed[0]["target_system"], 1, "{typed:?}");
    assert_eq!(
        executed[DO_SET_MODE.to_string()],
        1,
        "the autopilot's commands: {executed}"
    );
    let ack = log["acks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["command"] == DO_SET_MODE)
        .unwrap_or_else(|| panic!("no DO_SET_MODE ack in MAVProxy's log: {log}"));
    assert_eq!(ack["result"], 0, "DO_SET_MODE not ACCEPTED: {ack}");
    assert!(f(ack, "t") >= f(typed[0], "t"), "ack before the command");
    let modes: Vec<(f64, u64)> = log["modes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m["sender"] == "1/1")
        .map(|m| (f(m, "t"), m["custom_mode"].as_u64().unwrap()))
        .collect();
    assert_eq!(
        modes.iter().map(|m| m.1).collect::<Vec<_>>(),
        [MODE_MISSION, MODE_LOITER],
        "vehicle modes seen by MAVProxy: {modes:?}"
    );
    assert!(modes[1].0 >= f(ack, "t"), "{modes:?}, ack {ack}");
    assert_eq!(fc_said["custom_mode"], MODE_LOITER, "{fc_said}");

    eprintln!("wall time {:.1} s", started.elapsed().as_secs_f64());
    let _ = std::fs::remove_dir_all(&dir);
}
