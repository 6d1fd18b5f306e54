//! A serial port with a reader thread and a writer thread, closed and reopened with backoff
//! when it disappears (USB radios re-enumerate; a pty whose other side closed reads EOF or
//! EIO) *or* when a write fails or stalls (a radio that stopped reading: a writer that gave
//! up while the reader kept the port open would never send again).
//!
//! A port is reopened only while its name leads to the device first opened, or follows it
//! by design (`usb-serial:SERIAL`, `/dev/serial/by-id/...`): see [`hostio::device`].
//! Otherwise a new unrelated pty that gets a vanished radio pty's number would receive the
//! bridge's MAVLink.
//!
//! Writes go through a bounded [`Queue`] to the writer thread, so the main loop never blocks
//! on a port. Every byte offered to [`SerialLink::write`] ends up counted once: written, or
//! dropped (queue full, port closed, the unwritten rest of a frame whose write failed), or
//! still queued — see [`SerialCounters`].

use std::io::{ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::Duration;

use hostio::device::{DeviceError, Identity, PortName, Reopen};
use serialport::{SerialPort, TTYPort};
use tracing::{error, info, warn};

use super::queue::{Lane, Order, Queue};
use super::wake::{Ready, Wake};
use super::{Event, Inbox};
use crate::schedule::Class;
use crate::wire::Frame;

/// A write that makes no progress for this long is a stall: the port is closed and reopened.
pub const WRITE_STALL: Duration = Duration::from_secs(1);
/// Bytes queued towards one port at most (16 KB: 2.8 s of a 57600-baud radio).
pub const WRITE_QUEUE_BYTES: usize = 16 * 1024;
/// First wait before reopening; doubled on each consecutive failure.
const BACKOFF_MIN: Duration = Duration::from_millis(100);
/// Longest wait before trying to open a port that cannot be opened.
const BACKOFF_MAX_OPEN: Duration = Duration::from_secs(5);
/// Longest wait before reopening a port whose writes stall (bounds the recovery time once
/// the far end reads again: this plus [`WRITE_STALL`]).
const BACKOFF_MAX_STALL: Duration = Duration::from_secs(2);

/// What happened on a port.
#[derive(Debug)]
pub enum SerialEvent {
    /// The port is open (first time or again).
    Opened,
    /// Bytes read.
    Bytes(Vec<u8>),
    /// No byte for the port's idle gap after some arrived: a partial frame still buffered
    /// will never complete (its tail was lost) and should be dropped.
    Idle,
    /// The port failed, vanished or stalled; it is being reopened.
    Closed,
}

/// A port's byte counters: `offered = written + dropped + queued` once the link is stopped
/// (while running, give or take the one frame being written).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SerialCounters {
    /// Times the port was (re)opened.
    pub opens: u64,
    /// Write stalls and failures (each closed and reopened the port).
    pub write_failures: u64,
    /// Bytes given to [`SerialLink::write`].
    pub offered_bytes: u64,
    /// Bytes the port accepted.
    pub written_bytes: u64,
    /// Bytes never written: queue full, port closed, or after a failed write.
    pub dropped_bytes: u64,
    /// Bytes waiting in the write queue.
    pub queued_bytes: u64,
    /// Opens refused because the name now leads to another device (see [`Reopen`]).
    pub refused_opens: u64,
}

#[derive(Debug)]
struct Shared {
    /// Wakes the reader from its wait on the port: a write failed, or stop.
    wake: Wake,
    /// The writer's handle on the open port; `None` while closed.
    port: Mutex<Option<Box<dyn SerialPort>>>,
    /// `port` is `Some`, readable without waiting for a write in progress.
    open: AtomicBool,
    /// Set by the writer when a write failed: the reader closes and reopens the port.
    broken: AtomicBool,
    /// A write succeeded since the port was last opened (resets the backoff).
    wrote: AtomicBool,
    /// The last write failure was a timeout (the device is still there, it does not read),
    /// not an error of a device that went away.
    stalled: AtomicBool,
    opens: AtomicU64,
    refused_opens: AtomicU64,
    write_failures: AtomicU64,
    offered: AtomicU64,
    written: AtomicU64,
    /// Dropped by the writer (port closed, failed write); queue drops are in the queue.
    dropped: AtomicU64,
}

/// One serial port with its reader and writer threads.
#[derive(Debug)]
pub struct SerialLink {
    name: &'static str,
    out: Arc<Queue<Vec<u8>>>,
    shared: Arc<Shared>,
    writer: Option<JoinHandle<()>>,
}

