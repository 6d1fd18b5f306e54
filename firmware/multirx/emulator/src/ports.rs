//! Serial ports as MultiRX sees them: SBUS settings, reader threads that
//! timestamp what arrives, and writers that never stall the engine.

use std::io::{self, Read, Write};
use std::sync::mpsc::Sender;
use std::thread;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use serialport::TTYPort;

/// Which input bytes came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    Receiver(u8),
    Ifs,
}

/// Bytes read from an input, stamped when `read` returned.
#[derive(Debug)]
pub enum Input {
    Bytes {
        source: Source,
        at: Instant,
        bytes: Vec<u8>,
    },
    /// The port failed (a USB adapter unplugged, a pty closed); the input
    /// is silent until it is reopened, which the engine treats as link loss.
    Closed { source: Source, error: String },
    /// A reader still waits for its port to come back (sent once per attempt,
    /// so a reader notices when the engine is gone).
    Waiting,
}

/// Opens `path` with SBUS settings ([`hostio::sbus::port`]).
pub fn open_sbus(path: &str, timeout: Duration) -> Result<TTYPort> {
    hostio::sbus::port(path)
        .timeout(timeout)
        .open_native()
        .with_context(|| format!("cannot open serial port {path}"))
}

/// The device `path` names now (its `st_rdev`), following symlinks such as
/// `/dev/serial/by-id/...`; `None` if the path is gone.
fn device_of(path: &str) -> Option<u64> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| m.rdev())
}

/// Whether the other end of `port` hung up (a pty's master closed, a modem
/// line dropped): reads then time out and writes fill a buffer nobody drains,
/// which looks like a quiet or slow peer unless the poll flags are asked.
fn hung_up(port: &TTYPort) -> bool {
    use rustix::event::{PollFd, PollFlags, Timespec, poll};
    use std::os::fd::{AsRawFd, BorrowedFd};
    // SAFETY: the descriptor belongs to `port`, which outlives this borrow.
    let fd = unsafe { BorrowedFd::borrow_raw(port.as_raw_fd()) };
    let mut fds = [PollFd::new(&fd, PollFlags::empty())];
    let now = Timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    poll(&mut fds, Some(&now)).is_ok()
        && fds[0]
            .revents()
            .intersects(PollFlags::HUP | PollFlags::ERR | PollFlags::NVAL)
}

/// First and longest wait between attempts to reopen a port that went away.
const REOPEN_FIRST: Duration = Duration::from_millis(100);
const REOPEN_MAX: Duration = Duration::from_secs(1);

