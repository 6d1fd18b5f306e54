//! Load on the real binaries, every flood the README's trust model lists: on the router one
//! local sender of 64 KB datagrams, a sweep of 60,000 source addresses, unsigned frames
//! injected on the radio under made-up senders, and TCP clients that push frames, never
//! read, or connect and disconnect past the client limit; on the bridge the flight
//! controller's port flooded with telemetry and garbage and the radio's with garbage,
//! unsigned frames and forged headers. None may grow a program past 8 MB of peak RSS (VmRSS
//! sampled every 50 ms, then VmHWM) or hold up the pilot's commands: a COMMAND_LONG reaches
//! the radio within 1 s of the ground sending it, during or right after a flood, and the
//! router's signed command reaches the flight controller through a flooded bridge.
//! The floods go to 127.0.0.0/8 and ptys only, bounded in count and time; a program is
//! killed early if its RSS passes 256 MB.

use std::io::Read;
use std::io::Write as _;
use std::net::{TcpListener, TcpStream, UdpSocket};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use mavlink::MavlinkVersion;
use serialport::{SerialPort as _, TTYPort};

use mavlora::dialect::{
    ATTITUDE_DATA, COMMAND_LONG_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, MavAutopilot,
    MavCmd, MavMessage, MavType,
};
use mavlora::wire::{FrameReader, Sender};

mod common;

const FLOOD: Duration = Duration::from_secs(5);
const MAX_DATAGRAMS: usize = 1_000_000;
/// Peak RSS either program may reach under any flood.
const RSS_LIMIT_KB: u64 = 8 * 1024;
const KILL_KB: u64 = 256 * 1024;

fn rss_kb(pid: u32, key: &str) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// A program's peak RSS while `busy` says the load goes on, sampled every 50 ms; past
/// [`KILL_KB`] it is killed (and `busy` is left to stop the load).
fn peak_rss_while(router: &mut Child, busy: impl Fn() -> bool) -> u64 {
    let pid = router.id();
    let mut peak_kb = 0;
    while busy() {
        let rss = rss_kb(pid, "VmRSS:").unwrap_or(0);
        peak_kb = peak_kb.max(rss);
        if rss > KILL_KB {
            let _ = router.kill();
            break;
        }
        thread::sleep(Duration::from_millis(50));
    }
    peak_kb
}

/// Stops the router with SIGTERM: whether it exited cleanly, its log, and its last status
/// line.
fn stop(mut router: Child, log: &Path) -> (bool, String, String) {
    let _ = Command::new("kill")
        .args(["-TERM", &router.id().to_string()])
        .status();
    let exited_ok = router.wait().unwrap().success();
    let log_text = std::fs::read_to_string(log).unwrap();
    let status = log_text
        .lines()
        .rev()
        .find(|l| l.contains(" status "))
        .unwrap_or("")
        .to_string();
    (exited_ok, log_text, status)
}

