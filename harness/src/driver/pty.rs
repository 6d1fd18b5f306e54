//! Pty pairs: the rig's stand-in for serial cables when no hardware is there.
//!
//! A pty does not pace bytes or emulate parity and baud rate; timing comes
//! from whoever writes. Reading a master whose slave nobody holds gives EIO,
//! so each pair keeps its own slave open for its whole life.
//!
//! Both ends are close-on-exec: serialport opens them without it, and then every
//! child the rig spawns would hold every master, so closing one (a replugged
//! adapter) would never hang the line up for the device on the other end.

use std::io::{self, Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result};
use serialport::{SerialPort, TTYPort};

/// One pty pair: the rig holds the master; a program opens [`PtyPair::path`].
pub struct PtyPair {
    master: Option<TTYPort>,
    slave: TTYPort,
    path: String,
}

impl PtyPair {
    pub fn new() -> Result<PtyPair> {
        let (master, slave) = TTYPort::pair().context("cannot create a pty pair")?;
        let path = slave.name().context("pty slave has no path")?;
        for port in [&master, &slave] {
            set_cloexec(port).with_context(|| format!("cannot set close-on-exec on {path}"))?;
        }
        Ok(PtyPair {
            master: Some(master),
            slave,
            path,
        })
    }

    /// The slave's path, for a device or fixture to open.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// The master end, for the rig to read or write; once.
    pub fn take_master(&mut self) -> Result<TTYPort> {
        self.master
            .take()
            .with_context(|| format!("master of {} already taken", self.path))
    }

    /// Keeps the slave referenced (see the module docs).
    pub fn slave(&self) -> &TTYPort {
        &self.slave
    }
}

/// Marks `port`'s descriptor close-on-exec. A child spawned between `TTYPort::pair`
/// and this call still inherits it; the rig creates its ptys before spawning.
fn set_cloexec(port: &TTYPort) -> io::Result<()> {
    use std::os::fd::{AsRawFd, BorrowedFd};
    // SAFETY: the descriptor belongs to `port`, which outlives this borrow.
    #[allow(unsafe_code)]
    let fd = unsafe { BorrowedFd::borrow_raw(port.as_raw_fd()) };
    rustix::io::fcntl_setfd(fd, rustix::io::FdFlags::CLOEXEC)?;
    Ok(())
}

/// A one-way serial cable between two programs that both open a path:
/// bytes written at [`PtyLink::input_path`] come out at [`PtyLink::output_path`].
pub struct PtyLink {
    input: PtyPair,
    output: PtyPair,
    stop: Arc<AtomicBool>,
    relay: Option<JoinHandle<()>>,
}

impl PtyLink {
    pub fn new(name: &str) -> Result<PtyLink> {
        let mut input = PtyPair::new()?;
        let mut output = PtyPair::new()?;
        let mut from = input.take_master()?;
        let mut to = output.take_master()?;
        from.set_timeout(Duration::from_millis(100))?;
        // A reader that stopped must not stall the writer for long.
        to.set_timeout(Duration::from_millis(20))?;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let name = name.to_string();
        let relay = std::thread::Builder::new()
            .name(format!("pty-link-{name}"))
            .spawn(move || relay(&name, &mut from, &mut to, &flag))?;
        Ok(PtyLink {
            input,
            output,
            stop,
            relay: Some(relay),
        })
    }

    pub fn input_path(&self) -> &str {
        self.input.path()
    }

    pub fn output_path(&self) -> &str {
        self.output.path()
    }
}

fn relay(name: &str, from: &mut TTYPort, to: &mut TTYPort, stop: &AtomicBool) {
    // A cable adds no delay; neither should the relay standing in for one.
    hostio::realtime::request("pty-link");
    let mut buf = [0u8; 1024];
    let mut dropped = 0u64;
    while !stop.load(Ordering::Relaxed) {
        match from.read(&mut buf) {
            Ok(0) => {}
            Ok(n) => {
                if to.write_all(&buf[..n]).is_err() {
                    dropped += n as u64;
                }
            }
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                ) => {}
            Err(e) => {
                tracing::debug!(link = name, error = %e, "pty link closed");
                break;
            }
        }
    }
    if dropped > 0 {
        tracing::warn!(link = name, dropped, "pty link dropped bytes nobody read");
    }
}

impl Drop for PtyLink {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(relay) = self.relay.take() {
            let _ = relay.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn link_carries_bytes_from_input_to_output() {
        let link = PtyLink::new("test").unwrap();
        let mut writer = serialport::new(link.input_path(), 100_000)
            .timeout(Duration::from_millis(200))
            .open_native()
            .unwrap();
        let mut reader = serialport::new(link.output_path(), 100_000)
            .timeout(Duration::from_millis(500))
            .open_native()
            .unwrap();
        writer.write_all(b"\x0fhello").unwrap();
        let mut got = [0u8; 6];
        reader.read_exact(&mut got).unwrap();
        assert_eq!(&got, b"\x0fhello");
    }

    /// Regression: the masters were inherited by every child, so closing one never hung
    /// the line up for the device (the replug phases need the hang-up).
    #[test]
    fn a_spawned_child_holds_no_end_of_the_rigs_ptys() {
        let pair = PtyPair::new().unwrap();
        let mut child = std::process::Command::new("sleep")
            .arg("5")
            .spawn()
            .unwrap();
        let fds = std::fs::read_dir(format!("/proc/{}/fd", child.id())).unwrap();
        let held: Vec<_> = fds
            .filter_map(|e| std::fs::read_link(e.ok()?.path()).ok())
            .filter(|l| l.to_string_lossy().contains("ptmx") || l.to_str() == Some(pair.path()))
            .collect();
        child.kill().unwrap();
        child.wait().unwrap();
        assert!(held.is_empty(), "the child holds {held:?}");
    }
}