/// Starts a thread forwarding everything read from `port` (opened from `path`)
/// to `tx`. If the port fails (a USB adapter unplugged, a pty closed), the
/// input is silent — the engine treats that as link loss — and the thread
/// reopens `path` with backoff until it comes back (the adapter replugged),
/// so a receiver that returns is heard again.
pub fn spawn_reader(
    source: Source,
    path: String,
    mut port: TTYPort,
    timeout: Duration,
    tx: Sender<Input>,
) -> Result<()> {
    let name = format!("read-{source:?}");
    thread::Builder::new().name(name).spawn(move || {
        hostio::realtime::request("input");
        let mut buf = [0u8; 256];
        let mut device = device_of(&path);
        loop {
            let error = match port.read(&mut buf) {
                Ok(n) if n > 0 => {
                    let input = Input::Bytes {
                        source,
                        at: Instant::now(),
                        bytes: buf[..n].to_vec(),
                    };
                    if tx.send(input).is_err() {
                        return; // engine gone
                    }
                    continue;
                }
                // Quiet: a hung-up pty or an unplugged adapter reads as quiet too,
                // so check the name still leads to the device that was opened.
                Err(e) if e.kind() == io::ErrorKind::TimedOut => {
                    let now = device_of(&path);
                    if now.is_none() || now != device {
                        format!("{path} no longer names the device that was opened")
                    } else if hung_up(&port) {
                        "the other end hung up".to_string()
                    } else {
                        continue;
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                // A read timeout is an error above: 0 bytes is end of file (hang-up).
                Ok(_) => "end of file (hang-up)".to_string(),
                Err(e) => e.to_string(),
            };
            if tx.send(Input::Closed { source, error }).is_err() {
                return;
            }
            match reopen(&path, timeout, &tx) {
                Some(reopened) => {
                    tracing::info!(?source, %path, "input reopened");
                    port = reopened;
                    device = device_of(&path);
                }
                None => return, // engine gone
            }
        }
    })?;
    Ok(())
}

/// Tries `path` with backoff until it opens; `None` once the engine is gone.
fn reopen(path: &str, timeout: Duration, tx: &Sender<Input>) -> Option<TTYPort> {
    let mut wait = REOPEN_FIRST;
    loop {
        thread::sleep(wait);
        if let Ok(port) = open_sbus(path, timeout) {
            return Some(port);
        }
        // Sending nothing would never notice the engine's end: probe the channel.
        if tx.send(Input::Waiting).is_err() {
            return None;
        }
        wait = (wait * 2).min(REOPEN_MAX);
    }
}

/// How long an output may fail hard (not merely be full) before it counts as
/// gone for good: long enough for a USB adapter to be replugged.
pub const GONE_AFTER: Duration = Duration::from_secs(10);
/// Least time between two attempts to reopen a failed output.
const OUTPUT_REOPEN_EVERY: Duration = Duration::from_millis(500);

/// An output that drops what it cannot write at once instead of blocking:
/// a flight controller that stops reading must not stop MultiRX. A port that
/// fails outright (unplugged, pty closed) is reopened by path; one that stays
/// failed for [`GONE_AFTER`] is [`gone`](Output::gone).
pub struct Output {
    name: String,
    port: TTYPort,
    timeout: Duration,
    pub written: u64,
    pub dropped: u64,
    failing: bool,
    /// Since when writes fail with something other than a full buffer, and why.
    broken: Option<(Instant, String)>,
    last_reopen: Option<Instant>,
    /// The device the name led to when it was opened.
    device: Option<u64>,
    /// When the name was last checked against `device`.
    checked: Instant,
}

impl Output {
    pub fn new(name: &str, port: TTYPort, timeout: Duration) -> Self {
        Output {
            name: name.to_string(),
            port,
            timeout,
            written: 0,
            dropped: 0,
            failing: false,
            broken: None,
            last_reopen: None,
            device: device_of(name),
            checked: Instant::now(),
        }
    }

    /// Writes `bytes` whole or counts them dropped.
    pub fn send(&mut self, bytes: &[u8]) {
        // A hung-up pty may swallow writes without an error: the name tells.
        if self.broken.is_none() && self.checked.elapsed() >= OUTPUT_REOPEN_EVERY {
            self.checked = Instant::now();
            if device_of(&self.name).is_none_or(|d| Some(d) != self.device) || hung_up(&self.port) {
                tracing::warn!(port = %self.name, "output's device went away");
                self.broken = Some((
                    Instant::now(),
                    "the name no longer leads to the device that was opened".into(),
                ));
            }
        }
        if self.broken.is_some() {
            self.try_reopen();
        }
        match self.port.write_all(bytes) {
            Ok(()) => {
                self.broken = None;
                if self.failing {
                    tracing::info!(port = %self.name, dropped = self.dropped, "output flowing again");
                    self.failing = false;
                }
                self.written += 1;
            }
            Err(e) => {
                self.dropped += 1;
                if !self.failing {
                    tracing::warn!(port = %self.name, error = %e, "output not accepting bytes; dropping");
                    self.failing = true;
                }
                // A full buffer is a reader that is slow; a hung-up pty or an
                // unplugged adapter can look the same, so check the name too.
                let full = matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                ) && self.device.is_some()
                    && device_of(&self.name) == self.device
                    && !hung_up(&self.port);
                if !full && self.broken.is_none() {
                    self.broken = Some((Instant::now(), e.to_string()));
                }
            }
        }
    }

    fn try_reopen(&mut self) {
        let now = Instant::now();
        if self
            .last_reopen
            .is_some_and(|t| now.duration_since(t) < OUTPUT_REOPEN_EVERY)
        {
            return;
        }
        self.last_reopen = Some(now);
        if let Ok(port) = open_sbus(&self.name, self.timeout) {
            tracing::info!(port = %self.name, "output reopened");
            self.port = port;
            self.device = device_of(&self.name);
        }
    }

    /// Why the port is gone for good: it has failed outright for [`GONE_AFTER`]
    /// and could not be reopened.
    pub fn gone(&self) -> Option<String> {
        self.broken
            .as_ref()
            .filter(|(since, _)| since.elapsed() >= GONE_AFTER)
            .map(|(since, why)| {
                format!(
                    "{}: failing for {:.1} s and not reopened ({why})",
                    self.name,
                    since.elapsed().as_secs_f64()
                )
            })
    }
}
