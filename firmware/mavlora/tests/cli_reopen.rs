//! The router binary reopens its radio port when the device disappears and comes back (a
//! USB radio re-enumerating), here a pty behind a symlink that is removed and re-pointed.

use std::io::Write;
use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mavlink::MavlinkVersion;
use serialport::{SerialPort as _, TTYPort};

use mavlora::dialect::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavType};
use mavlora::wire::{Frame, Sender};

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
    let (mut master, slave) = TTYPort::pair().unwrap();
    std::os::unix::fs::symlink(slave.name().unwrap(), &link).unwrap();
    let first = heartbeat_arrives(&mut master, &udp, &mut sender);

    // It vanishes (both ends closed: the router reads EIO) and comes back as another pty.
    drop((master, slave));
    std::fs::remove_file(&link).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    // forget datagrams of the first device
    let mut buf = [0u8; 512];
    while udp.recv_from(&mut buf).is_ok() {}
    let (mut master, slave) = TTYPort::pair().unwrap();
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
