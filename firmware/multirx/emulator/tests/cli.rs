//! The real `multirx-emu` binary on real pty pairs.

use std::io::{Read, Write};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use multirx_core::wire::{SbusFrame, SbusRepr};
use multirx_core::{Config, Mode};
use serialport::{SerialPort, TTYPort};

const EMU: &str = env!("CARGO_BIN_EXE_multirx-emu");

struct Pty {
    master: TTYPort,
    // Held open so the master never reads EIO while the device (re)opens it.
    slave: TTYPort,
}

impl Pty {
    fn new() -> Pty {
        let (mut master, slave) = TTYPort::pair().expect("pty pair");
        master.set_timeout(Duration::from_millis(50)).unwrap();
        // serialport opens the master without close-on-exec: a spawned device would
        // hold it open, and closing ours would never hang the line up.
        for port in [&master, &slave] {
            use std::os::fd::{AsRawFd, BorrowedFd};
            // SAFETY: the descriptor belongs to `port`, alive for this call.
            let fd = unsafe { BorrowedFd::borrow_raw(port.as_raw_fd()) };
            rustix::io::fcntl_setfd(fd, rustix::io::FdFlags::CLOEXEC).unwrap();
        }
        Pty { master, slave }
    }
    fn path(&self) -> String {
        self.slave.name().unwrap()
    }
}

struct Killed(Child);
impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The emulator on `config`, with a receiver port per `rx` (in receiver order) and `fc`;
/// stdin closed.
fn emu(config: &std::path::Path, rx: &[&str], fc: &str) -> Command {
    let mut command = Command::new(EMU);
    command.arg("--config").arg(config);
    for port in rx {
        command.args(["--rx", port]);
    }
    command.args(["--fc", fc]).stdin(Stdio::null());
    command
}

fn write_config(dir: &std::path::Path, text: &str) -> std::path::PathBuf {
    let path = dir.join("multirx.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn bad_config_names_file_line_and_field() {
    let tmp = tempdir();
    let dir = tmp.path();
    let path = write_config(
        dir,
        "mode = \"parallel\"\nreceivers = 2\n[link]\nacquire_frames = 0\n",
    );
    let out = Command::new(EMU)
        .args([
            "--config",
            path.to_str().unwrap(),
            "--rx",
            "/dev/null",
            "--rx",
            "/dev/null",
            "--fc",
            "/dev/null",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!(
            "{}:4:1: link.acquire_frames: 0 is outside 1..=20",
            path.display()
        )),
        "{stderr}"
    );
}

#[test]
fn forwards_the_active_receiver_and_reports_power() {
    let tmp = tempdir();
    let dir = tmp.path();
    let path = write_config(dir, "mode = \"parallel\"\nreceivers = 2\n");
    let config = Config::new(Mode::Parallel, 2);
    let (mut rx0, rx1, mut fc, mut status) = (Pty::new(), Pty::new(), Pty::new(), Pty::new());
    let _child = Killed(
        emu(&path, &[&rx0.path(), &rx1.path()], &fc.path())
            .args(["--status", &status.path()])
            .spawn()
            .unwrap(),
    );

    let sticks = SbusRepr {
        channels: [1234; 16],
        ..SbusRepr::default()
    }
    .to_bytes();
    let start = Instant::now();
    let mut frames = Vec::new();
    let mut buf = [0u8; 512];
    let mut pending = Vec::new();
    while start.elapsed() < Duration::from_secs(3) {
        rx0.master.write_all(&sticks).unwrap();
        if let Ok(n) = fc.master.read(&mut buf) {
            pending.extend_from_slice(&buf[..n]);
        }
        while pending.len() >= 25 {
            let frame: Vec<u8> = pending.drain(..25).collect();
            frames.push(SbusRepr::parse(&SbusFrame::new_checked(&frame[..]).unwrap()).unwrap());
        }
        std::thread::sleep(Duration::from_millis(7));
    }
    assert!(frames.len() > 100, "only {} frames in 3 s", frames.len());
    let last = frames.last().unwrap();
    assert_eq!(last.channels[0], 1234);
    assert_eq!(
        last.channels[usize::from(config.pilot_channel)],
        config.pilot_values[0]
    );

    let mut text = String::new();
    let mut buf = [0u8; 4096];
    if let Ok(n) = status.master.read(&mut buf) {
        text.push_str(&String::from_utf8_lossy(&buf[..n]));
    }
    for expected in [" power 0 on", " power 1 on", " active 0"] {
        assert!(
            text.contains(expected),
            "{expected} missing from status:\n{text}"
        );
    }
    // The boot line: this config's hash, the emulated image's build id, and
    // the first frame within the 50 ms the firmware must meet too.
    let boot = text
        .lines()
        .find_map(|l| multirx_core::BootReport::parse_line(l).ok())
        .unwrap_or_else(|| panic!("no boot line in status:\n{text}"));
    let hash = config.identity_hash();
    assert_eq!(boot.config_hash, hash, "{text}");
    assert_eq!(
        boot.build_id,
        multirx_core::boot::build_id(
            multirx_core::boot::ImageKind::Emulated,
            hash,
            // The same source id build.rs compiled into the program.
            u64::from_str_radix(env!("MULTIRX_SOURCE_ID"), 16).unwrap()
        )
    );
    assert!(boot.first_frame.as_millis() < 50, "{boot}");
    drop(rx1);
}

/// Frames the flight controller side read since the last call.
fn read_frames(fc: &mut Pty, pending: &mut Vec<u8>) -> Vec<SbusRepr> {
    let mut buf = [0u8; 512];
    let mut frames = Vec::new();
    if let Ok(n) = fc.master.read(&mut buf) {
        pending.extend_from_slice(&buf[..n]);
    }
    while pending.len() >= 25 {
        let frame: Vec<u8> = pending.drain(..25).collect();
        if let Ok(view) = SbusFrame::new_checked(&frame[..])
            && let Ok(repr) = SbusRepr::parse(&view)
        {
            frames.push(repr);
        }
    }
    frames
}

fn sticks(value: u16) -> [u8; 25] {
    SbusRepr {
        channels: [value; 16],
        ..SbusRepr::default()
    }
    .to_bytes()
}

/// Feeds `value` on `rx` until the flight controller sees it from pilot 0, or `limit` passes.
fn until_pilot0_shows(rx: &mut Pty, fc: &mut Pty, value: u16, limit: Duration) -> bool {
    let config = Config::new(Mode::Parallel, 2);
    let (start, mut pending) = (Instant::now(), Vec::new());
    while start.elapsed() < limit {
        let _ = rx.master.write_all(&sticks(value));
        if read_frames(fc, &mut pending).iter().any(|f| {
            f.channels[0] == value
                && f.channels[usize::from(config.pilot_channel)] == config.pilot_values[0]
        }) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(7));
    }
    false
}