#[test]
fn udp_flood_keeps_router_memory_bounded_and_commands_flowing() {
    let dir = std::env::temp_dir().join(format!("mavlora-flood-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (mut radio, radio_slave) = TTYPort::pair().unwrap();
    radio.set_timeout(Duration::from_millis(100)).unwrap();
    let gcs = UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let log = dir.join("router.log");
    let mut router = Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
        .arg("--unsigned")
        .arg("--radio")
        .arg(radio_slave.name().unwrap())
        .args(["--udp", &gcs.local_addr().unwrap().to_string()])
        .args(["--udp-bind", &format!("127.0.0.1:{port}")])
        .arg("--tlog")
        .arg(dir.join("flood.tlog"))
        .env("RUST_LOG", "info")
        .stderr(Stdio::from(std::fs::File::create(&log).unwrap()))
        .spawn()
        .unwrap();
    let pid = router.id();
    thread::sleep(Duration::from_millis(300));
    let rss_before = rss_kb(pid, "VmRSS:").unwrap_or(0);

    // The radio keeps reading (its content is not the point here).
    let draining = Arc::new(AtomicBool::new(true));
    let mut drain_port = radio.try_clone_native().unwrap();
    let d = draining.clone();
    let drainer = thread::spawn(move || {
        let mut buf = [0u8; 4096];
        while d.load(Ordering::Relaxed) {
            let _ = drain_port.read(&mut buf);
        }
    });

    // 64 KB datagrams of valid ATTITUDE frames, each ending in a partial frame.
    let mut sender = Sender::new(255, 190, MavlinkVersion::V2);
    let mut datagram = Vec::with_capacity(65_507);
    loop {
        let f = sender.frame(&MavMessage::ATTITUDE(ATTITUDE_DATA {
            roll: 0.1,
            ..Default::default()
        }));
        if datagram.len() + f.as_bytes().len() > 65_507 - 10 {
            break;
        }
        datagram.extend_from_slice(f.as_bytes());
    }
    datagram.extend_from_slice(&[0xFD, 0xFF, 0, 0, 0, 255, 190, 0x1E, 0, 0]);
    let flooding = Arc::new(AtomicBool::new(true));
    let f = flooding.clone();
    let flooder = thread::spawn(move || {
        let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
        let start = Instant::now();
        let mut sent = 0usize;
        while f.load(Ordering::Relaxed) && start.elapsed() < FLOOD && sent < MAX_DATAGRAMS {
            if sock.send_to(&datagram, ("127.0.0.1", port)).is_ok() {
                sent += 1;
            }
        }
        (sent, start.elapsed())
    });
    let mut peak_kb = peak_rss_while(&mut router, || !flooder.is_finished());
    flooding.store(false, Ordering::Relaxed);
    let (sent, flood_time) = flooder.join().unwrap();
    peak_kb = peak_kb.max(rss_kb(pid, "VmHWM:").unwrap_or(0));
    draining.store(false, Ordering::Relaxed);
    drainer.join().unwrap();

    // After the flood: one COMMAND_LONG, sent once, must reach the radio within 1 s.
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    let cmd = ground.frame(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        ..Default::default()
    }));
    let sent_at = Instant::now();
    let _ = gcs.send_to(cmd.as_bytes(), ("127.0.0.1", port));
    let mut reader = FrameReader::new();
    let mut buf = [0u8; 4096];
    let mut latency = None;
    while latency.is_none() && sent_at.elapsed() < Duration::from_secs(10) {
        if let Ok(n) = radio.read(&mut buf) {
            reader.push(&buf[..n]);
            while let Some(rx) = reader.next_frame() {
                if let Ok(MavMessage::COMMAND_LONG(c)) = rx.frame.decode::<MavMessage>()
                    && c.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM
                {
                    latency = Some(sent_at.elapsed());
                }
            }
        }
    }
    peak_kb = peak_kb.max(rss_kb(pid, "VmHWM:").unwrap_or(0));

    let (exited_ok, log_text, status) = stop(router, &log);
    let tlog = std::fs::metadata(dir.join("flood.tlog")).map_or(0, |m| m.len());
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!(
        "flood: {sent} datagrams of {} B in {flood_time:?}; router RSS {rss_before} kB before, \
         peak {peak_kb} kB (limit {RSS_LIMIT_KB} kB); command after the flood: {latency:?}; \
         tlog {tlog} B\n{status}",
        65_507
    );
    assert!(sent > 100, "the flood did not happen: {sent} datagrams");
    assert!(
        peak_kb <= RSS_LIMIT_KB,
        "router peak RSS {peak_kb} kB > {RSS_LIMIT_KB} kB\n{status}"
    );
    assert!(
        latency.is_some_and(|t| t < Duration::from_secs(1)),
        "command after the flood reached the radio after {latency:?} (limit 1 s)\n{status}"
    );
    assert!(exited_ok, "{log_text}");
}

