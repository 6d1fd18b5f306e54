//! `cargo bench -p harness-sim --features mavlora/cli --bench router_cost`: what the ground
//! router costs the machine.
//!
//! It runs the real programs of the same build: `mavlora-router` and `mavlora-bridge` next
//! to the benchmark's target folder (`target/release/` for `cargo bench`), so build them
//! first with the same profile: `cargo build --release -p mavlora --bins`
//! (`MAVLORA_BENCH_ROUTER` names another router to measure, e.g. another build to compare).
//!
//! 1. **CPU per frame and peak memory.** A simulated PX4 flight (60 s of PX4 on its USB
//!    "Config" stream profile, the densest, at full rate) is replayed
//!    `MAVLORA_BENCH_ROUNDS` times (default 60, about 1.1 M frames) into
//!    the radio's pty as fast as the pty accepts it; a UDP ground station counts what comes
//!    out. Measured in the same run, one after the other, on a fresh pty each:
//!    - the **baseline**: a relay process that reads the same pty the same way, checks each
//!      frame with the same reader and sends it as one datagram (one `sendto` per frame, as
//!      mavlink-router does): the least a forwarder to UDP must do;
//!    - `mavlora-router --unsigned`, and `mavlora-router` with a signing key (frames signed
//!      by the replaying side; each one is verified).
//!
//!    CPU is each process's time on a core (every thread, from `/proc/PID/task/*/schedstat`)
//!    from the first replayed byte until the last frame is out; peak RSS is `VmHWM`.
//!    Targets: CPU per frame <= 0.5 x the baseline's, peak RSS <= 8 MB.
//! 2. **Idle.** The router and the bridge with ports open and nothing coming in, for
//!    `MAVLORA_BENCH_IDLE_S` seconds (default 10): CPU per second and wakeups per second, by
//!    thread. What remains is the engines' own timers (heartbeats, link-quality reports,
//!    the status line).

use std::fs;
use std::io::Write;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use mavlink::MavlinkVersion;
use serialport::SerialPort as _;

use mavlora::dialect::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavType};
use mavlora::io::signing_epoch_now;
use mavlora::signing::{LinkSigner, SigningKey};
use mavlora::wire::{FrameReader, OwnedFrame, Sender};

mod common;
use common::px4_capture;
use harness_sim::PX4_CONFIG;
use testkit::{Guard, pty_pair};

/// The router measured: this build's, or `MAVLORA_BENCH_ROUTER` (another build, to compare).
fn router_program() -> PathBuf {
    std::env::var_os("MAVLORA_BENCH_ROUTER")
        .map_or_else(|| program("mavlora-router"), PathBuf::from)
}

/// A program of this build: in the target folder above `deps/`, where cargo puts this
/// benchmark. Another package's programs are not built for a benchmark, so this one cannot
/// ask cargo for them (`CARGO_BIN_EXE_*` is only for a package's own).
fn program(name: &str) -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let path = exe.parent().and_then(Path::parent).unwrap().join(name);
    assert!(
        path.exists(),
        "{} not found: build it first with `cargo build --release -p mavlora --bins`",
        path.display()
    );
    path
}