impl SerialLink {
    /// Starts the threads for the port named `port` (a path or `usb-serial:SERIAL`) at `baud`;
    /// events go to `inbox`. `idle_gap`: after bytes, this long without any sends
    /// [`SerialEvent::Idle`] (see [`frame_gap`]). Frames leave in `order`: the radio's in the
    /// order they were written (numbered and signed for the air), another port's commands
    /// and mission traffic first. Fails only on a name that names nothing.
    pub fn spawn(
        name: &'static str,
        port: &str,
        baud: u32,
        idle_gap: Duration,
        order: Order,
        inbox: Inbox,
        stop: Arc<AtomicBool>,
    ) -> anyhow::Result<Self> {
        let path = PortName::parse(port).map_err(|e| anyhow::anyhow!("{name} port: {e}"))?;
        let shared = Arc::new(Shared {
            wake: Wake::new()?,
            port: Mutex::default(),
            open: AtomicBool::default(),
            broken: AtomicBool::default(),
            wrote: AtomicBool::default(),
            stalled: AtomicBool::default(),
            opens: AtomicU64::default(),
            refused_opens: AtomicU64::default(),
            write_failures: AtomicU64::default(),
            offered: AtomicU64::default(),
            written: AtomicU64::default(),
            dropped: AtomicU64::default(),
        });
        let out = Arc::new(Queue::with_order(WRITE_QUEUE_BYTES, order));
        let s = shared.clone();
        thread::Builder::new()
            .name(format!("serial-{name}"))
            .spawn(move || reader(name, &path, baud, idle_gap, &inbox, &stop, &s))
            .expect("spawn serial reader");
        let (s, q) = (shared.clone(), out.clone());
        let writer = thread::Builder::new()
            .name(format!("serial-{name}-tx"))
            .spawn(move || writer(name, &q, &s))
            .expect("spawn serial writer");
        Ok(Self {
            name,
            out,
            shared,
            writer: Some(writer),
        })
    }

    /// Queues one frame for the port; never blocks. Returns `false` if it was dropped (the
    /// queue is full of frames that matter more, or the link is stopped). A full queue drops
    /// its oldest periodic frame first, commands and mission traffic last.
    pub fn write(&self, bytes: &[u8]) -> bool {
        self.shared
            .offered
            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
        let lane = match Frame::new_checked(bytes).map(|f| Class::of(f.message_id())) {
            Ok(class) if class.is_protocol() => Lane::Priority,
            _ => Lane::Bulk,
        };
        self.out.push(bytes.to_vec(), bytes.len(), lane)
    }

    /// Whether the port is open and not waiting to be reopened: frames handed over now can
    /// reach it. While it is not, callers keep their frames (a frame renumbered for the
    /// radio and then dropped here would read as radio loss at the far end).
    pub fn is_open(&self) -> bool {
        self.shared.open.load(Ordering::Relaxed) && !self.shared.broken.load(Ordering::Relaxed)
    }

    /// The counters now (never blocks). While the writer runs, the frame it is writing is
    /// in none of `written`, `dropped` and `queued`; after [`stop`](Self::stop) they add up.
    pub fn counters(&self) -> SerialCounters {
        let s = &self.shared;
        let q = self.out.stats();
        SerialCounters {
            opens: s.opens.load(Ordering::Relaxed),
            write_failures: s.write_failures.load(Ordering::Relaxed),
            offered_bytes: s.offered.load(Ordering::Relaxed),
            written_bytes: s.written.load(Ordering::Relaxed),
            dropped_bytes: s.dropped.load(Ordering::Relaxed) + q.dropped_bytes,
            queued_bytes: self.out.bytes() as u64,
            refused_opens: s.refused_opens.load(Ordering::Relaxed),
        }
    }

    /// Stops the writer: what is still queued is counted as dropped. The counters are final
    /// afterwards.
    pub fn stop(&mut self) {
        self.out.close(true);
        self.shared.wake.wake();
        if let Some(w) = self.writer.take()
            && w.join().is_err()
        {
            warn!(port = self.name, "serial writer panicked");
        }
    }
}

impl Drop for SerialLink {
    fn drop(&mut self) {
        self.out.close(true);
        self.shared.wake.wake();
    }
}

