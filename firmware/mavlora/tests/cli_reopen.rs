//! The router binary reopens its radio port when the device disappears and comes back (a
//! USB radio re-enumerating), here a pty behind a symlink that is removed and re-pointed.

use std::io::Write;
use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mavlink::MavlinkVersion;
use serialport::{SerialPort as _, TTYPort};

use mavlora::dialect::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavType};
mod common;
use common::pty_pair;

use mavlora::wire::{Frame, FrameReader, Sender};

/// Writes heartbeats into `master` until one arrives on `udp` (or 10 s pass).
fn heartbeat_arrives(master: &mut TTYPort, udp: &UdpSocket, sender: &mut Sender) -> bool {
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        ..Default::default()
    });
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut buf = [0u8; 512];
    while Instant::now() < deadline {
        let _ = master.write_all(sender.frame(&hb).as_bytes());
        if let Ok((n, _)) = udp.recv_from(&mut buf)
            && Frame::new_checked(&buf[..n]).is_ok_and(|f| f.message_id() == 0)
        {
            return true;
        }
    }
    false
}

#[test]
fn router_reopens_a_radio_that_disappears_and_returns() {
    let dir = std::env::temp_dir().join(format!("mavlora-reopen-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("radio");
    let _ = std::fs::remove_file(&link);
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    udp.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let log = std::fs::File::create(dir.join("router.log")).unwrap();
    let mut router = Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
        .arg("--unsigned")
        .arg("--radio")
        .arg(&link)
        .args(["--udp", &udp.local_addr().unwrap().to_string()])
        .args(["--udp-bind", "127.0.0.1:0"])
        .env("RUST_LOG", "info")
        .stderr(Stdio::from(log))
        .spawn()
        .unwrap();
    let mut sender = Sender::new(1, 1, MavlinkVersion::V2);

    // The device is absent at start: the router retries with backoff.
    std::thread::sleep(Duration::from_millis(400));
    let (mut master, slave) = pty_pair();
    std::os::unix::fs::symlink(slave.name().unwrap(), &link).unwrap();
    let first = heartbeat_arrives(&mut master, &udp, &mut sender);

    // It vanishes (both ends closed: the router reads EIO) and comes back as another pty.
    drop((master, slave));
    std::fs::remove_file(&link).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    // forget datagrams of the first device
    let mut buf = [0u8; 512];
    while udp.recv_from(&mut buf).is_ok() {}
    let (mut master, slave) = pty_pair();
    std::os::unix::fs::symlink(slave.name().unwrap(), &link).unwrap();
    let second = heartbeat_arrives(&mut master, &udp, &mut sender);

    let _ = Command::new("kill")
        .args(["-TERM", &router.id().to_string()])
        .status();
    let status = router.wait().unwrap();
    let log = std::fs::read_to_string(dir.join("router.log")).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(first, "no heartbeat through the first device:\n{log}");
    assert!(second, "no heartbeat after the device returned:\n{log}");
    assert!(log.contains("cannot open serial port"), "{log}");
    assert_eq!(log.matches("serial port open").count(), 2, "{log}");
    assert!(status.success(), "exit status {status:?}");
}

#[test]
fn config_file_with_an_unknown_key_is_an_error_naming_the_file() {
    let dir = std::env::temp_dir().join(format!("mavlora-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("router.toml");
    std::fs::write(&config, "radio = \"/dev/null\"\nradoi_baud = 57600\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
        .arg("--unsigned")
        .arg("--config")
        .arg(&config)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let _ = std::fs::remove_dir_all(&dir);
    // a bad config file is bad usage, like a bad flag: exit 2, naming file:line and key
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("router.toml:2") && stderr.contains("radoi_baud"),
        "{stderr}"
    );
    // a bad flag is a usage error
    let usage = Command::new(env!("CARGO_BIN_EXE_mavlora-bridge"))
        .arg("--unsigned")
        .arg("--no-such-flag")
        .output()
        .unwrap();
    assert_eq!(usage.status.code(), Some(2));
}

/// Regression: after the radio pty vanished, an unrelated new pty got the same `/dev/pts/N`
/// and the bridge wrote MAVLink into it. A bare pty node is never reopened once it went away
/// (its number belongs to whoever allocated it next); the refusal is logged and counted.
#[test]
fn router_never_attaches_to_an_unrelated_pty_that_reuses_the_radios_number() {
    use std::io::Read;
    let dir = std::env::temp_dir().join(format!("mavlora-reuse-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    udp.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let (mut master, slave) = pty_pair();
    let node = slave.name().unwrap();
    let log = std::fs::File::create(dir.join("router.log")).unwrap();
    let mut router = Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
        .arg("--unsigned")
        .args(["--radio", &node])
        .args(["--udp", &udp.local_addr().unwrap().to_string()])
        .args(["--udp-bind", "127.0.0.1:0", "--status-interval", "0.5"])
        .env("RUST_LOG", "info")
        .stderr(Stdio::from(log))
        .spawn()
        .unwrap();
    let mut sender = Sender::new(1, 1, MavlinkVersion::V2);
    let first = heartbeat_arrives(&mut master, &udp, &mut sender);

    // The radio's pty goes away (its number is free once the router has closed it too);
    // new ptys are made until one gets the same number (the kernel hands out the lowest
    // free one; other programs on the host may take some first). Up to 5 s: on a loaded
    // machine the router may notice the hang-up and close its side late (64 tries 20 ms
    // apart were not always enough with other tests beside this one).
    drop((master, slave));
    std::thread::sleep(Duration::from_millis(500));
    let mut held = Vec::new();
    let looking = Instant::now();
    let stranger = loop {
        let (m, s) = pty_pair();
        if s.name().as_deref() == Some(node.as_str()) {
            break Some((m, s));
        }
        held.push((m, s));
        if looking.elapsed() > Duration::from_secs(5) {
            break None;
        }
        std::thread::sleep(Duration::from_millis(25));
    };
    let mut buf = [0u8; 512];
    while udp.recv_from(&mut buf).is_ok() {}
    // Invariant: for 3 s, nothing the stranger writes reaches the ground and the router
    // writes nothing into the stranger's pty. The stranger speaks as system 77, so its
    // frames are told apart from what the router itself tells the ground (its link
    // reports: RADIO_STATUS and the like).
    const STRANGER: u8 = 77;
    let mut stranger_sender = Sender::new(STRANGER, 1, MavlinkVersion::V2);
    let (mut to_ground, mut into_stranger) = (0, 0);
    let reused = stranger.is_some();
    if let Some((mut m, _s)) = stranger {
        m.set_timeout(Duration::from_millis(100)).unwrap();
        let deadline = Instant::now() + Duration::from_secs(3);
        while Instant::now() < deadline {
            let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
            let _ = m.write_all(stranger_sender.frame(&hb).as_bytes());
            if let Ok(n) = m.read(&mut buf) {
                into_stranger += n;
            }
            if let Ok((n, _)) = udp.recv_from(&mut buf) {
                let mut reader = FrameReader::new();
                reader.push(&buf[..n]);
                while let Some(received) = reader.next_frame() {
                    if received.frame.system_id() == STRANGER {
                        to_ground += 1;
                    }
                }
            }
        }
    }
    let held_count = held.len();
    drop(held);
    let _ = Command::new("kill")
        .args(["-TERM", &router.id().to_string()])
        .status();
    let status = router.wait().unwrap();
    let log = std::fs::read_to_string(dir.join("router.log")).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(first, "no heartbeat through the radio:\n{log}");
    assert!(
        reused,
        "the kernel never reused {node} in 5 s ({} new ptys)",
        held_count
    );
    assert_eq!(
        into_stranger, 0,
        "router wrote into an unrelated pty:\n{log}"
    );
    assert_eq!(
        to_ground, 0,
        "an unrelated pty's frames reached the ground:\n{log}"
    );
    assert!(log.contains("not reopened"), "{log}");
    // Refused at each retry (backoff up to 5 s), counted every time.
    let refused = log
        .rsplit("radio_refused_opens=")
        .next()
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse::<u64>().ok());
    assert!(refused.is_some_and(|n| n >= 1), "{refused:?}\n{log}");
    assert_eq!(log.matches("serial port open").count(), 1, "{log}");
    assert!(status.success(), "exit status {status:?}");
}

/// A radio named by a USB serial number that is not plugged in: the router runs, waits for
/// it and says which serial number it looks for and what is there instead.
#[test]
fn router_waits_for_a_radio_named_by_an_absent_usb_serial_number() {
    let dir = std::env::temp_dir().join(format!("mavlora-usbserial-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = std::fs::File::create(dir.join("router.log")).unwrap();
    let mut router = Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
        .arg("--unsigned")
        .args(["--radio", "usb-serial:NO-SUCH-RADIO-7"])
        .args(["--udp-bind", "127.0.0.1:0"])
        .env("RUST_LOG", "info")
        .stderr(Stdio::from(log))
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(800));
    let still_running = router.try_wait().unwrap().is_none();
    let _ = Command::new("kill")
        .args(["-TERM", &router.id().to_string()])
        .status();
    let status = router.wait().unwrap();
    let log = std::fs::read_to_string(dir.join("router.log")).unwrap();
    assert!(still_running, "{log}");
    assert!(
        log.contains("no USB serial port with serial number `NO-SUCH-RADIO-7`"),
        "{log}"
    );
    assert!(status.success(), "{status:?}");
    // An empty serial number is bad usage, named by the port it was given for.
    let out = Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
        .args([
            "--unsigned",
            "--radio",
            "usb-serial:",
            "--udp-bind",
            "127.0.0.1:0",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let _ = std::fs::remove_dir_all(&dir);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("radio port") && stderr.contains("usb-serial:"),
        "{stderr}"
    );
}