/// 60,000 datagrams, each from its own loopback address the ground policy refuses, while
/// unsigned frames under 60,000 made-up senders arrive on a signed radio: every one is
/// counted, none is remembered beyond a bound (they took 9.3 MB and 21.7 MB) or logged
/// beyond 1,024 sources per period (7.9 MB of log).
#[test]
fn address_sweeps_and_unsigned_radio_senders_keep_router_memory_and_log_bounded() {
    let dir = common::temp_dir("flood-sweep");
    let key = common::radio_key(&dir, 0x42);
    let (mut radio, radio_slave) = TTYPort::pair().unwrap();
    radio.set_timeout(Duration::from_millis(100)).unwrap();
    let port = common::free_udp_port();
    let log = dir.join("router.log");
    let mut router = Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
        .arg("--key")
        .arg(&key)
        .arg("--radio")
        .arg(radio_slave.name().unwrap())
        .args(["--udp-bind", &format!("127.0.0.1:{port}")])
        .args(["--status-interval", "1"])
        .env("RUST_LOG", "info")
        .current_dir(&dir)
        .stderr(Stdio::from(std::fs::File::create(&log).unwrap()))
        .spawn()
        .unwrap();
    let pid = router.id();
    thread::sleep(Duration::from_millis(300));
    let rss_before = rss_kb(pid, "VmRSS:").unwrap_or(0);

    let mut drain_port = radio.try_clone_native().unwrap();
    let injector = thread::spawn(move || {
        // Unsigned HEARTBEATs, each under its own (system, component) and sequence.
        for k in 0..60_000u32 {
            let [a, b, c, _] = k.to_le_bytes();
            let mut s = Sender::new(a, b, MavlinkVersion::V2);
            s.set_next_sequence(c);
            let f = s.frame(&MavMessage::HEARTBEAT(Default::default()));
            let _ = std::io::Write::write_all(&mut drain_port, f.as_bytes());
        }
    });
    let sweeper = thread::spawn(move || {
        let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
        let hb = ground.frame(&MavMessage::HEARTBEAT(Default::default()));
        let mut sent = 0;
        for k in 0..60_000u32 {
            let [a, b, _, _] = (k + 2).to_le_bytes();
            let Ok(sock) = UdpSocket::bind((std::net::Ipv4Addr::new(127, 1, b, a), 0)) else {
                continue;
            };
            if sock.send_to(hb.as_bytes(), ("127.0.0.1", port)).is_ok() {
                sent += 1;
            }
        }
        sent
    });
    let mut peak_kb = peak_rss_while(&mut router, || {
        !(sweeper.is_finished() && injector.is_finished())
    });
    let sent = sweeper.join().unwrap();
    injector.join().unwrap();
    // Let the router read what is queued, then stop it.
    thread::sleep(Duration::from_millis(1500));
    peak_kb = peak_kb.max(rss_kb(pid, "VmHWM:").unwrap_or(0));
    let (exited_ok, log_text, status) = stop(router, &log);
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!(
        "sweep: {sent} datagrams from as many addresses, 60000 unsigned radio senders; router \
         RSS {rss_before} kB before, peak {peak_kb} kB (limit {RSS_LIMIT_KB} kB); log {} B\n{status}",
        log_text.len()
    );
    assert!(sent > 50_000, "the sweep did not happen: {sent} datagrams");
    assert!(
        peak_kb <= RSS_LIMIT_KB,
        "router peak RSS {peak_kb} kB > {RSS_LIMIT_KB} kB\n{status}"
    );
    // 1,024 sources logged per period at ~200 bytes a line, and the rest of a run's log.
    assert!(
        log_text.len() < 1 << 20,
        "{} B of log for a sweep\n{status}",
        log_text.len()
    );
    assert!(status.contains("rejected_unsigned="), "{status}");
    assert!(exited_ok, "{log_text}");
}

/// When each COMMAND_LONG's command id first came out of a port.
type Arrivals = Arc<std::sync::Mutex<Vec<(MavCmd, Instant)>>>;

/// Reads `port` until `stop`, noting when each COMMAND_LONG's command id first came out of it.
fn watch_commands(mut port: TTYPort, stop: Arc<AtomicBool>) -> (Arrivals, thread::JoinHandle<u64>) {
    let seen = Arc::new(std::sync::Mutex::new(Vec::new()));
    let s = seen.clone();
    let watcher = thread::spawn(move || {
        let mut reader = FrameReader::new();
        let mut buf = [0u8; 4096];
        let mut total = 0u64;
        while !stop.load(Ordering::Relaxed) {
            if let Ok(n) = port.read(&mut buf) {
                total += n as u64;
                reader.push(&buf[..n]);
                while let Some(rx) = reader.next_frame() {
                    if let Ok(MavMessage::COMMAND_LONG(c)) = rx.frame.decode::<MavMessage>() {
                        let mut seen = s.lock().unwrap();
                        if !seen.iter().any(|(id, _)| *id == c.command) {
                            seen.push((c.command, Instant::now()));
                        }
                    }
                }
            }
        }
        total
    });
    (seen, watcher)
}

