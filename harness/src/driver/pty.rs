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
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result};

use crate::clock::Mono;
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
    output: Mutex<PtyPair>,
    /// The stable name (a symlink) the reading program opens, when made.
    output_link: Option<String>,
    /// A new output master for the relay to take up, or `None` to let go of the one it has.
    swap: Arc<Mutex<Option<Option<TTYPort>>>>,
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
        let swap = Arc::new(Mutex::new(None));
        let (flag, slot) = (stop.clone(), swap.clone());
        let name = name.to_string();
        let relay = std::thread::Builder::new()
            .name(format!("pty-link-{name}"))
            .spawn(move || relay(&name, &mut from, Some(to), &flag, &slot))?;
        Ok(PtyLink {
            input,
            output: Mutex::new(output),
            output_link: None,
            swap,
            stop,
            relay: Some(relay),
        })
    }

    /// As [`PtyLink::new`], with a stable name for the reading end: the symlink `link` to
    /// its pty (what `/dev/serial/by-id` is to a USB adapter), so it can be unplugged and
    /// plugged in again ([`PtyLink::replug_output`]) as a new pty under the same name.
    pub fn with_stable_output(name: &str, link: &Path) -> Result<PtyLink> {
        let mut cable = Self::new(name)?;
        relink(
            link,
            cable
                .output
                .get_mut()
                .unwrap_or_else(PoisonError::into_inner)
                .path(),
        )?;
        cable.output_link = Some(link.display().to_string());
        Ok(cable)
    }

    pub fn input_path(&self) -> &str {
        self.input.path()
    }

    /// What the reading program opens: the stable name if there is one, else the pty.
    pub fn output_path(&self) -> String {
        match &self.output_link {
            Some(link) => link.clone(),
            None => self
                .output
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .path()
                .to_string(),
        }
    }

    /// Unplugs the reading end (its pty goes away: the reader's port hangs up and the
    /// stable name leads nowhere; what is written meanwhile is dropped), waits `down`, and
    /// plugs a new pty in under the same name. Returns when it is back. Needs
    /// [`PtyLink::with_stable_output`].
    pub fn replug_output(&self, down: Duration) -> Result<Mono> {
        let link = self
            .output_link
            .as_deref()
            .context("this cable has no stable name to replug under (with_stable_output)")?;
        let _ = std::fs::remove_file(link);
        self.hand_over(None);
        let new = PtyPair::new()?;
        // The old pair's slave closes with it: its node is gone.
        drop(std::mem::replace(
            &mut *self.output.lock().unwrap_or_else(PoisonError::into_inner),
            new,
        ));
        std::thread::sleep(down);
        let mut output = self.output.lock().unwrap_or_else(PoisonError::into_inner);
        let mut master = output.take_master()?;
        master.set_timeout(Duration::from_millis(20))?;
        relink(Path::new(link), output.path())?;
        drop(output);
        self.hand_over(Some(master));
        Ok(Mono::now())
    }

    /// Gives the relay a new output master (or none) and waits until it took it.
    fn hand_over(&self, master: Option<TTYPort>) {
        *self.swap.lock().unwrap_or_else(PoisonError::into_inner) = Some(master);
        while self
            .swap
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .is_some()
            && self.relay.as_ref().is_some_and(|r| !r.is_finished())
        {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// Points the symlink `link` at `target`, replacing what was there.
pub fn relink(link: &Path, target: &str) -> Result<()> {
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(target, link)
        .with_context(|| format!("cannot link {} to {target}", link.display()))
}

fn relay(
    name: &str,
    from: &mut TTYPort,
    mut to: Option<TTYPort>,
    stop: &AtomicBool,
    swap: &Mutex<Option<Option<TTYPort>>>,
) {
    // A cable adds no delay; neither should the relay standing in for one.
    hostio::realtime::request("pty-link");
    let mut buf = [0u8; 1024];
    let mut dropped = 0u64;
    while !stop.load(Ordering::Relaxed) {
        if let Some(next) = swap.lock().unwrap_or_else(PoisonError::into_inner).take() {
            // The old master closes here: the reader on that end sees its line hang up.
            to = next;
        }
        match from.read(&mut buf) {
            Ok(0) => {}
            Ok(n) => {
                let written = to.as_mut().is_some_and(|t| t.write_all(&buf[..n]).is_ok());
                if !written {
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

/// A two-way serial cable between two programs that each open a path (a flight
/// controller's telemetry port wired to a companion computer): what one writes at its end,
/// the other reads at its own. Both programs open a pty slave; the rig relays between the
/// masters, so neither needs to create a pty (SITL and the bridge both open a path).
pub struct PtyCable {
    ends: [PtyPair; 2],
    stop: Arc<AtomicBool>,
    relays: Vec<JoinHandle<()>>,
}

impl PtyCable {
    pub fn new(name: &str) -> Result<PtyCable> {
        let mut ends = [PtyPair::new()?, PtyPair::new()?];
        let a = ends[0].take_master()?;
        let b = ends[1].take_master()?;
        let stop = Arc::new(AtomicBool::new(false));
        let mut relays = Vec::new();
        for (label, from, to) in [("a-b", &a, &b), ("b-a", &b, &a)] {
            let mut from = from
                .try_clone_native()
                .with_context(|| format!("cannot clone the master of cable {name}"))?;
            let to = to
                .try_clone_native()
                .with_context(|| format!("cannot clone the master of cable {name}"))?;
            set_cloexec(&from)?;
            set_cloexec(&to)?;
            from.set_timeout(Duration::from_millis(100))?;
            let mut to = to;
            to.set_timeout(Duration::from_millis(20))?;
            let (flag, name) = (stop.clone(), format!("{name}-{label}"));
            let no_swap = Mutex::new(None);
            relays.push(
                std::thread::Builder::new()
                    .name(format!("pty-cable-{name}"))
                    .spawn(move || relay(&name, &mut from, Some(to), &flag, &no_swap))?,
            );
        }
        Ok(PtyCable { ends, stop, relays })
    }

    /// The path one program opens (`0`: the first end, `1`: the other).
    pub fn path(&self, end: usize) -> &str {
        self.ends[end].path()
    }
}

impl Drop for PtyCable {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for relay in self.relays.drain(..) {
            let _ = relay.join();
        }
    }
}

impl Drop for PtyLink {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(relay) = self.relay.take() {
            let _ = relay.join();
        }
        // The stable name leads to a pty that dies with us (see `RadioEmulator`'s drop).
        if let Some(link) = &self.output_link {
            let _ = std::fs::remove_file(link);
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

    #[test]
    fn cable_carries_bytes_both_ways() {
        let cable = PtyCable::new("test").unwrap();
        let open = |path: &str| {
            serialport::new(path, 57_600)
                .timeout(Duration::from_millis(500))
                .open_native()
                .unwrap()
        };
        let (mut fc, mut companion) = (open(cable.path(0)), open(cable.path(1)));
        fc.write_all(b"down").unwrap();
        companion.write_all(b"up").unwrap();
        let mut got = [0u8; 4];
        companion.read_exact(&mut got).unwrap();
        assert_eq!(&got, b"down");
        let mut got = [0u8; 2];
        fc.read_exact(&mut got).unwrap();
        assert_eq!(&got, b"up");
    }

    /// A replugged reading end: the reader's port hangs up, the stable name leads nowhere
    /// while it is out, and the same name opens a new pty that carries the bytes again.
    #[test]
    fn a_replugged_output_hangs_up_and_comes_back_under_its_stable_name() {
        let dir = tempfile::tempdir().unwrap();
        let name = dir.path().join("rx0-device");
        let link = Arc::new(PtyLink::with_stable_output("test", &name).unwrap());
        assert_eq!(link.output_path(), name.display().to_string());
        let open = |path: &str| {
            serialport::new(path, 100_000)
                .timeout(Duration::from_millis(300))
                .open_native()
        };
        let mut writer = open(link.input_path()).unwrap();
        let mut reader = open(&link.output_path()).unwrap();
        writer.write_all(b"one").unwrap();
        let mut got = [0u8; 3];
        reader.read_exact(&mut got).unwrap();
        assert_eq!(&got, b"one");

        let replug = {
            let link = link.clone();
            std::thread::spawn(move || link.replug_output(Duration::from_millis(500)).unwrap())
        };
        std::thread::sleep(Duration::from_millis(250));
        let mut buf = [0u8; 8];
        assert!(
            matches!(reader.read(&mut buf), Ok(0) | Err(_))
                && !matches!(reader.read(&mut buf), Err(e) if e.kind() == io::ErrorKind::TimedOut),
            "the unplugged end still reads as a live line"
        );
        assert!(
            open(&link.output_path()).is_err(),
            "the name leads somewhere while out"
        );
        replug.join().unwrap();
        let mut reader = open(&link.output_path()).unwrap();
        writer.write_all(b"two").unwrap();
        reader.read_exact(&mut got).unwrap();
        assert_eq!(&got, b"two");
        // The name goes with the link (it would dangle in the phase's folder).
        drop((reader, writer));
        drop(Arc::into_inner(link).expect("the replug thread let go"));
        assert!(
            std::fs::symlink_metadata(&name).is_err(),
            "the name is left"
        );
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