/// The idle gap of a port: twice the time the longest MAVLink frame (280 bytes) takes at
/// `bytes_per_s`, and at least 100 ms (USB adapters and the OS deliver bytes in bursts).
pub fn frame_gap(bytes_per_s: u32) -> Duration {
    let frame = Duration::from_secs_f64(2.0 * 280.0 / f64::from(bytes_per_s.max(1)));
    frame.max(Duration::from_millis(100))
}

fn writer(name: &'static str, out: &Queue<Vec<u8>>, s: &Shared) {
    while let Ok(frame) = out.pop_until(None) {
        let mut guard = s.port.lock().unwrap_or_else(|e| e.into_inner());
        let Some(port) = guard.as_mut() else {
            s.dropped.fetch_add(frame.len() as u64, Ordering::Relaxed);
            continue;
        };
        let mut done = 0;
        while done < frame.len() {
            match port.write(&frame[done..]) {
                Ok(0) => {
                    fail(name, s, &mut guard, &ErrorKind::WriteZero.into());
                    break;
                }
                Ok(n) => {
                    done += n;
                    s.written.fetch_add(n as u64, Ordering::Relaxed);
                    s.wrote.store(true, Ordering::Relaxed);
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => {
                    fail(name, s, &mut guard, &e);
                    break;
                }
            }
        }
        s.dropped
            .fetch_add((frame.len() - done) as u64, Ordering::Relaxed);
    }
}

/// A write failed or stalled: drop the writer's handle and have the reader reopen the port.
fn fail(
    name: &'static str,
    s: &Shared,
    port: &mut Option<Box<dyn SerialPort>>,
    e: &std::io::Error,
) {
    let n = s.write_failures.fetch_add(1, Ordering::Relaxed) + 1;
    // One line per failure: failures are at least one backoff apart.
    warn!(port = name, error = %e, failures = n, "write failed or stalled, reopening the port");
    s.stalled
        .store(e.kind() == ErrorKind::TimedOut, Ordering::Relaxed);
    *port = None;
    s.broken.store(true, Ordering::Relaxed);
    s.wake.wake();
}

fn reader(
    name: &'static str,
    port_name: &PortName,
    baud: u32,
    idle_gap: Duration,
    inbox: &Inbox,
    stop: &AtomicBool,
    s: &Shared,
) {
    let mut backoff = BACKOFF_MIN;
    let mut open_failures = 0u64;
    // Set at the first open: which device a reopen may attach to.
    let mut rule: Option<Reopen> = None;
    // The port last closed because its device went away (not a write stall).
    let mut vanished = false;
    while !stop.load(Ordering::Relaxed) {
        let checked = port_name.resolve().and_then(|path| {
            match &rule {
                Some(rule) => rule.check(&path, vanished),
                None => Ok(()),
            }
            .map(|()| path)
        });
        let path = match checked {
            Ok(path) => path,
            Err(e) => {
                refused(name, port_name, &e, s);
                open_failures += 1;
                thread::sleep(backoff);
                backoff = (backoff * 2).min(BACKOFF_MAX_OPEN);
                continue;
            }
        };
        let path = path.to_string_lossy();
        let path = path.as_ref();
        // Native: its descriptor is what the reader polls (see `read_until_failure`).
        let mut port = match serialport::new(path, baud).timeout(idle_gap).open_native() {
            Ok(port) => port,
            Err(e) => {
                open_failures += 1;
                // First failure and then every 10th: a missing device must not fill the log.
                if open_failures == 1 || open_failures.is_multiple_of(10) {
                    warn!(port = name, path, error = %e, retry_in = ?backoff, failures = open_failures, "cannot open serial port");
                }
                thread::sleep(backoff);
                backoff = (backoff * 2).min(BACKOFF_MAX_OPEN);
                continue;
            }
        };
        open_failures = 0;
        if rule.is_none() {
            rule = Identity::of(std::path::Path::new(path))
                .ok()
                .map(|first| Reopen::after_first_open(port_name, first));
        }
        let mut writer = match port.try_clone_native() {
            Ok(clone) => clone,
            Err(e) => {
                warn!(port = name, error = %e, "cannot clone port for writing");
                thread::sleep(backoff);
                continue;
            }
        };
        if let Err(e) = writer.set_timeout(WRITE_STALL) {
            warn!(port = name, error = %e, "cannot set write timeout");
        }
        s.broken.store(false, Ordering::Relaxed);
        s.wrote.store(false, Ordering::Relaxed);
        s.stalled.store(false, Ordering::Relaxed);
        *s.port.lock().unwrap_or_else(|e| e.into_inner()) = Some(Box::new(writer));
        s.open.store(true, Ordering::Relaxed);
        s.opens.fetch_add(1, Ordering::Relaxed);
        info!(port = name, path, baud, "serial port open");
        inbox.send(Event::Serial(name, SerialEvent::Opened));
        let stalled = read_until_failure(name, &mut port, idle_gap, inbox, stop, s);
        vanished = !(stalled && s.stalled.load(Ordering::Relaxed));
        s.open.store(false, Ordering::Relaxed);
        *s.port.lock().unwrap_or_else(|e| e.into_inner()) = None;
        drop(port);
        if stop.load(Ordering::Relaxed) {
            return;
        }
        inbox.send(Event::Serial(name, SerialEvent::Closed));
        // A stall that no write got through since the last open doubles the wait; anything
        // else (a vanished device, a stall after good writes) starts again from the minimum.
        backoff = if stalled && !s.wrote.load(Ordering::Relaxed) {
            (backoff * 2).min(BACKOFF_MAX_STALL)
        } else {
            BACKOFF_MIN
        };
        thread::sleep(backoff);
    }
}

/// An open refused because the name leads elsewhere (or nowhere, for `usb-serial:`): counted,
/// logged at the first refusal and every 10th.
fn refused(name: &'static str, port_name: &PortName, e: &DeviceError, s: &Shared) {
    let n = s.refused_opens.fetch_add(1, Ordering::Relaxed) + 1;
    if n == 1 || n.is_multiple_of(10) {
        match e {
            DeviceError::Different { .. } | DeviceError::PtyGone { .. } => {
                error!(port = name, name = %port_name, refused = n, "{e}");
            }
            _ => warn!(port = name, name = %port_name, refused = n, "cannot open serial port: {e}"),
        }
    }
}

/// Reads until the port fails, the writer reports a failure (returns `true`) or `stop`.
/// Between bytes it waits on the port with no timeout, except for the idle gap after bytes
/// (see [`SerialEvent::Idle`]): an idle link costs no wake-ups.
fn read_until_failure(
    name: &'static str,
    port: &mut TTYPort,
    idle_gap: Duration,
    inbox: &Inbox,
    stop: &AtomicBool,
    s: &Shared,
) -> bool {
    use std::os::fd::{AsRawFd, BorrowedFd};
    // A pty or a USB adapter hands over up to 4 KB at once: one event for all of it.
    let mut buf = [0u8; 4096];
    let mut since_bytes = false;
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        if s.broken.load(Ordering::Relaxed) {
            return true;
        }
        // Read no further ahead of the main loop than the inbox allows; a port that is not
        // read is a port that must be checked for a writer failure or a stop.
        if !inbox.wait_room(std::time::Instant::now() + Duration::from_millis(100)) {
            continue;
        }
        // serialport's TTYPort has no `AsFd`, only `AsRawFd`.
        // SAFETY: the descriptor belongs to `port`, which outlives this borrow.
        #[allow(unsafe_code)]
        let fd = unsafe { BorrowedFd::borrow_raw(port.as_raw_fd()) };
        match s.wake.wait_readable(fd, since_bytes.then_some(idle_gap)) {
            Ok(Ready::Port) => {}
            Ok(Ready::Woken) => continue,
            Ok(Ready::Timeout) => {
                since_bytes = false;
                inbox.send(Event::Serial(name, SerialEvent::Idle));
                continue;
            }
            Err(e) => {
                warn!(port = name, error = %e, "waiting on serial port failed");
                return false;
            }
        }
        match port.read(&mut buf) {
            Ok(0) => {
                warn!(port = name, "end of file on serial port");
                return false;
            }
            Ok(n) => {
                since_bytes = true;
                inbox.send(Event::Serial(name, SerialEvent::Bytes(buf[..n].to_vec())));
            }
            // Readable but nothing to read: the idle gap restarts at the next wait.
            Err(e) if e.kind() == ErrorKind::TimedOut => {}
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => {
                warn!(port = name, error = %e, "serial port failed");
                return false;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_gap_follows_the_byte_rate_with_a_floor() {
        assert_eq!(frame_gap(92_160), Duration::from_millis(100));
        // A LoRa SF7 budget: a 280-byte frame takes 410 ms.
        let lora = frame_gap(683);
        assert!(lora > Duration::from_millis(800) && lora < Duration::from_millis(830));
    }
}