/// How long after `sent` the command `id` was first seen, waiting up to `wait` for it.
fn latency(
    seen: &std::sync::Mutex<Vec<(MavCmd, Instant)>>,
    id: MavCmd,
    sent: Instant,
    wait: Duration,
) -> Option<Duration> {
    while sent.elapsed() < wait {
        if let Some((_, at)) = seen.lock().unwrap().iter().find(|(c, _)| *c == id) {
            return Some(at.saturating_duration_since(sent));
        }
        thread::sleep(Duration::from_millis(5));
    }
    None
}

/// A COMMAND_LONG `command` to the vehicle, confirmation 0.
fn command(sender: &mut Sender, command: MavCmd) -> Vec<u8> {
    sender
        .frame(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 1,
            target_component: 1,
            command,
            ..Default::default()
        }))
        .as_bytes()
        .to_vec()
}

/// About `len` bytes of whole frames: `make` called for each.
fn frames(len: usize, mut make: impl FnMut() -> Vec<u8>) -> Vec<u8> {
    let mut out = Vec::with_capacity(len + 300);
    while out.len() < len {
        out.extend(make());
    }
    out
}

/// A vehicle's periodic telemetry from `sender`, in turn: attitude, position, heartbeat.
fn telemetry(sender: &mut Sender, k: usize) -> Vec<u8> {
    let m = match k % 3 {
        0 => MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: k as u32,
            roll: 0.1,
            ..Default::default()
        }),
        1 => MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: k as u32,
            lat: 473_977_418,
            lon: 85_455_939,
            ..Default::default()
        }),
        _ => MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            ..Default::default()
        }),
    };
    sender.frame(&m).as_bytes().to_vec()
}

/// Pseudo-random bytes (xorshift), a fifth of them MAVLink start bytes so the readers keep
/// finding frame candidates that turn out to be garbage.
fn garbage(len: usize, seed: &mut u64) -> Vec<u8> {
    (0..len)
        .map(|_| {
            *seed ^= *seed << 13;
            *seed ^= *seed >> 7;
            *seed ^= *seed << 17;
            match *seed % 5 {
                0 => 0xFD,
                _ => (*seed >> 24) as u8,
            }
        })
        .collect()
}

const PUSHERS: usize = 3;
const STALLED: usize = 3;
const MAX_CLIENTS: usize = 8;

