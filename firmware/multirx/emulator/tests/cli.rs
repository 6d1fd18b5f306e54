//! The real `multirx-emu` binary on real pty pairs.

use std::io::{Read, Write};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use multirx_core::wire::{SbusFrame, SbusRepr};
use multirx_core::{Config, Mode};
use serialport::{SerialPort, TTYPort};

const EMU: &str = env!("CARGO_BIN_EXE_multirx-emu");

struct Pty {
    master: TTYPort,
    // Held open so the master never reads EIO while the device (re)opens it.
    slave: TTYPort,
}

impl Pty {
    fn new() -> Pty {
        let (mut master, slave) = TTYPort::pair().expect("pty pair");
        master.set_timeout(Duration::from_millis(50)).unwrap();
        Pty { master, slave }
    }
    fn path(&self) -> String {
        self.slave.name().unwrap()
    }
}

struct Killed(Child);
impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn write_config(dir: &std::path::Path, text: &str) -> std::path::PathBuf {
    let path = dir.join("multirx.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn bad_config_names_file_line_and_field() {
    let dir = tempdir();
    let path = write_config(
        &dir,
        "mode = \"parallel\"\nreceivers = 2\n[link]\nacquire_frames = 0\n",
    );
    let out = Command::new(EMU)
        .args([
            "--config",
            path.to_str().unwrap(),
            "--rx",
            "/dev/null",
            "--rx",
            "/dev/null",
            "--fc",
            "/dev/null",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!(
            "{}:4:1: link.acquire_frames: 0 is outside 1..=20",
            path.display()
        )),
        "{stderr}"
    );
}

#[test]
fn forwards_the_active_receiver_and_reports_power() {
    let dir = tempdir();
    let path = write_config(&dir, "mode = \"parallel\"\nreceivers = 2\n");
    let config = Config::new(Mode::Parallel, 2);
    let (mut rx0, rx1, mut fc, mut status) = (Pty::new(), Pty::new(), Pty::new(), Pty::new());
    let _child = Killed(
        Command::new(EMU)
            .args(["--config", path.to_str().unwrap()])
            .args(["--rx", &rx0.path(), "--rx", &rx1.path()])
            .args(["--fc", &fc.path(), "--status", &status.path()])
            .stdin(Stdio::null())
            .spawn()
            .unwrap(),
    );

    let sticks = SbusRepr {
        channels: [1234; 16],
        ..SbusRepr::default()
    }
    .to_bytes();
    let start = Instant::now();
    let mut frames = Vec::new();
    let mut buf = [0u8; 512];
    let mut pending = Vec::new();
    while start.elapsed() < Duration::from_secs(3) {
        rx0.master.write_all(&sticks).unwrap();
        if let Ok(n) = fc.master.read(&mut buf) {
            pending.extend_from_slice(&buf[..n]);
        }
        while pending.len() >= 25 {
            let frame: Vec<u8> = pending.drain(..25).collect();
            frames.push(SbusRepr::parse(&SbusFrame::new_checked(&frame[..]).unwrap()).unwrap());
        }
        std::thread::sleep(Duration::from_millis(7));
    }
    assert!(frames.len() > 100, "only {} frames in 3 s", frames.len());
    let last = frames.last().unwrap();
    assert_eq!(last.channels[0], 1234);
    assert_eq!(
        last.channels[usize::from(config.pilot_channel)],
        config.pilot_values[0]
    );

    let mut text = String::new();
    let mut buf = [0u8; 4096];
    if let Ok(n) = status.master.read(&mut buf) {
        text.push_str(&String::from_utf8_lossy(&buf[..n]));
    }
    for expected in [" power 0 on", " power 1 on", " active 0"] {
        assert!(
            text.contains(expected),
            "{expected} missing from status:\n{text}"
        );
    }
    drop(rx1);
}

fn tempdir() -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "multirx-emu-test-{}-{:?}",
        std::process::id(),
        std::thread::current().id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
