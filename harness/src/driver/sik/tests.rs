//! The client against the emulator's SiK radios over real ptys, and against ports that
//! misbehave. Guard times are short so each test takes a second or a few.

use std::io::{Read, Write};
use std::time::Duration;

use harness_radio::sik::{Board, Param, Params};
use harness_radio::{LinkConfig, Preset, Radio};
use serialport::SerialPort;

use super::*;
use crate::driver::pty::PtyPair;
use crate::driver::radio_emulator::{End, RadioEmulator, SikPersonality};

const GUARD: Duration = Duration::from_millis(40);

fn sik() -> SikPersonality {
    SikPersonality::default().guard(GUARD)
}

fn emulator(air: Option<SikPersonality>, ground: Option<SikPersonality>) -> RadioEmulator {
    let c = LinkConfig::default();
    let radio = Radio::new(&Preset::sik_64k(), &c, &c).unwrap();
    RadioEmulator::with_sik("sik-test", radio, air, ground).unwrap()
}

fn client(path: &str) -> SikClient {
    SikClient::open(path, 57_600)
        .unwrap()
        .guard(GUARD + Duration::from_millis(60))
        .timeout(Duration::from_millis(1500))
}

/// Factory registers with `changes` saved.
fn eeprom(changes: &[(Param, u32)]) -> Params {
    let board = Board::hm_trp_915();
    let mut p = Params::defaults(&board);
    for &(param, value) in changes {
        assert!(p.set(&board, param, value));
    }
    p
}

#[test]
fn reads_both_radios_sets_a_value_on_both_and_sees_it_after_reboot() {
    let emu = emulator(Some(sik()), Some(sik()));
    let mut c = client(&emu.ground_path());
    let record = c.read_both().unwrap();
    assert_eq!(record.local.banner, "SiK 2.2 on HM-TRP");
    assert_eq!(record.remote.banner, "SiK 2.2 on HM-TRP");
    for info in [&record.local, &record.remote] {
        let numbers: Vec<u8> = info.params.iter().map(|p| p.number).collect();
        assert_eq!(numbers, (0..16).collect::<Vec<u8>>(), "{info:?}");
        assert_eq!(info.get("NETID"), Some(25));
        assert_eq!(info.get("MAX_WINDOW"), Some(131));
    }
    check_match(&record).unwrap();
    // For results.json.
    let json = serde_json::to_string(&record).unwrap();
    assert_eq!(serde_json::from_str::<SikRecord>(&json).unwrap(), record);

    c.enter_command_mode().unwrap();
    c.set_both(Param::NetId, 42).unwrap();
    // Set, not yet booted: the air radio still runs on 25.
    assert_eq!(emu.sik_radio(End::Air).unwrap().settings().net_id, 25);
    c.write_and_reboot().unwrap();
    for end in [End::Air, End::Ground] {
        assert_eq!(emu.sik_radio(end).unwrap().settings().net_id, 42);
    }
    // Into command mode twice: the second escape finds the radio there already.
    c.enter_command_mode().unwrap();
    c.enter_command_mode().unwrap();
    assert_eq!(c.banner(Which::Local).unwrap(), "SiK 2.2 on HM-TRP");
    c.leave_command_mode().unwrap();
    let after = c.read_both().unwrap();
    assert_eq!(after.local.get("NETID"), Some(42));
    assert_eq!(after.remote.get("NETID"), Some(42));
    check_match(&after).unwrap();
}

#[test]
fn a_mismatch_lists_each_setting_that_differs() {
    let ground = sik().eeprom(eeprom(&[(Param::DutyCycle, 50), (Param::MaxWindow, 100)]));
    let emu = emulator(Some(sik()), Some(ground));
    let mut c = client(&emu.air_path());
    let record = c.read_both().unwrap();
    let err = check_match(&record).unwrap_err();
    let SikError::Mismatch { port, mismatches } = &err else {
        panic!("{err}");
    };
    assert_eq!(port, &emu.air_path());
    let names: Vec<&str> = mismatches.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["DUTY_CYCLE", "MAX_WINDOW"]);
    assert_eq!((mismatches[0].local, mismatches[0].remote), (100, 50));
    let text = err.to_string();
    assert!(text.contains("DUTY_CYCLE local 100 remote 50"), "{text}");
}

#[test]
fn a_remote_on_another_netid_is_unreachable() {
    let ground = sik().eeprom(eeprom(&[(Param::NetId, 26)]));
    let emu = emulator(Some(sik()), Some(ground));
    let mut c = client(&emu.air_path());
    c.enter_command_mode().unwrap();
    assert_eq!(c.banner(Which::Local).unwrap(), "SiK 2.2 on HM-TRP");
    let err = c.banner(Which::Remote).unwrap_err();
    assert!(
        matches!(&err, SikError::RemoteUnreachable { command, .. } if command == "RTI"),
        "{err}"
    );
    let text = err.to_string();
    assert!(
        text.contains(&emu.air_path()) && text.contains("RTI"),
        "{text}"
    );
}

