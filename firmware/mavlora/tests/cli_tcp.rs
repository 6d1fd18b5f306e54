//! The router's TCP endpoint with the real binary: a ground station on TCP gets the vehicle's
//! frames from the radio pty, and its own frames reach the radio even when written a few
//! bytes at a time (TCP keeps no message boundaries).

use std::io::{Read, Write};
use std::net::{TcpStream, UdpSocket};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use mavlink::MavlinkVersion;
use serialport::{SerialPort as _, TTYPort};

use mavlora::dialect::{
    COMMAND_LONG_DATA, HEARTBEAT_DATA, MavAutopilot, MavCmd, MavMessage, MavType,
};
use mavlora::wire::{FrameReader, Sender};

mod common;
use common::free_port;

/// Reads frames from `read` until one with `id` arrives or `timeout` passes.
fn wait_for(read: &mut dyn Read, id: u32, timeout: Duration, mut poke: impl FnMut()) -> bool {
    let deadline = Instant::now() + timeout;
    let mut reader = FrameReader::new();
    let mut buf = [0u8; 1024];
    while Instant::now() < deadline {
        poke();
        if let Ok(n) = read.read(&mut buf)
            && n > 0
        {
            reader.push(&buf[..n]);
            while let Some(rx) = reader.next_frame() {
                if rx.frame.message_id() == id {
                    return true;
                }
            }
        }
    }
    false
}

/// A router on a fresh radio pty listening for TCP on a free port (UDP to a socket nobody
/// reads: TCP alone must carry the conversation), logging into `dir/router.log`, with `args`.
/// Returns it with the radio's master end and the TCP port; the pty's slave end and the UDP
/// sink stay open as long as the returned value lives.
fn tcp_router(dir: &Path, args: &[&str]) -> (Child, TTYPort, u16, (TTYPort, UdpSocket)) {
    std::fs::create_dir_all(dir).unwrap();
    let (mut radio, slave) = TTYPort::pair().unwrap();
    radio.set_timeout(Duration::from_millis(100)).unwrap();
    let port = free_port();
    let udp_sink = UdpSocket::bind("127.0.0.1:0").unwrap();
    let log = std::fs::File::create(dir.join("router.log")).unwrap();
    let router = Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
        .arg("--unsigned")
        .arg("--radio")
        .arg(slave.name().unwrap())
        .args(["--udp", &udp_sink.local_addr().unwrap().to_string()])
        .args(["--udp-bind", "127.0.0.1:0"])
        .args(["--tcp-listen", &format!("127.0.0.1:{port}")])
        .args(args)
        .env("RUST_LOG", "info")
        .stderr(Stdio::from(log))
        .spawn()
        .unwrap();
    (router, radio, port, (slave, udp_sink))
}

#[test]
fn tcp_ground_station_talks_to_the_vehicle_through_the_router() {
    let dir = std::env::temp_dir().join(format!("mavlora-tcp-{}", std::process::id()));
    let (mut router, mut radio, port, _held) = tcp_router(&dir, &[]);

    let deadline = Instant::now() + Duration::from_secs(10);
    let mut gcs = loop {
        match TcpStream::connect(("127.0.0.1", port)) {
            Ok(s) => break s,
            Err(_) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(50)),
            Err(e) => panic!("router does not listen on TCP {port}: {e}"),
        }
    };
    gcs.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();

    // vehicle → radio → router → TCP
    let mut vehicle = Sender::new(1, 1, MavlinkVersion::V2);
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        ..Default::default()
    });
    let mut radio_w = radio.try_clone_native().unwrap();
    let down = wait_for(&mut gcs, 0, Duration::from_secs(10), || {
        let _ = radio_w.write_all(vehicle.frame(&hb).as_bytes());
    });

    // TCP → router → radio, one command written 3 bytes at a time
    let mut ground = Sender::new(255, 190, MavlinkVersion::V2);
    let cmd = ground.frame(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_DO_SET_MODE,
        ..Default::default()
    }));
    for chunk in cmd.as_bytes().chunks(3) {
        gcs.write_all(chunk).unwrap();
        gcs.flush().unwrap();
        std::thread::sleep(Duration::from_millis(5));
    }
    let up = wait_for(&mut radio, 76, Duration::from_secs(10), || {});

    let _ = Command::new("kill")
        .args(["-TERM", &router.id().to_string()])
        .status();
    let status = router.wait().unwrap();
    let log = std::fs::read_to_string(dir.join("router.log")).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(down, "no vehicle heartbeat on TCP:\n{log}");
    assert!(up, "COMMAND_LONG from TCP never reached the radio:\n{log}");
    assert!(log.contains("TCP ground station connected"), "{log}");
    assert!(status.success(), "exit status {status:?}\n{log}");
}

/// Regression: a TCP client from an address the ground policy does not allow was served the
/// vehicle's telemetry (and eight of them took every client slot from the allowed pilot). It
/// is closed at once, gets no frame, takes no slot, and is counted.
#[test]
fn a_tcp_client_from_an_address_not_allowed_gets_nothing_and_takes_no_slot() {
    let dir = std::env::temp_dir().join(format!("mavlora-tcp-refused-{}", std::process::id()));
    // Only 127.0.0.2 may talk to the vehicle; the test connects from 127.0.0.1.
    let status_json = dir.join("router.status.jsonl");
    let (mut router, radio, port, _held) = tcp_router(
        &dir,
        &[
            "--allow",
            "127.0.0.2",
            "--tcp-max-clients",
            "1",
            "--status-json",
            status_json.to_str().unwrap(),
        ],
    );
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut clients = Vec::new();
    while clients.len() < 3 {
        match TcpStream::connect(("127.0.0.1", port)) {
            Ok(s) => {
                s.set_read_timeout(Some(Duration::from_millis(100)))
                    .unwrap();
                clients.push(s);
            }
            Err(_) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(50)),
            Err(e) => panic!("router does not listen on TCP {port}: {e}"),
        }
    }
    let mut vehicle = Sender::new(1, 1, MavlinkVersion::V2);
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
    let mut radio_w = radio.try_clone_native().unwrap();
    let mut got = vec![0usize; clients.len()];
    let until = Instant::now() + Duration::from_secs(2);
    while Instant::now() < until {
        let _ = radio_w.write_all(vehicle.frame(&hb).as_bytes());
        for (c, n) in clients.iter_mut().zip(got.iter_mut()) {
            let mut buf = [0u8; 512];
            if let Ok(k) = c.read(&mut buf) {
                *n += k;
            }
        }
    }
    let _ = Command::new("kill")
        .args(["-TERM", &router.id().to_string()])
        .status();
    let status = router.wait().unwrap();
    let log = std::fs::read_to_string(dir.join("router.log")).unwrap();
    let status_file = std::fs::read_to_string(dir.join("router.status.jsonl")).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(status.success(), "exit status {status:?}\n{log}");
    assert_eq!(got, [0, 0, 0], "refused clients got bytes:\n{log}");
    let stop: serde_json::Value =
        serde_json::from_str(status_file.lines().last().unwrap()).unwrap();
    assert_eq!(stop["kind"], "stop");
    assert_eq!(stop["counters"]["tcp_refused"], 3, "{stop}");
    assert_eq!(stop["gauges"]["tcp_clients"], 0, "{stop}");
    assert!(log.contains("address not allowed"), "{log}");
}