/// Regression: a receiver port that went away was never reopened, so its pilot
/// could not take control again after the adapter came back.
#[test]
fn a_receiver_that_goes_away_is_heard_again_when_it_comes_back() {
    let tmp = tempdir();
    let dir = tmp.path();
    let path = write_config(dir, "mode = \"parallel\"\nreceivers = 2\n");
    // A stable name for the receiver, as /dev/serial/by-id gives a USB adapter.
    let link = dir.join("rx0");
    let mut first = Pty::new();
    std::os::unix::fs::symlink(first.path(), &link).unwrap();
    let (rx1, mut fc) = (Pty::new(), Pty::new());
    let mut child = Killed(
        emu(&path, &[link.to_str().unwrap(), &rx1.path()], &fc.path())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    assert!(until_pilot0_shows(
        &mut first,
        &mut fc,
        1111,
        Duration::from_secs(3)
    ));

    // Unplugged: the port vanishes; another appears under the same name.
    drop(first);
    std::fs::remove_file(&link).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let mut second = Pty::new();
    std::os::unix::fs::symlink(second.path(), &link).unwrap();
    let back = until_pilot0_shows(&mut second, &mut fc, 1555, Duration::from_secs(6));
    if !back {
        let _ = child.0.kill();
        let mut err = String::new();
        let _ = child.0.stderr.take().unwrap().read_to_string(&mut err);
        panic!("pilot 0 never came back after the receiver port returned:\n{err}");
    }
    drop(rx1);
}

/// Regression: with its flight-controller port gone the emulator ran on for
/// ever. It must reopen the port for a while, then end with an error, which its
/// status file's stop line gives with the final counters.
#[test]
fn ends_when_the_flight_controller_port_is_gone_for_good() {
    let tmp = tempdir();
    let dir = tmp.path();
    let path = write_config(dir, "mode = \"parallel\"\nreceivers = 1\n");
    let json = dir.join("emu.jsonl");
    let (rx0, fc) = (Pty::new(), Pty::new());
    let started = Instant::now();
    let mut child = emu(&path, &[&rx0.path()], &fc.path())
        .arg("--status-json")
        .arg(&json)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    drop(fc);
    // GONE_AFTER (10 s) of failing writes, plus start-up and slack.
    let limit = Duration::from_secs(20);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            let mut err = String::new();
            let _ = child.stderr.take().unwrap().read_to_string(&mut err);
            panic!("still running {limit:?} after its flight-controller port went away:\n{err}");
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains("flight-controller port gone for good"),
        "{err}"
    );
    let stop = status_lines(&json).pop().unwrap();
    assert_eq!(stop["kind"], "stop", "{stop}");
    assert_eq!(stop["exit_code"], 1, "{stop}");
    assert!(
        stop["error"]
            .as_str()
            .is_some_and(|e| e.starts_with("flight-controller port gone for good")),
        "{stop}"
    );
    assert!(
        stop["counters"]["frames_out"].as_u64().unwrap() > 0,
        "{stop}"
    );
    drop(rx0);
}