#[test]
fn a_port_that_never_answers_times_out_naming_the_port() {
    let pair = PtyPair::new().unwrap();
    let mut c = client(pair.path()).timeout(Duration::from_millis(200));
    let err = c.enter_command_mode().unwrap_err();
    assert!(matches!(err, SikError::NoAnswer { .. }), "{err}");
    let text = err.to_string();
    assert!(
        text.contains(pair.path()) && text.contains("no answer") && text.contains("+++"),
        "{text}"
    );
}

/// A fake radio on a pty: `OK` to the escape, then for each line the echo and `answer`.
fn fake_radio(answer: &'static [u8]) -> (PtyPair, std::thread::JoinHandle<()>) {
    let mut pair = PtyPair::new().unwrap();
    let mut master = pair.take_master().unwrap();
    master.set_timeout(Duration::from_millis(20)).unwrap();
    let worker = std::thread::spawn(move || {
        let mut got = Vec::new();
        let mut buf = [0u8; 256];
        let start = std::time::Instant::now();
        while start.elapsed() < Duration::from_secs(3) {
            let n = match master.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                Err(_) => return,
            };
            got.extend_from_slice(&buf[..n]);
            if got.ends_with(b"+++") {
                got.clear();
                let _ = master.write_all(b"OK\r\n");
            }
            if let Some(i) = got.iter().position(|&b| b == b'\r') {
                let line: Vec<u8> = got.drain(..=i).collect();
                let _ = master.write_all(&line[..line.len() - 1]);
                let _ = master.write_all(b"\r\n");
                let _ = master.write_all(answer);
            }
        }
    });
    (pair, worker)
}

#[test]
fn a_garbage_answer_is_refused_with_its_bytes() {
    let (pair, _worker) = fake_radio(b"S0: FORMAT=25\r\nS3: NETID=\xfe\x01banana\r\n");
    let mut c = client(pair.path());
    c.enter_command_mode().unwrap();
    let err = c.params(Which::Local).unwrap_err();
    let SikError::Garbage {
        port,
        command,
        bytes,
    } = &err
    else {
        panic!("{err}");
    };
    assert_eq!((port.as_str(), command.as_str()), (pair.path(), "ATI5"));
    assert!(bytes.windows(6).any(|w| w == b"banana"), "{bytes:?}");
    let text = err.to_string();
    assert!(text.contains("\\xfe\\x01banana"), "{text}");
}

#[test]
fn an_error_to_a_set_is_refused_naming_the_command() {
    let (pair, _worker) = fake_radio(b"ERROR\r\n");
    let mut c = client(pair.path());
    c.enter_command_mode().unwrap();
    let err = c.set(Which::Local, Param::TxPower, 30).unwrap_err();
    assert!(
        matches!(&err, SikError::Refused { command, answer, .. } if command == "ATS4=30" && answer == "ERROR"),
        "{err}"
    );
}

#[test]
fn the_emulators_sik_side_answers_a_heartbeat_with_radio_status_and_a_plain_side_does_not() {
    let emu = emulator(Some(sik()), None);
    let open = |path: &str| {
        serialport::new(path, 57_600)
            .timeout(Duration::from_millis(400))
            .open()
            .unwrap()
    };
    let (mut air, mut ground) = (open(&emu.air_path()), open(&emu.ground_path()));
    // A MAVLink 1 HEARTBEAT from the drone's autopilot (SiK checks no CRC).
    let mut heartbeat = vec![0xFE, 9, 0, 1, 1, 0];
    heartbeat.extend([0u8; 11]);
    air.write_all(&heartbeat).unwrap();
    let mut report = [0u8; 17];
    air.read_exact(&mut report).unwrap();
    assert_eq!(&report[..6], &[0xFE, 9, 0, b'3', b'D', 109]);
    assert_eq!(report[6 + 6], 100, "txbuf: the buffer is empty again");
    // The heartbeat itself crossed to the plain ground side, with nothing added there.
    let mut crossed = vec![0u8; heartbeat.len()];
    ground.read_exact(&mut crossed).unwrap();
    assert_eq!(crossed, heartbeat);
    ground.write_all(&heartbeat).unwrap();
    let mut more = [0u8; 1];
    assert!(
        ground.read(&mut more).is_err(),
        "a plain side injects nothing"
    );
}