/// TCP ground clients flood the router for 5 s while the vehicle streams telemetry to them:
/// three push 64 KB of frames per write as fast as their sockets take them (and never read),
/// three connect and never read (each client's queue is bounded, so what they do not take is
/// dropped, not kept), and one more opens and closes three connections at a time as fast as
/// it can, with the legitimate pilot's one past the limit of 8: peak RSS <= 8 MB, and the
/// pilot's commands reach the radio within 1 s during the flood and right after it.
#[test]
fn tcp_flood_keeps_router_memory_bounded_and_commands_flowing() {
    let dir = common::temp_dir("flood-tcp");
    let (radio, radio_slave) = TTYPort::pair().unwrap();
    let mut radio_w = radio.try_clone_native().unwrap();
    radio_w.set_timeout(Duration::from_secs(1)).unwrap();
    let mut radio_r = radio.try_clone_native().unwrap();
    radio_r.set_timeout(Duration::from_millis(100)).unwrap();
    let udp_sink = UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = common::free_port();
    let tcp_addr = format!("127.0.0.1:{port}");
    let log = dir.join("router.log");
    let mut router = Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
        .arg("--unsigned")
        .arg("--radio")
        .arg(radio_slave.name().unwrap())
        .args(["--udp", &udp_sink.local_addr().unwrap().to_string()])
        .args(["--udp-bind", "127.0.0.1:0"])
        .args(["--tcp-listen", &tcp_addr])
        .args(["--tcp-max-clients", &MAX_CLIENTS.to_string()])
        .args(["--status-interval", "1"])
        .env("RUST_LOG", "info")
        .stderr(Stdio::from(std::fs::File::create(&log).unwrap()))
        .spawn()
        .unwrap();
    let pid = router.id();
    let done = Arc::new(AtomicBool::new(false));
    let (seen, watcher) = watch_commands(radio_r, done.clone());

    // The pilot connects first and reads everything it is sent.
    let deadline = Instant::now() + Duration::from_secs(10);
    let pilot = loop {
        match TcpStream::connect(&tcp_addr) {
            Ok(s) => break s,
            Err(_) if Instant::now() < deadline => thread::sleep(Duration::from_millis(50)),
            Err(e) => panic!("router does not listen on TCP {port}: {e}"),
        }
    };
    pilot
        .set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let mut pilot_w = pilot.try_clone().unwrap();
    let s = done.clone();
    let mut pilot_r = pilot;
    let pilot_reader = thread::spawn(move || {
        let mut buf = [0u8; 8192];
        let mut total = 0u64;
        while !s.load(Ordering::Relaxed) {
            if let Ok(n) = pilot_r.read(&mut buf) {
                total += n as u64;
            }
        }
        total
    });
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    // The link is up once a command of the pilot's reaches the radio.
    let probe_sent = Instant::now();
    pilot_w
        .write_all(&command(&mut ground, MavCmd::MAV_CMD_REQUEST_MESSAGE))
        .unwrap();
    let up = latency(
        &seen,
        MavCmd::MAV_CMD_REQUEST_MESSAGE,
        probe_sent,
        Duration::from_secs(10),
    );
    thread::sleep(Duration::from_millis(200));
    let rss_before = rss_kb(pid, "VmRSS:").unwrap_or(0);

    // The vehicle streams telemetry for everyone, stalled clients included.
    let flooding = Arc::new(AtomicBool::new(true));
    let f = flooding.clone();
    let vehicle = thread::spawn(move || {
        let mut sender = Sender::new(1, 1, MavlinkVersion::V2);
        let mut k = 0;
        let mut sent = 0u64;
        while f.load(Ordering::Relaxed) {
            let burst = frames(4096, || {
                k += 1;
                telemetry(&mut sender, k)
            });
            if radio_w.write_all(&burst).is_ok() {
                sent += burst.len() as u64;
            }
            thread::sleep(Duration::from_millis(2));
        }
        sent
    });
    let start = Instant::now();
    let mut flooders = Vec::new();
    for p in 0..PUSHERS {
        let (f, addr) = (flooding.clone(), tcp_addr.clone());
        flooders.push(thread::spawn(move || {
            let mut s = TcpStream::connect(&addr).unwrap();
            s.set_write_timeout(Some(Duration::from_millis(500)))
                .unwrap();
            let mut sender = Sender::new(255, 190 + p as u8, MavlinkVersion::V2);
            let mut k = 0;
            let chunk = frames(64 * 1024, || {
                k += 1;
                telemetry(&mut sender, k)
            });
            let mut sent = 0u64;
            while f.load(Ordering::Relaxed) && start.elapsed() < FLOOD {
                if s.write_all(&chunk).is_ok() {
                    sent += chunk.len() as u64;
                }
            }
            sent
        }));
    }
    let stalled: Vec<TcpStream> = (0..STALLED)
        .map(|_| TcpStream::connect(&tcp_addr).unwrap())
        .collect();
    let (f, addr) = (flooding.clone(), tcp_addr.clone());
    let churner = thread::spawn(move || {
        let mut connects = 0u64;
        while f.load(Ordering::Relaxed) && start.elapsed() < FLOOD {
            // One more than the slots left: the last is refused.
            let batch: Vec<TcpStream> = (0..MAX_CLIENTS - PUSHERS - STALLED)
                .filter_map(|_| TcpStream::connect(&addr).ok())
                .collect();
            connects += batch.len() as u64;
            drop(batch);
        }
        connects
    });

    // Midway, the pilot arms.
    thread::sleep(FLOOD / 2);
    let during_sent = Instant::now();
    pilot_w
        .write_all(&command(&mut ground, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM))
        .unwrap();
    let mut peak_kb = peak_rss_while(&mut router, || start.elapsed() < FLOOD);
    let during = latency(
        &seen,
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        during_sent,
        Duration::from_secs(5),
    );
    flooding.store(false, Ordering::Relaxed);
    let pushed: u64 = flooders.into_iter().map(|t| t.join().unwrap()).sum();
    let connects = churner.join().unwrap();
    let streamed = vehicle.join().unwrap();
    peak_kb = peak_kb.max(rss_kb(pid, "VmHWM:").unwrap_or(0));

    // Right after it, the pilot sets a mode.
    let after_sent = Instant::now();
    pilot_w
        .write_all(&command(&mut ground, MavCmd::MAV_CMD_DO_SET_MODE))
        .unwrap();
    let after = latency(
        &seen,
        MavCmd::MAV_CMD_DO_SET_MODE,
        after_sent,
        Duration::from_secs(5),
    );
    thread::sleep(Duration::from_millis(1200));
    peak_kb = peak_kb.max(rss_kb(pid, "VmHWM:").unwrap_or(0));
    let (exited_ok, log_text, status) = stop(router, &log);
    drop(stalled);
    done.store(true, Ordering::Relaxed);
    let pilot_got = pilot_reader.join().unwrap();
    watcher.join().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!(
        "TCP flood: {PUSHERS} clients pushed {pushed} B, {STALLED} never read, {connects} \
         connects past the limit of {MAX_CLIENTS}, the vehicle streamed {streamed} B (the \
         pilot read {pilot_got} B); router RSS {rss_before} kB before, peak {peak_kb} kB \
         (limit {RSS_LIMIT_KB} kB); pilot's command during the flood {during:?}, after it \
         {after:?} (limit 1 s)\n{status}"
    );
    assert!(
        up.is_some(),
        "the pilot's probe never reached the radio\n{log_text}"
    );
    assert!(pushed > 1 << 20, "the flood did not happen: {pushed} B");
    // The radio is read throughout the flood: ten times the serial read-ahead (640 KB, 128 KB/s,
    // a fraction of what a pty carries). While the flood's frames counted against the serial
    // reader's room it was read once per wait: 16 KB to 3 MB in the same 5 s.
    assert!(
        streamed >= 10 * mavlora::io::READ_AHEAD as u64,
        "the vehicle's telemetry stalled behind the ground flood: {streamed} B in 5 s\n{status}"
    );
    assert!(
        connects > 100,
        "the connection churn did not happen: {connects}"
    );
    assert!(
        peak_kb <= RSS_LIMIT_KB,
        "router peak RSS {peak_kb} kB > {RSS_LIMIT_KB} kB\n{status}"
    );
    for (when, t) in [("during", during), ("after", after)] {
        assert!(
            t.is_some_and(|t| t < Duration::from_secs(1)),
            "pilot's command {when} the TCP flood reached the radio after {t:?} (limit 1 s)\n{status}"
        );
    }
    assert!(status.contains("tcp_refused="), "{status}");
    assert!(!status.contains("tcp_refused=0 "), "none refused: {status}");
    assert!(exited_ok, "{log_text}");
}