/// A stopped process is what a host hold looks like from inside: the TX probe shows the
/// holes in host time, and none in device time, where the output keeps its period (the
/// rig judges 1.5 periods there). Invariant: what the host takes is held, whole.
#[test]
fn a_stopped_device_is_held_and_keeps_its_cadence_in_device_time() {
    let tmp = tempdir();
    let dir = tmp.path();
    let path = write_config(dir, "mode = \"parallel\"\nreceivers = 1\n");
    let tx_log = dir.join("tx.log");
    let (rx0, mut fc) = (Pty::new(), Pty::new());
    let child = Killed(
        emu(&path, &[&rx0.path()], &fc.path())
            .arg("--tx-log")
            .arg(&tx_log)
            .spawn()
            .unwrap(),
    );
    let pid = child.0.id().to_string();
    let signal = |sig: &str| {
        let ok = Command::new("kill").args([sig, &pid]).status().unwrap();
        assert!(ok.success(), "kill {sig}");
    };
    // Drain the flight-controller side meanwhile, as a flight controller would.
    let mut drain = |for_: Duration| {
        let until = Instant::now() + for_;
        let mut buf = [0u8; 512];
        while Instant::now() < until {
            let _ = fc.master.read(&mut buf);
        }
    };
    drain(Duration::from_millis(800));
    const STOP: Duration = Duration::from_millis(60);
    for _ in 0..3 {
        signal("-STOP");
        std::thread::sleep(STOP);
        signal("-CONT");
        drain(Duration::from_millis(300));
    }
    drop(child);
    let text = std::fs::read_to_string(&tx_log).unwrap();
    let lines: Vec<(f64, f64)> = text
        .lines()
        .filter_map(|l| {
            let (sent, held) = l.split_once(' ')?;
            Some((sent.parse().ok()?, held.parse().ok()?))
        })
        .collect();
    assert!(lines.len() > 100, "{} frames:\n{text}", lines.len());
    let (mut host_gap, mut device_gap) = (0f64, 0f64);
    for w in lines.windows(2) {
        let host = w[1].0 - w[0].0;
        host_gap = host_gap.max(host);
        device_gap = device_gap.max(host - (w[1].1 - w[0].1));
    }
    let held = lines.last().unwrap().1;
    assert!(
        host_gap >= STOP.as_secs_f64(),
        "the stops show in host time: {host_gap}"
    );
    // Each stop is held but for the part that fell in the device's own wait for its next
    // frame (up to one 7 ms period): that time the device was idle anyway.
    assert!(
        held >= 3.0 * (STOP.as_secs_f64() - 0.007),
        "held {held} s in all"
    );
    // 1.5 frame periods of the default config's 7 ms.
    assert!(
        device_gap <= 0.0105,
        "device-time gap {:.2} ms (host {:.2} ms)",
        device_gap * 1000.0,
        host_gap * 1000.0
    );
    drop(rx0);
}

/// The complete lines of a status JSON file, each parsed with `serde_json` (a line still
/// being written is left out); panics naming a complete line that is not JSON.
fn status_lines(path: &std::path::Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let complete = &text[..text.rfind('\n').map_or(0, |i| i + 1)];
    complete
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect()
}

/// The emulator's counters (firmware/hostio/STATUS-JSON.md).
const COUNTERS: [&str; 5] = [
    "frames_out",
    "frames_dropped",
    "status_lines",
    "max_gap_ms",
    "host_held_ms",
];

