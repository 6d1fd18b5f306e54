//! The real binaries refuse to run the radio leg unsigned unless told, and refuse key files
//! that others may read or that are not 64 hex characters, naming the file; what a signer
//! accepted stays refused across a restart (the radio's and the router's ground key's), and a
//! state file stamped far ahead of the clock is refused at start.

use serialport::SerialPort as _;
use std::os::unix::fs::PermissionsExt as _;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

const ROUTER: &str = env!("CARGO_BIN_EXE_mavlora-router");
const BRIDGE: &str = env!("CARGO_BIN_EXE_mavlora-bridge");

mod common;
use common::{run, temp_dir};

use mavlora::dialect::{
    COMMAND_LONG_DATA, HEARTBEAT_DATA, MavAutopilot, MavCmd, MavMessage, MavType,
};

#[test]
fn without_key_or_unsigned_both_binaries_refuse_to_start() {
    let dir = temp_dir("signing-nokey");
    let router = ["--radio", "/dev/null/none", "--udp-bind", "127.0.0.1:0"];
    let (code, stderr) = run(ROUTER, &dir, &router);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("--key") && stderr.contains("--unsigned"),
        "{stderr}"
    );
    let bridge = ["--fc", "/dev/null/fc", "--radio", "/dev/null/none"];
    let (code, stderr) = run(BRIDGE, &dir, &bridge);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("--key") && stderr.contains("--unsigned"),
        "{stderr}"
    );
    // a config file can say it too, and the status line shows it
    std::fs::write(
        dir.join("router.toml"),
        "unsigned = true\nstatus_interval = 0.2\n",
    )
    .unwrap();
    let mut args = router.to_vec();
    args.extend(["--config", "router.toml"]);
    let (_, stderr) = run_for(ROUTER, &dir, &args, Duration::from_millis(1500));
    assert!(stderr.contains("signing=OFF"), "{stderr}");
    // a ground signing state without a ground key is bad usage too
    let mut args = router.to_vec();
    args.extend(["--unsigned", "--ground-signing-state", "ground.state"]);
    let (code, stderr) = run(ROUTER, &dir, &args);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("--ground-key"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs a binary for `wait`, then stops it; its stderr.
fn run_for(bin: &str, dir: &Path, args: &[&str], wait: Duration) -> (Option<i32>, String) {
    let mut child = Command::new(bin)
        .args(args)
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(wait);
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn readable_truncated_and_raw_keys_are_refused_naming_the_file() {
    let dir = temp_dir("signing-badkey");
    let key = dir.join("radio.key");
    let args = [
        "--radio",
        "/dev/null/none",
        "--udp-bind",
        "127.0.0.1:0",
        "--key",
        "radio.key",
    ];
    std::fs::write(&key, format!("{}\n", "2a".repeat(32))).unwrap();
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o644)).unwrap();
    let (code, stderr) = run(ROUTER, &dir, &args);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("radio.key") && stderr.contains("0644"),
        "{stderr}"
    );
    for (contents, says) in [
        (&"2a".repeat(31)[..], "62 characters"),
        (&"*".repeat(32)[..], "column 1"),
    ] {
        std::fs::write(&key, contents).unwrap();
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).unwrap();
        let (code, stderr) = run(ROUTER, &dir, &args);
        assert_eq!(code, Some(1), "{stderr}");
        assert!(
            stderr.contains("radio.key") && stderr.contains(says),
            "{stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Regression: the router kept the ground key's last-seen timestamps in memory only, so after
/// a restart a signed ARM captured from the pilot was a "new stream" within the minute and
/// went to the radio again. Run 1 relays the pilot's ARM; run 2 gets the same bytes (and a
/// fresh signed heartbeat after them, to show it is listening) and must keep the ARM off
/// the radio.
#[test]
fn a_pilots_signed_arm_captured_before_a_router_restart_is_refused_after_it() {
    use mavlora::signing::{LinkSigner, SigningKey};
    use mavlora::wire::Sender;
    let dir = temp_dir("signing-ground-restart");
    let key = [0x5a; 32];
    let key_path = dir.join("ground.key");
    std::fs::write(&key_path, SigningKey(key).to_hex()).unwrap();
    std::fs::set_permissions(&key_path, std::fs::Permissions::from_mode(0o600)).unwrap();
    let pilot = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let router_port = common::free_udp_port();
    let clock = std::time::Instant::now();
    let mut station = LinkSigner::new(SigningKey(key), 5, mavlora::io::signing_epoch_now());
    let mut gcs = Sender::new(255, 190, mavlink::MavlinkVersion::V2);
    let mut sign = |msg: &MavMessage| {
        let at = mavlora::Instant::from_micros(clock.elapsed().as_micros() as u64);
        station.sign(&gcs.frame(msg), at).unwrap()
    };
    let arm = sign(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        ..Default::default()
    }));
    let heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        ..Default::default()
    });
    let mut runs = Vec::new();
    for run in 0..2 {
        let (mut radio, slave) = common::pty_pair();
        radio.set_timeout(Duration::from_millis(50)).unwrap();
        let log = std::fs::File::create(dir.join(format!("router-{run}.log"))).unwrap();
        let mut router = common::Guard(
            Some(
                Command::new(ROUTER)
                    .current_dir(&dir)
                    .args(["--unsigned", "--ground-key", "ground.key", "--radio"])
                    .arg(slave.name().unwrap())
                    .args(["--udp-bind", &format!("127.0.0.1:{router_port}")])
                    .args(["--udp", &pilot.local_addr().unwrap().to_string()])
                    .env("RUST_LOG", "info")
                    .stderr(Stdio::from(log))
                    .spawn()
                    .unwrap(),
            ),
            "router",
        );
        // Until the router shows it listens (run 1: the ARM, run 2: the heartbeat after it),
        // the same captured ARM and, in run 2, a freshly signed heartbeat behind it.
        let mut reader = mavlora::wire::FrameReader::new();
        let (mut seen_arm, mut seen_heartbeat) = (0, false);
        let deadline = std::time::Instant::now() + Duration::from_secs(8);
        let mut next_send = std::time::Instant::now();
        let mut buf = [0u8; 1024];
        while std::time::Instant::now() < deadline
            && !(if run == 0 {
                seen_arm > 0
            } else {
                seen_heartbeat
            })
        {
            if std::time::Instant::now() >= next_send {
                let mut datagram = arm.as_bytes().to_vec();
                if run == 1 {
                    datagram.extend_from_slice(sign(&heartbeat).as_bytes());
                }
                pilot
                    .send_to(&datagram, ("127.0.0.1", router_port))
                    .unwrap();
                next_send += Duration::from_millis(300);
            }
            if let Ok(n) = std::io::Read::read(&mut radio, &mut buf) {
                reader.push(&buf[..n]);
                while let Some(rx) = reader.next_frame() {
                    match rx.frame.decode::<MavMessage>() {
                        Ok(MavMessage::COMMAND_LONG(c))
                            if c.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM =>
                        {
                            seen_arm += 1
                        }
                        Ok(MavMessage::HEARTBEAT(_)) if rx.frame.system_id() == 255 => {
                            seen_heartbeat = true
                        }
                        _ => {}
                    }
                }
            }
        }
        let clean = router.terminate();
        let log = std::fs::read_to_string(dir.join(format!("router-{run}.log"))).unwrap();
        runs.push((seen_arm, seen_heartbeat, clean, log));
    }
    let _ = std::fs::remove_dir_all(&dir);
    let (first, second) = (&runs[0], &runs[1]);
    assert!(first.0 > 0, "run 1 did not relay the ARM:\n{}", first.3);
    assert!(
        second.1,
        "run 2 never relayed the fresh heartbeat:\n{}",
        second.3
    );
    assert_eq!(second.0, 0, "run 2 relayed the captured ARM:\n{}", second.3);
    // a new state is started loudly (its clock is all it has), the stored one is resumed
    assert!(first.3.contains("no signing state"), "{}", first.3);
    assert!(!second.3.contains("no signing state"), "{}", second.3);
    assert!(
        first.2 && second.2,
        "not a clean exit:\n{}\n{}",
        first.3,
        second.3
    );
}
/// Regression: a state file holding a timestamp at 2^48 - 60 (from a frame a key holder
/// stamped there) was loaded as is, and the program signed from there: its timestamps wrapped
/// and its peer refused every frame. Both programs now refuse such a file at start, naming it.
#[test]
fn a_signing_state_stamped_far_ahead_of_the_clock_is_refused_naming_the_file() {
    let dir = temp_dir("signing-state-ahead");
    common::radio_key(&dir, 0x2a);
    let wedged = format!(
        "mavlora-signing-state 1\ntimestamp {}\nstream 2 255 190 {}\n",
        (1u64 << 48) - 60,
        (1u64 << 48) - 61
    );
    let router = [
        "--radio",
        "/dev/null/none",
        "--udp-bind",
        "127.0.0.1:0",
        "--key",
        "radio.key",
    ];
    let bridge = [
        "--fc",
        "/dev/null/fc",
        "--radio",
        "/dev/null/none",
        "--key",
        "radio.key",
    ];
    for (bin, args, state) in [
        (ROUTER, &router, "radio.key.router-state"),
        (BRIDGE, &bridge, "radio.key.bridge-state"),
    ] {
        std::fs::write(dir.join(state), &wedged).unwrap();
        let (code, stderr) = run(bin, &dir, args);
        assert_eq!(code, Some(1), "{stderr}");
        assert!(
            stderr.contains(state) && stderr.contains("ahead"),
            "{stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
