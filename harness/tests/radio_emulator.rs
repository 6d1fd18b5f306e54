//! The radio emulator over real pty pairs and the real clock: bytes written
//! on one side arrive on the other, paced by the model. Timing bounds are
//! generous (the host is shared); the model's own timing is tested exactly,
//! under a virtual clock, in `radio_model.rs`.

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use harness::driver::radio_emulator::RadioEmulator;
use harness_radio::{Direction, LinkBudget, LinkConfig, Preset, Radio};
use serialport::{SerialPort as _, TTYPort};

fn open(path: &str) -> TTYPort {
    serialport::new(path, 57_600)
        .timeout(Duration::from_millis(100))
        .open_native()
        .unwrap()
}

/// Reads until `want` bytes came or `deadline` passed.
fn read_for(port: &mut TTYPort, want: usize, deadline: Duration) -> Vec<u8> {
    let start = Instant::now();
    let mut got = Vec::new();
    let mut buf = [0u8; 1024];
    while got.len() < want && start.elapsed() < deadline {
        match port.read(&mut buf) {
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => panic!("read: {e}"),
        }
    }
    got
}

/// One 17-byte write over LoRa SF7 takes the 5 ms idle timeout plus the
/// 56.6 ms airtime before it can arrive; every byte value passes unchanged.
#[test]
fn a_lora_message_crosses_after_its_airtime() {
    let cfg = LinkConfig::default();
    let radio = Radio::new(&Preset::lora_sf7(), &cfg, &cfg).unwrap();
    let emulator = RadioEmulator::new("lora-test", radio).unwrap();
    let mut a = open(&emulator.air_path());
    let mut b = open(&emulator.ground_path());
    let message: Vec<u8> = (0u8..17)
        .map(|i| i.wrapping_mul(15).wrapping_add(0x0a))
        .collect();
    let sent = Instant::now();
    a.write_all(&message).unwrap();
    let got = read_for(&mut b, message.len(), Duration::from_secs(3));
    let took = sent.elapsed();
    assert_eq!(got, message);
    assert!(
        took >= Duration::from_micros(61_000),
        "arrived after {took:?}"
    );
    assert!(took < Duration::from_secs(1), "arrived after {took:?}");
    // And back, B → A.
    b.write_all(&[0x0d, 0x03, 0x11, 0x13, 0x7f, 0xff]).unwrap();
    let back = read_for(&mut a, 6, Duration::from_secs(3));
    assert_eq!(back, [0x0d, 0x03, 0x11, 0x13, 0x7f, 0xff]);
    let radio = emulator.finish();
    assert_eq!(radio.link(Direction::Downlink).stats().bytes_delivered, 17);
    assert_eq!(radio.link(Direction::Uplink).stats().bytes_delivered, 6);
}

/// 6 000 bytes each way through SiK at 64 kbit/s: everything offered is
/// delivered or dropped at the buffer, the far side reads exactly what was
/// delivered, and it cannot arrive faster than the TDM windows allow
/// (3 full packets per 236.8 ms round, ≈ 3.2 kB/s per direction).
#[test]
fn sik_carries_both_directions_at_no_more_than_its_air_rate() {
    let cfg = LinkConfig::default();
    let radio = Radio::new(&Preset::sik_64k(), &cfg, &cfg).unwrap();
    let emulator = RadioEmulator::new("sik-test", radio).unwrap();
    let mut a = open(&emulator.air_path());
    let mut b = open(&emulator.ground_path());
    let start = Instant::now();
    let payload: Vec<u8> = (0..6000u32).map(|i| (i % 251) as u8).collect();
    // Written at once: far more than the 1850-byte buffer takes.
    a.write_all(&payload).unwrap();
    b.write_all(&payload).unwrap();
    let mut got_a = Vec::new();
    let mut got_b = Vec::new();
    // Drain: the buffer holds at most 1850 bytes, < 1 s at the air rate.
    let until = Instant::now() + Duration::from_secs(2);
    while Instant::now() < until {
        got_b.extend(read_for(&mut b, usize::MAX, Duration::from_millis(50)));
        got_a.extend(read_for(&mut a, usize::MAX, Duration::from_millis(50)));
    }
    let elapsed = start.elapsed().as_secs_f64();
    let radio = emulator.finish();
    for (dir, got) in [(Direction::Downlink, &got_b), (Direction::Uplink, &got_a)] {
        let s = radio.link(dir).stats();
        assert_eq!(s.bytes_offered, 6000, "{dir:?}: {s:?}");
        assert_eq!(s.bytes_delivered + s.bytes_dropped, 6000, "{dir:?}: {s:?}");
        assert!(
            s.bytes_dropped > 0,
            "{dir:?}: 6 kB/s offered should overflow: {s:?}"
        );
        assert_eq!(got.len() as u64, s.bytes_delivered, "{dir:?}");
        // Delivered bytes are the offered stream with gaps, in order: every
        // byte read follows the i % 251 pattern somewhere, never reordered
        // within a packet (check runs of consecutive bytes).
        let in_order = got
            .windows(2)
            .filter(|w| w[1] == ((w[0] as u32 + 1) % 251) as u8)
            .count();
        assert!(
            in_order as f64 > 0.95 * got.len() as f64,
            "{dir:?}: stream scrambled"
        );
        // No faster than 3 full packets per 236.8 ms round.
        let ceiling = 3.0 * 250.0 / 0.2368;
        assert!(
            (s.bytes_delivered as f64) <= ceiling * elapsed,
            "{dir:?}: {} B in {elapsed:.2} s",
            s.bytes_delivered
        );
    }
}

