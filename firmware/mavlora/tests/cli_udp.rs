//! The router's UDP side with the real binary: frames that come off the radio together leave
//! packed into datagrams of at most `MAX_DATAGRAM` bytes (one `sendto` for many frames), and
//! with `--udp-one-frame-per-datagram` one frame each. Either way every frame arrives exactly
//! once, whole and in order. (pymavlink and MAVProxy reading packed datagrams: the `e2e_*`
//! tests.)

use std::io::Write;
use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mavlink::MavlinkVersion;
use serialport::SerialPort as _;

use mavlora::dialect::{ATTITUDE_DATA, MavMessage};
use mavlora::io::MAX_DATAGRAM;
use mavlora::wire::{FrameReader, Sender};

mod common;
use common::{Guard, pty_pair};

/// Frames written into the radio pty in one write.
const FRAMES: u32 = 300;
/// As many, one datagram each: more would overflow the test's own socket buffer (each
/// datagram costs the kernel about 1 KB of it, whatever its size), loss no router can help.
const FRAMES_UNPACKED: u32 = 100;

/// The vehicle's ATTITUDE frames (by `time_boot_ms`) in the order they arrived, and the
/// datagrams that carried them (each as a list of its frames' lengths).
fn run(frames: u32, extra: &[&str]) -> (Vec<u32>, Vec<Vec<usize>>) {
    let (mut radio, slave) = pty_pair();
    let ground = UdpSocket::bind("127.0.0.1:0").unwrap();
    ground
        .set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let mut router = Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
                .args(["--unsigned", "--radio", &slave.name().unwrap()])
                .args(["--udp", &ground.local_addr().unwrap().to_string()])
                .args(["--udp-bind", "127.0.0.1:0"])
                .args(extra)
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        ),
        "mavlora-router",
    );
    let mut sender = Sender::new(1, 1, MavlinkVersion::V2);
    let attitude = |t: u32| {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: t,
            ..Default::default()
        })
    };
    // The router is up when a first frame (t = 0) comes through.
    let mut buf = [0u8; 65_536];
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut up = false;
    while !up && Instant::now() < deadline {
        radio
            .write_all(sender.frame(&attitude(0)).as_bytes())
            .unwrap();
        up = ground.recv(&mut buf).is_ok();
    }
    assert!(up, "the router forwarded nothing in 10 s");
    while ground.recv(&mut buf).is_ok() {}

    let burst: Vec<u8> = (1..=frames)
        .flat_map(|t| sender.frame(&attitude(t)).as_bytes().to_vec())
        .collect();
    radio.write_all(&burst).unwrap();
    let (mut times, mut datagrams) = (Vec::new(), Vec::new());
    let deadline = Instant::now() + Duration::from_secs(10);
    while times.last() != Some(&frames) && Instant::now() < deadline {
        let Ok(n) = ground.recv(&mut buf) else {
            continue;
        };
        let mut reader = FrameReader::new();
        reader.push(&buf[..n]);
        let mut lengths = Vec::new();
        while let Some(rx) = reader.next_frame() {
            lengths.push(rx.frame.as_bytes().len());
            if let Ok(MavMessage::ATTITUDE(a)) = rx.frame.decode::<MavMessage>() {
                times.push(a.time_boot_ms);
            }
        }
        // Nothing but whole frames in a datagram.
        assert_eq!(
            lengths.iter().sum::<usize>(),
            n,
            "a datagram held a partial frame"
        );
        datagrams.push(lengths);
    }
    assert!(router.terminate(), "the router did not stop cleanly");
    (times, datagrams)
}

#[test]
fn frames_read_together_share_datagrams_and_all_arrive_once_in_order() {
    let (times, datagrams) = run(FRAMES, &[]);
    assert_eq!(times, (1..=FRAMES).collect::<Vec<_>>());
    let sizes: Vec<usize> = datagrams.iter().map(|d| d.iter().sum()).collect();
    assert!(sizes.iter().all(|&s| s <= MAX_DATAGRAM), "{sizes:?}");
    // 300 ATTITUDE frames (40 bytes) in one pty write: packed, not one datagram each.
    assert!(
        datagrams.len() < FRAMES as usize / 4,
        "{} datagrams for {FRAMES} frames",
        datagrams.len()
    );
}