/// `--status-json`: a start line naming what runs, status lines while it runs (read here
/// while it runs), a stop line with the final counters; every line whole, schema
/// `c2-status/1`, counters never going down, and `frames_out` every frame the flight
/// controller side read.
#[test]
fn status_json_reports_from_start_to_stop_every_frame_out() {
    let tmp = tempdir();
    let dir = tmp.path();
    let path = write_config(dir, "mode = \"parallel\"\nreceivers = 1\n");
    let json = dir.join("emu.jsonl");
    let (mut rx0, mut fc) = (Pty::new(), Pty::new());
    let mut child = Killed(
        emu(&path, &[&rx0.path()], &fc.path())
            .args(["--status-interval", "0.2", "--status-json"])
            .arg(&json)
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    // Read everything the flight controller side gets, until the device has stopped.
    let mut bytes = 0usize;
    let mut buf = [0u8; 512];
    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(1500) {
        let _ = rx0.master.write_all(&sticks(1234));
        if let Ok(n) = fc.master.read(&mut buf) {
            bytes += n;
        }
        std::thread::sleep(Duration::from_millis(7));
    }
    let running = status_lines(&json);
    let statuses_while_running = running.iter().filter(|l| l["kind"] == "status").count();
    let ok = Command::new("kill")
        .args(["-TERM", &child.0.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let exit = child.0.wait().unwrap();
    while let Ok(n) = fc.master.read(&mut buf) {
        if n == 0 {
            break;
        }
        bytes += n;
    }
    assert!(exit.success(), "{exit:?}");
    assert!(statuses_while_running >= 2, "{running:?}");

    let text = std::fs::read_to_string(&json).unwrap();
    assert!(text.ends_with('\n'), "{text}");
    let lines = status_lines(&json);
    let kinds: Vec<&str> = lines.iter().map(|l| l["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds[0], "start", "{text}");
    assert_eq!(*kinds.last().unwrap(), "stop", "{text}");
    assert!(
        kinds[1..kinds.len() - 1].iter().all(|&k| k == "status"),
        "{kinds:?}"
    );
    for line in &lines {
        assert_eq!(line["schema"], "c2-status/1", "{line}");
        assert_eq!(line["program"], "multirx-emu", "{line}");
    }
    let start = &lines[0];
    assert_eq!(start["pid"], child.0.id(), "{start}");
    assert_eq!(start["options"]["mode"], "parallel", "{start}");
    assert_eq!(start["options"]["receivers"], 1, "{start}");
    let hash = Config::new(Mode::Parallel, 1).identity_hash();
    assert_eq!(
        start["options"]["config_hash"],
        format!("{hash:016x}"),
        "{start}"
    );
    let counted = &lines[1..];
    for pair in counted.windows(2) {
        for name in COUNTERS {
            let (a, b) = (&pair[0]["counters"][name], &pair[1]["counters"][name]);
            assert!(
                b.as_f64().unwrap() >= a.as_f64().unwrap(),
                "{name} went down:\n{}\n{}",
                pair[0],
                pair[1]
            );
        }
    }
    let stop = lines.last().unwrap();
    assert_eq!(stop["exit_code"], 0, "{stop}");
    assert!(stop["error"].is_null(), "{stop}");
    assert_eq!(stop["gauges"], serde_json::json!({}), "{stop}");
    let counters = stop["counters"].as_object().unwrap();
    assert_eq!(counters.len(), COUNTERS.len(), "{stop}");
    let frames_out = counters["frames_out"].as_u64().unwrap();
    assert!(frames_out > 100, "{stop}");
    assert_eq!(counters["frames_dropped"], 0, "{stop}");
    // Every frame handed to the port, and no other byte, reached the flight controller side.
    assert_eq!(bytes as u64, 25 * frames_out, "{stop}");
    assert!(counters["max_gap_ms"].as_f64().unwrap() > 0.0, "{stop}");
}

/// A status path that cannot be created ends the device at start with status 1 and an
/// error naming it.
#[test]
fn a_status_path_that_cannot_be_created_is_an_error_naming_it() {
    let tmp = tempdir();
    let dir = tmp.path();
    let path = write_config(dir, "mode = \"parallel\"\nreceivers = 1\n");
    let file = dir.join("a-file");
    std::fs::write(&file, "").unwrap();
    for json in [
        dir.join("no-such-folder").join("emu.jsonl"),
        file.join("emu.jsonl"),
    ] {
        let (rx0, fc) = (Pty::new(), Pty::new());
        let out = emu(&path, &[&rx0.path()], &fc.path())
            .arg("--status-json")
            .arg(&json)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(json.to_str().unwrap()), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

/// A folder of the test's own, removed when the test ends (pass or fail).
fn tempdir() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("multirx-emu-test-")
        .tempdir()
        .unwrap()
}