/// Attenuation past the edge loses what it should: SiK at 95 dB (11 dB
/// past the fitted 84 dB edge) delivers almost nothing.
#[test]
fn a_deep_fade_loses_the_packets() {
    let lossy = LinkConfig {
        budget: LinkBudget::attenuation(95.0),
        ..LinkConfig::default()
    };
    let radio = Radio::new(&Preset::sik_64k(), &LinkConfig::default(), &lossy).unwrap();
    let emulator = RadioEmulator::new("fade-test", radio).unwrap();
    let mut a = open(&emulator.air_path());
    let mut b = open(&emulator.ground_path());
    for _ in 0..10 {
        a.write_all(&[0x42; 21]).unwrap();
        std::thread::sleep(Duration::from_millis(30));
    }
    let got = read_for(&mut b, usize::MAX, Duration::from_millis(800));
    let radio = emulator.finish();
    let s = radio.link(Direction::Downlink).stats();
    assert!(s.packets_sent > 0, "{s:?}");
    assert_eq!(s.packets_lost, s.packets_sent, "{s:?}");
    assert!(got.is_empty());
}

/// On a bench the emulator sits between two serial devices; here the devices are the far
/// ends of two pty pairs, and the programs' ends are their masters.
#[test]
fn between_two_devices_carries_both_ways() {
    let (mut drone, drone_dev) = TTYPort::pair().unwrap();
    let (mut ground, ground_dev) = TTYPort::pair().unwrap();
    for p in [&mut drone, &mut ground] {
        p.set_timeout(Duration::from_millis(100)).unwrap();
    }
    let cfg = LinkConfig::default();
    let radio = Radio::new(&Preset::sik_64k(), &cfg, &cfg).unwrap();
    let emulator = RadioEmulator::between(
        "bench-test",
        radio,
        drone_dev.name().as_deref().unwrap(),
        ground_dev.name().as_deref().unwrap(),
        57_600,
    )
    .unwrap();
    assert_eq!(emulator.air_path(), drone_dev.name().unwrap());
    drone.write_all(b"telemetry").unwrap();
    assert_eq!(
        read_for(&mut ground, 9, Duration::from_secs(3)),
        b"telemetry"
    );
    ground.write_all(b"command").unwrap();
    assert_eq!(read_for(&mut drone, 7, Duration::from_secs(3)), b"command");
    let radio = emulator.finish();
    assert_eq!(radio.link(Direction::Downlink).stats().bytes_offered, 9);
    assert_eq!(radio.link(Direction::Uplink).stats().bytes_offered, 7);
    // a device that is not there is an error naming it
    let cfg = LinkConfig::default();
    let radio = Radio::new(&Preset::sik_64k(), &cfg, &cfg).unwrap();
    let err = RadioEmulator::between("bench", radio, "/dev/ttyNOPE0", "/dev/ttyNOPE1", 57_600)
        .err()
        .unwrap();
    assert!(format!("{err:#}").contains("/dev/ttyNOPE0"), "{err:#}");
}

/// A replugged air side: the program's open port hangs up, the stable name leads nowhere
/// while it is out, what the ground sends meanwhile is counted as unwritten, and the same
/// name opens a new pty that carries bytes both ways again.
#[test]
fn a_replugged_side_hangs_up_and_comes_back_under_its_stable_name() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = LinkConfig::default();
    let radio = Radio::new(&Preset::sik_64k(), &cfg, &cfg).unwrap();
    let emulator = std::sync::Arc::new(
        RadioEmulator::with_stable_names("replug-test", radio, dir.path()).unwrap(),
    );
    let air_name = emulator.air_path();
    assert!(air_name.ends_with("radio-air"), "{air_name}");
    let mut a = open(&air_name);
    let mut b = open(&emulator.ground_path());
    a.write_all(b"before").unwrap();
    assert_eq!(read_for(&mut b, 6, Duration::from_secs(3)), b"before");

    let replugger = {
        let emulator = emulator.clone();
        std::thread::spawn(move || {
            emulator
                .replug(
                    harness::driver::radio_emulator::End::Air,
                    Duration::from_millis(600),
                )
                .unwrap()
        })
    };
    std::thread::sleep(Duration::from_millis(200));
    // Out: the old port hangs up, the name leads nowhere, the ground's bytes go nowhere.
    let mut buf = [0u8; 16];
    let hung_up = matches!(a.read(&mut buf), Ok(0) | Err(_))
        && !matches!(a.read(&mut buf), Err(e) if e.kind() == std::io::ErrorKind::TimedOut);
    assert!(
        hung_up,
        "the unplugged side's port still reads as a live line"
    );
    assert!(serialport::new(&air_name, 57_600).open_native().is_err());
    b.write_all(b"lost").unwrap();
    let back = replugger.join().unwrap();
    assert!(harness::clock::Mono::now().since(back) < Duration::from_secs(1));
    assert!(
        emulator.unwritten() >= 4,
        "unwritten {}",
        emulator.unwritten()
    );

    let mut a = open(&air_name);
    a.write_all(b"after").unwrap();
    assert_eq!(read_for(&mut b, 5, Duration::from_secs(3)), b"after");
    b.write_all(b"down").unwrap();
    assert_eq!(read_for(&mut a, 4, Duration::from_secs(3)), b"down");
    // The names go with the emulator: links left in a phase's folder would dangle, and an
    // evidence folder holds files only.
    drop((a, b));
    drop(std::sync::Arc::into_inner(emulator).expect("the replug thread let go"));
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}
