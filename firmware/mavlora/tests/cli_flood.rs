//! Load on the router: one local sender of 64 KB datagrams, a sweep of 60,000 source
//! addresses and unsigned frames injected on the radio under made-up senders must neither
//! grow the router without bound nor hold up the pilot's commands. Targets: under the
//! datagram flood (the project's), peak RSS < 64 MB and a COMMAND_LONG sent after it reaches
//! the radio within 1 s; under the sweep and the injection (issue 22's), peak RSS <= 8 MB.
//! The floods go to 127.0.0.0/8 only, bounded in count and time; the router is killed early
//! if its RSS passes 256 MB.

use std::io::Read;
use std::net::{TcpListener, UdpSocket};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use mavlink::MavlinkVersion;
use serialport::{SerialPort as _, TTYPort};

use mavlora::dialect::{ATTITUDE_DATA, COMMAND_LONG_DATA, MavCmd, MavMessage};
use mavlora::wire::{FrameReader, Sender};

mod common;

const FLOOD: Duration = Duration::from_secs(5);
const MAX_DATAGRAMS: usize = 1_000_000;
const RSS_LIMIT_KB: u64 = 64 * 1024;
const SWEEP_RSS_LIMIT_KB: u64 = 8 * 1024;
const KILL_KB: u64 = 256 * 1024;

fn rss_kb(pid: u32, key: &str) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// The router's peak RSS while `busy` says the load goes on, sampled every 50 ms; past
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
        peak_kb < RSS_LIMIT_KB,
        "router peak RSS {peak_kb} kB >= {RSS_LIMIT_KB} kB\n{status}"
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
         RSS {rss_before} kB before, peak {peak_kb} kB (limit {SWEEP_RSS_LIMIT_KB} kB); log {} B\n{status}",
        log_text.len()
    );
    assert!(sent > 50_000, "the sweep did not happen: {sent} datagrams");
    assert!(
        peak_kb <= SWEEP_RSS_LIMIT_KB,
        "router peak RSS {peak_kb} kB > {SWEEP_RSS_LIMIT_KB} kB\n{status}"
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