/// Copies `from` to `to` until `done`; with `inject` set, each read is followed by the next
/// of `chunks` (whole: injected bytes never split a frame that was copied).
fn relay(
    mut from: TTYPort,
    mut to: TTYPort,
    done: Arc<AtomicBool>,
    inject: Arc<AtomicBool>,
    mut chunks: impl FnMut() -> Vec<u8> + Send + 'static,
) -> thread::JoinHandle<u64> {
    thread::spawn(move || {
        let mut buf = [0u8; 4096];
        let mut injected = 0u64;
        while !done.load(Ordering::Relaxed) {
            if let Ok(n) = from.read(&mut buf)
                && n > 0
            {
                let _ = to.write_all(&buf[..n]);
            }
            if inject.load(Ordering::Relaxed) {
                let chunk = chunks();
                if to.write_all(&chunk).is_ok() {
                    injected += chunk.len() as u64;
                }
            }
        }
        injected
    })
}

/// The bridge between a flooded flight controller and a flooded radio for 5 s, signed, with
/// the real router at the other end of the radio. On the flight controller's port: 64 KB of
/// valid telemetry, then 16 KB of garbage, in turn, as fast as the pty takes them (far above
/// the 921600-baud line rate). On the radio: after each read of the router's bytes, garbage,
/// unsigned frames under 60,000 made-up senders and in the router's name, and forged
/// 10-byte headers announcing 255-byte payloads, in turn, as fast as the pty takes them.
/// Peak RSS <= 8 MB, and the ground's commands, signed by the router, reach the flight
/// controller within 1 s during the flood and right after it.
#[test]
fn floods_on_both_sides_keep_bridge_memory_bounded_and_commands_flowing() {
    let dir = common::temp_dir("flood-bridge");
    let key = common::radio_key(&dir, 0x5a);
    let (fc, fc_slave) = TTYPort::pair().unwrap();
    let (air_b, bridge_radio) = TTYPort::pair().unwrap();
    let (air_r, router_radio) = TTYPort::pair().unwrap();
    let done = Arc::new(AtomicBool::new(false));
    let flooding = Arc::new(AtomicBool::new(false));
    let never = Arc::new(AtomicBool::new(false));
    let port = |p: &TTYPort, timeout_ms| {
        let mut c = p.try_clone_native().unwrap();
        c.set_timeout(Duration::from_millis(timeout_ms)).unwrap();
        c
    };
    let uplink = {
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let (mut k, mut n) = (0usize, 0u32);
        let mut in_routers_name = Sender::new(255, 190, MavlinkVersion::V2);
        relay(
            port(&air_r, 1),
            port(&air_b, 1000),
            done.clone(),
            flooding.clone(),
            move || {
                k += 1;
                match k % 4 {
                    0 => garbage(2048, &mut seed),
                    1 => frames(2048, || {
                        n = (n + 1) % 60_000;
                        let [a, b, c, _] = n.to_le_bytes();
                        let mut s = Sender::new(a, b, MavlinkVersion::V2);
                        s.set_next_sequence(c);
                        s.frame(&MavMessage::HEARTBEAT(Default::default()))
                            .as_bytes()
                            .to_vec()
                    }),
                    2 => frames(2048, || {
                        in_routers_name.set_next_sequence((seed >> 8) as u8);
                        seed = seed.rotate_left(7) ^ 0x5555;
                        command(&mut in_routers_name, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM)
                    }),
                    _ => [0xFD, 0xFF, 0, 0, 0, 255, 190, 0x1E, 0, 0].repeat(200),
                }
            },
        )
    };
    let downlink = relay(
        port(&air_b, 20),
        port(&air_r, 1000),
        done.clone(),
        never,
        Vec::new,
    );

    let gcs = UdpSocket::bind("127.0.0.1:0").unwrap();
    let udp_port = common::free_udp_port();
    let router_log = dir.join("router.log");
    let router = common::Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
                .arg("--key")
                .arg(&key)
                .arg("--radio")
                .arg(router_radio.name().unwrap())
                .args(["--udp", &gcs.local_addr().unwrap().to_string()])
                .args(["--udp-bind", &format!("127.0.0.1:{udp_port}")])
                .env("RUST_LOG", "info")
                .current_dir(&dir)
                .stderr(Stdio::from(std::fs::File::create(&router_log).unwrap()))
                .spawn()
                .unwrap(),
        ),
        "router",
    );
    let log = dir.join("bridge.log");
    let mut bridge = Command::new(env!("CARGO_BIN_EXE_mavlora-bridge"))
        .arg("--key")
        .arg(&key)
        .arg("--fc")
        .arg(fc_slave.name().unwrap())
        .arg("--radio")
        .arg(bridge_radio.name().unwrap())
        .args(["--status-interval", "1"])
        .env("RUST_LOG", "info")
        .current_dir(&dir)
        .stderr(Stdio::from(std::fs::File::create(&log).unwrap()))
        .spawn()
        .unwrap();
    let pid = bridge.id();
    let (seen, watcher) = watch_commands(port(&fc, 100), done.clone());

    // The link is up (the two ends answered each other's challenge) once a ground command
    // reaches the flight controller.
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    let to_router = ("127.0.0.1", udp_port);
    let mut fc_w = port(&fc, 1000);
    let mut vehicle = Sender::new(1, 1, MavlinkVersion::V2);
    let probe = command(&mut ground, MavCmd::MAV_CMD_REQUEST_MESSAGE);
    let mut up = None;
    let started = Instant::now();
    while up.is_none() && started.elapsed() < Duration::from_secs(20) {
        let _ = fc_w.write_all(&telemetry(&mut vehicle, 2));
        let _ = gcs.send_to(&probe, to_router);
        up = latency(
            &seen,
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            Instant::now(),
            Duration::from_millis(300),
        );
    }
    let rss_before = rss_kb(pid, "VmRSS:").unwrap_or(0);

    flooding.store(true, Ordering::Relaxed);
    let start = Instant::now();
    let fc_flooder = thread::spawn(move || {
        let mut seed = 0x2545_F491_4F6C_DD1Du64;
        let (mut k, mut sent) = (0, 0u64);
        while start.elapsed() < FLOOD {
            let burst = frames(64 * 1024, || {
                k += 1;
                telemetry(&mut vehicle, k)
            });
            for chunk in [burst, garbage(16 * 1024, &mut seed)] {
                if fc_w.write_all(&chunk).is_ok() {
                    sent += chunk.len() as u64;
                }
            }
        }
        sent
    });
    thread::sleep(FLOOD / 2);
    let during_sent = Instant::now();
    let _ = gcs.send_to(
        &command(&mut ground, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM),
        to_router,
    );
    let mut peak_kb = peak_rss_while(&mut bridge, || start.elapsed() < FLOOD);
    let during = latency(
        &seen,
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        during_sent,
        Duration::from_secs(5),
    );
    let fc_flood = fc_flooder.join().unwrap();
    flooding.store(false, Ordering::Relaxed);
    peak_kb = peak_kb.max(rss_kb(pid, "VmHWM:").unwrap_or(0));

    let after_sent = Instant::now();
    let _ = gcs.send_to(
        &command(&mut ground, MavCmd::MAV_CMD_DO_SET_MODE),
        to_router,
    );
    let after = latency(
        &seen,
        MavCmd::MAV_CMD_DO_SET_MODE,
        after_sent,
        Duration::from_secs(5),
    );
    peak_kb = peak_kb.max(rss_kb(pid, "VmHWM:").unwrap_or(0));
    let (exited_ok, log_text, status) = stop(bridge, &log);
    drop(router);
    done.store(true, Ordering::Relaxed);
    let radio_flood = uplink.join().unwrap();
    downlink.join().unwrap();
    watcher.join().unwrap();
    let router_text = std::fs::read_to_string(&router_log).unwrap_or_default();
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!(
        "bridge floods: {fc_flood} B on the flight controller's port, {radio_flood} B injected \
         on the radio; bridge RSS {rss_before} kB before, peak {peak_kb} kB (limit \
         {RSS_LIMIT_KB} kB); the ground's command during the flood {during:?}, after it \
         {after:?} (limit 1 s)\n{status}"
    );
    assert!(
        up.is_some(),
        "the link never came up\n{log_text}\n{router_text}"
    );
    assert!(
        fc_flood > 1 << 20,
        "the FC flood did not happen: {fc_flood} B"
    );
    assert!(
        radio_flood > 1 << 20,
        "the radio flood did not happen: {radio_flood} B"
    );
    assert!(
        peak_kb <= RSS_LIMIT_KB,
        "bridge peak RSS {peak_kb} kB > {RSS_LIMIT_KB} kB\n{status}"
    );
    for (when, t) in [("during", during), ("after", after)] {
        assert!(
            t.is_some_and(|t| t < Duration::from_secs(1)),
            "the ground's command {when} the floods reached the FC after {t:?} (limit 1 s)\n{status}"
        );
    }
    assert!(!status.contains("rejected_unsigned=0 "), "{status}");
    assert!(exited_ok, "{log_text}");
}