#[test]
fn one_frame_per_datagram_on_request() {
    let (times, datagrams) = run(FRAMES_UNPACKED, &["--udp-one-frame-per-datagram"]);
    assert_eq!(times, (1..=FRAMES_UNPACKED).collect::<Vec<_>>());
    assert!(datagrams.iter().all(|d| d.len() == 1), "{datagrams:?}");
}

/// Several ground stations on one host (issue 22 item 16): every accepted sender gets every
/// frame, each in the MAVLink version it speaks. A station speaking MAVLink 1 gets MAVLink 1
/// (and not CURRENT_MODE, id 436, which MAVLink 1 cannot carry), the other keeps MAVLink 2
/// and gets it. Before, only the last sender got data, and one MAVLink 1 heartbeat turned
/// every station's output into MAVLink 1.
#[test]
fn each_ground_station_gets_every_frame_in_its_own_mavlink_version() {
    use mavlora::dialect::{CURRENT_MODE_DATA, HEARTBEAT_DATA, MavType};
    let (mut radio, slave) = pty_pair();
    let port = common::free_udp_port();
    let router_addr = format!("127.0.0.1:{port}");
    let mut router = Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
                .args(["--unsigned", "--radio", &slave.name().unwrap()])
                .args(["--udp-bind", &router_addr])
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        ),
        "mavlora-router",
    );
    let stations: Vec<(UdpSocket, Sender)> = [MavlinkVersion::V2, MavlinkVersion::V1]
        .into_iter()
        .map(|version| {
            let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
            socket
                .set_read_timeout(Some(Duration::from_millis(20)))
                .unwrap();
            (socket, Sender::new(255, 190, version))
        })
        .collect();
    let gcs_heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_GCS,
        ..Default::default()
    });
    let mut vehicle = Sender::new(1, 1, MavlinkVersion::V2);
    let vehicle_heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
    let current_mode = MavMessage::CURRENT_MODE(CURRENT_MODE_DATA::default());
    // (heartbeats as MAVLink 1, as MAVLink 2, CURRENT_MODE: id 436) seen by each station
    let mut seen = [(0, 0, 0); 2];
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut buf = [0u8; 65_536];
    let enough =
        |seen: &[(u32, u32, u32); 2]| seen[0].1 >= 10 && seen[0].2 >= 10 && seen[1].0 >= 10;
    let mut stations = stations;
    // The stations speak once a second, A then B: B is always the last sender.
    let mut next_hello = Instant::now();
    while !enough(&seen) && Instant::now() < deadline {
        if Instant::now() >= next_hello {
            for (socket, sender) in &mut stations {
                socket
                    .send_to(sender.frame(&gcs_heartbeat).as_bytes(), &router_addr)
                    .unwrap();
            }
            next_hello += Duration::from_secs(1);
        }
        radio
            .write_all(vehicle.frame(&vehicle_heartbeat).as_bytes())
            .unwrap();
        radio
            .write_all(vehicle.frame(&current_mode).as_bytes())
            .unwrap();
        for (k, (socket, _)) in stations.iter().enumerate() {
            while let Ok(n) = socket.recv(&mut buf) {
                let mut reader = FrameReader::new();
                reader.push(&buf[..n]);
                while let Some(rx) = reader.next_frame() {
                    match (rx.frame.message_id(), rx.frame.version()) {
                        (0, MavlinkVersion::V1) => seen[k].0 += 1,
                        (0, MavlinkVersion::V2) => seen[k].1 += 1,
                        (436, _) => seen[k].2 += 1,
                        _ => {}
                    }
                }
            }
        }
    }
    assert!(router.terminate(), "the router did not stop cleanly");
    assert!(
        enough(&seen),
        "(v1 heartbeats, v2 heartbeats, id 436): {seen:?}"
    );
    assert_eq!((seen[0].0, seen[1].1, seen[1].2), (0, 0, 0), "{seen:?}");
}