/// The system id of the replayed autopilot: its component 1's frames are what the ground
/// counts (the router speaks for the vehicle's radio as component 68 besides).
const VEHICLE: u8 = 1;
/// Argument that makes this program the baseline relay (it runs itself as a child).
const RELAY_ARG: &str = "--relay-baseline";

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == RELAY_ARG) {
        relay(
            &args[i + 1],
            args[i + 2].parse().expect("relay destination"),
        );
        return;
    }
    // Found before anything runs: a missing program fails here, not after the baseline.
    let (router_exe, bridge_exe) = (router_program(), program("mavlora-bridge"));
    let rounds: usize = env_or("MAVLORA_BENCH_ROUNDS", 60);
    let idle_s: u64 = env_or("MAVLORA_BENCH_IDLE_S", 10);
    let dir = tempdir();
    let key = SigningKey([0x5a; 32]);
    let key_path = dir.join("radio.key");
    fs::write(&key_path, key.to_hex()).unwrap();
    set_mode_600(&key_path);

    let capture: Vec<Vec<u8>> = px4_capture(PX4_CONFIG)
        .into_iter()
        .map(|(_, b)| b)
        .collect();
    let flight_bytes: usize = capture.iter().map(Vec::len).sum();
    println!(
        "router cost: {} frames ({rounds} replays of 60 s of PX4 Config, {} B/s) into a pty as fast as it accepts them, out to UDP",
        capture.len() * rounds,
        flight_bytes / 60
    );
    let me = std::env::current_exe().unwrap();
    let plain = || Feed::new(&capture, rounds, None);
    let baseline = replay("baseline", plain(), |pty, sink| {
        Command::new(&me)
            .args([RELAY_ARG, pty, &sink.to_string()])
            .spawn()
            .unwrap()
    });
    let log = dir.join("router.log");
    let unsigned = replay("mavlora-router --unsigned", plain(), |pty, sink| {
        router(&router_exe, pty, sink, &["--unsigned"], &log)
    });
    let unsigned_log = file_len(&log);
    let (key_arg, state) = (key_path.to_str().unwrap(), dir.join("state"));
    // A router that knows the bridge's link from a previous run: a fresh one would hold the
    // bridge's frames until it answered a liveness challenge, and the replay answers none.
    let known = signing_epoch_now().saturating_sub(100_000);
    fs::write(
        &state,
        format!("mavlora-signing-state 1\ntimestamp {known}\nstream 1 1 1 {known}\n"),
    )
    .unwrap();
    let signed_log = dir.join("router-signed.log");
    let signed_feed = Feed::new(&capture, rounds, Some(key));
    let signed = replay("mavlora-router --key", signed_feed, |pty, sink| {
        let state = state.to_str().unwrap();
        router(
            &router_exe,
            pty,
            sink,
            &["--key", key_arg, "--signing-state", state],
            &signed_log,
        )
    });
    println!("CPU per frame and peak memory (lower is better):");
    baseline.print(&baseline, "baseline, one sendto per frame", 0);
    unsigned.print(&baseline, "mavlora-router --unsigned", unsigned_log);
    signed.print(
        &baseline,
        "mavlora-router --key (verifies)",
        file_len(&signed_log),
    );
    println!("  (targets: <= 0.50 x baseline CPU per frame, peak RSS <= 8192 kB)");

    idle(&router_exe, &bridge_exe, idle_s, &dir);
    let _ = fs::remove_dir_all(&dir);
}

fn file_len(path: &Path) -> u64 {
    fs::metadata(path).map(|m| m.len()).unwrap_or(0)
}

/// What the replaying side writes: the flight `rounds` times, as it is or signed as the
/// bridge would sign it (fresh timestamps each round: a replayed signature is rejected).
struct Feed {
    frames: Vec<Vec<u8>>,
    rounds: usize,
    signer: Option<(LinkSigner, Instant)>,
}

impl Feed {
    fn new(capture: &[Vec<u8>], rounds: usize, key: Option<SigningKey>) -> Self {
        Self {
            frames: capture.to_vec(),
            rounds,
            signer: key.map(|k| (LinkSigner::new(k, 1, signing_epoch_now()), Instant::now())),
        }
    }

    fn encode(&mut self, frame: &[u8], out: &mut Vec<u8>) {
        match &mut self.signer {
            None => out.extend_from_slice(frame),
            Some((signer, start)) => {
                let now = mavlora::Instant::from_micros(start.elapsed().as_micros() as u64);
                let frame = OwnedFrame::new_checked(frame.to_vec()).unwrap();
                out.extend_from_slice(signer.sign(&frame, now).unwrap().as_bytes());
            }
        }
    }

    fn frames_in(&self) -> usize {
        self.frames.len() * self.rounds
    }

    /// Writes every round into `to`, a round at a time.
    fn write_all(mut self, to: &mut impl Write) {
        let frames = std::mem::take(&mut self.frames);
        let mut round = Vec::new();
        for _ in 0..self.rounds {
            round.clear();
            for f in &frames {
                self.encode(f, &mut round);
            }
            to.write_all(&round).unwrap();
        }
    }
}

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn tempdir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mavlora-bench-{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    dir
}

fn set_mode_600(path: &Path) {
    use std::os::unix::fs::PermissionsExt;
    fs::set_permissions(path, fs::Permissions::from_mode(0o600)).unwrap();
}

fn router(program: &Path, pty: &str, sink: SocketAddr, extra: &[&str], log: &Path) -> Child {
    Command::new(program)
        .args(["--radio", pty, "--udp", &sink.to_string()])
        .args(["--udp-bind", "127.0.0.1:0"])
        .args(extra)
        .stderr(fs::File::create(log).unwrap())
        .spawn()
        .unwrap()
}

/// One process's figures for one replay.
struct Run {
    frames_in: usize,
    frames_out: u64,
    datagrams: u64,
    cpu: Duration,
    wall: Duration,
    peak_rss_kb: u64,
}

impl Run {
    fn print(&self, baseline: &Run, label: &str, log_bytes: u64) {
        let per_frame = |r: &Run| r.cpu.as_secs_f64() * 1e6 / r.frames_in as f64;
        let lost = self.frames_in as i64 - self.frames_out as i64;
        println!(
            "  {label:<34} {:>6.2} us/frame ({:.2} x baseline)  peak RSS {:>6} kB  {:>5.2} frames/datagram  {} of {} frames out{}  {:.1} s{}",
            per_frame(self),
            per_frame(self) / per_frame(baseline),
            self.peak_rss_kb,
            self.frames_out as f64 / self.datagrams.max(1) as f64,
            self.frames_out,
            self.frames_in,
            if lost == 0 {
                String::new()
            } else {
                format!(" ({lost} missing)")
            },
            self.wall.as_secs_f64(),
            if log_bytes > 0 {
                format!("  log {log_bytes} B")
            } else {
                String::new()
            },
        );
    }
}

/// A UDP ground station that counts the vehicle's frames (however many share a datagram).
struct Sink {
    addr: SocketAddr,
    frames: Arc<AtomicU64>,
    datagrams: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
}

impl Sink {
    fn start() -> Self {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        // Room for bursts: the ground must not be where frames are lost.
        let _ = rustix::net::sockopt::set_socket_recv_buffer_size(&socket, 8 << 20);
        socket
            .set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        let (frames, datagrams) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
        let stop = Arc::new(AtomicBool::new(false));
        let sink = Self {
            addr: socket.local_addr().unwrap(),
            frames: frames.clone(),
            datagrams: datagrams.clone(),
            stop: stop.clone(),
        };
        thread::spawn(move || {
            let mut buf = vec![0u8; 65_536];
            let mut reader = FrameReader::new();
            while !stop.load(Ordering::Relaxed) {
                let Ok(n) = socket.recv(&mut buf) else {
                    continue;
                };
                datagrams.fetch_add(1, Ordering::Relaxed);
                reader.push(&buf[..n]);
                while let Some(r) = reader.next_frame() {
                    if (r.frame.system_id(), r.frame.component_id()) == (VEHICLE, 1) {
                        frames.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
        });
        sink
    }
}

impl Drop for Sink {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// Replays `feed` into a fresh pty read by the process `spawn` starts, and measures that
/// process from the first replayed byte to the last frame out.
fn replay(
    label: &'static str,
    mut feed: Feed,
    spawn: impl FnOnce(&str, SocketAddr) -> Child,
) -> Run {
    let (mut master, slave) = pty_pair();
    let sink = Sink::start();
    let mut child = Guard(
        Some(spawn(slave.name().as_deref().unwrap(), sink.addr)),
        label,
    );
    let pid = child.0.as_ref().map_or(0, Child::id);
    // Ready when a heartbeat gets through.
    let mut sender = Sender::new(VEHICLE, 1, MavlinkVersion::V2);
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        ..Default::default()
    });
    let ready = Instant::now() + Duration::from_secs(20);
    while sink.frames.load(Ordering::Relaxed) == 0 {
        assert!(Instant::now() < ready, "{label}: nothing came out in 20 s");
        let mut bytes = Vec::new();
        feed.encode(sender.frame(&hb).as_bytes(), &mut bytes);
        master.write_all(&bytes).unwrap();
        thread::sleep(Duration::from_millis(100));
    }
    thread::sleep(Duration::from_millis(300));
    let before_frames = sink.frames.load(Ordering::Relaxed);
    let before_datagrams = sink.datagrams.load(Ordering::Relaxed);
    let frames_in = feed.frames_in();
    let before = cpu(pid);
    let start = Instant::now();
    let writer = thread::spawn(move || {
        feed.write_all(&mut master);
        master
    });
    let mut progress = Instant::now();
    let mut last = (0, Instant::now());
    loop {
        thread::sleep(Duration::from_millis(20));
        let out = sink.frames.load(Ordering::Relaxed) - before_frames;
        if out != last.0 {
            last = (out, Instant::now());
        }
        if out as usize >= frames_in {
            break;
        }
        if writer.is_finished() && last.1.elapsed() > Duration::from_secs(1) {
            break;
        }
        if let Some(Ok(Some(status))) = child.0.as_mut().map(Child::try_wait) {
            panic!("{label}: exited during the replay: {status}");
        }
        if progress.elapsed() > Duration::from_secs(5) {
            progress = Instant::now();
            eprintln!("  {label}: {out} of {frames_in} frames out");
        }
    }
    let wall = last.1 - start;
    let after = cpu(pid);
    let peak_rss_kb = vm_hwm_kb(pid);
    let _master = writer.join().unwrap();
    Run {
        frames_in,
        frames_out: last.0,
        datagrams: sink.datagrams.load(Ordering::Relaxed) - before_datagrams,
        cpu: after.saturating_sub(before),
        wall,
        peak_rss_kb,
    }
}

/// Time on a core of every thread of `pid` so far.
fn cpu(pid: u32) -> Duration {
    Duration::from_nanos(threads(pid).iter().map(|t| t.cpu_ns).sum())
}

struct ThreadSample {
    tid: std::ffi::OsString,
    name: String,
    cpu_ns: u64,
    switches: u64,
}

fn threads(pid: u32) -> Vec<ThreadSample> {
    let mut out = Vec::new();
    for task in fs::read_dir(format!("/proc/{pid}/task")).unwrap() {
        let task = task.unwrap().path();
        let Ok(schedstat) = fs::read_to_string(task.join("schedstat")) else {
            continue;
        };
        let cpu_ns = schedstat
            .split_whitespace()
            .next()
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        let status = fs::read_to_string(task.join("status")).unwrap_or_default();
        let switches = ["voluntary_ctxt_switches:", "nonvoluntary_ctxt_switches:"]
            .iter()
            .map(|k| field(&status, k))
            .sum();
        let name = fs::read_to_string(task.join("comm"))
            .unwrap_or_default()
            .trim()
            .to_string();
        out.push(ThreadSample {
            tid: task.file_name().unwrap_or_default().to_owned(),
            name,
            cpu_ns,
            switches,
        });
    }
    out
}

fn field(status: &str, key: &str) -> u64 {
    status
        .lines()
        .find_map(|l| l.strip_prefix(key))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

fn vm_hwm_kb(pid: u32) -> u64 {
    field(
        &fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default(),
        "VmHWM:",
    )
}

/// The baseline: read the pty, check each frame, one datagram per frame.
fn relay(pty: &str, to: SocketAddr) {
    let mut port = serialport::new(pty, 115_200)
        .timeout(Duration::from_secs(3600))
        .open()
        .expect("baseline relay: open the pty");
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut reader = FrameReader::new();
    let mut buf = [0u8; 4096];
    loop {
        match std::io::Read::read(&mut port, &mut buf) {
            Ok(0) => return,
            Ok(n) => {
                reader.push(&buf[..n]);
                while let Some(r) = reader.next_frame() {
                    let _ = socket.send_to(r.frame.as_bytes(), to);
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(_) => return,
        }
    }
}

/// Router and bridge with open ports and no traffic: CPU and wakeups per second by thread.
fn idle(router_exe: &Path, bridge_exe: &Path, seconds: u64, dir: &Path) {
    let (_radio_master, radio_slave) = pty_pair();
    let (_fc_master, fc_slave) = pty_pair();
    let (_bridge_radio_master, bridge_radio_slave) = pty_pair();
    let sink = Sink::start();
    let profile = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../firmware/mavlora/profiles/px4-normal.toml"
    );
    let router = router(
        router_exe,
        radio_slave.name().as_deref().unwrap(),
        sink.addr,
        &["--unsigned"],
        &dir.join("idle-router.log"),
    );
    let bridge = Command::new(bridge_exe)
        .args(["--fc", fc_slave.name().as_deref().unwrap()])
        .args(["--radio", bridge_radio_slave.name().as_deref().unwrap()])
        .args(["--profile", profile, "--unsigned"])
        .stderr(fs::File::create(dir.join("idle-bridge.log")).unwrap())
        .spawn()
        .unwrap();
    let pids = [
        ("mavlora-router", router.id()),
        ("mavlora-bridge", bridge.id()),
    ];
    let _guards = [
        Guard(Some(router), "mavlora-router"),
        Guard(Some(bridge), "mavlora-bridge"),
    ];
    // Past start-up (ports opened, first heartbeats sent).
    thread::sleep(Duration::from_secs(2));
    let before: Vec<_> = pids.iter().map(|(_, pid)| threads(*pid)).collect();
    thread::sleep(Duration::from_secs(seconds));
    println!("idle for {seconds} s, ports open, nothing coming in (lower is better):");
    for ((name, pid), before) in pids.iter().zip(before) {
        let after = threads(*pid);
        let per_s = |v: u64| v as f64 / seconds as f64;
        let total_cpu: u64 = after.iter().map(|t| t.cpu_ns).sum::<u64>()
            - before.iter().map(|t| t.cpu_ns).sum::<u64>();
        let total_switches: u64 = after.iter().map(|t| t.switches).sum::<u64>()
            - before.iter().map(|t| t.switches).sum::<u64>();
        println!(
            "  {name:<16} {:>8.1} us CPU/s  {:>6.1} wakeups/s",
            per_s(total_cpu) / 1e3,
            per_s(total_switches)
        );
        for t in &after {
            let b = before.iter().find(|b| b.tid == t.tid);
            let cpu = t.cpu_ns - b.map_or(0, |b| b.cpu_ns.min(t.cpu_ns));
            let sw = t.switches - b.map_or(0, |b| b.switches.min(t.switches));
            if sw > 0 {
                println!(
                    "    thread {:<14} {:>8.1} us CPU/s  {:>6.1} wakeups/s",
                    t.name,
                    per_s(cpu) / 1e3,
                    per_s(sw)
                );
            }
        }
    }
}
