//! The ground-station endpoint over TCP (QGroundControl's and MAVProxy's `tcp:` links, and
//! scripts): the router listens, every connected client gets every frame for the ground and
//! may send its own.
//!
//! Each client has its own [`FrameReader`], so a frame split across TCP segments is put back
//! together before the router sees it and bytes of two clients (or of UDP) never interleave
//! inside the router's reader: only whole frames cross into the main loop. A partial frame
//! followed by [`CLIENT_IDLE_GAP`] of silence is dropped, so frames behind it come out.
//!
//! Each client also has its own bounded write queue and writer thread: a client that stops
//! reading never blocks the main loop or the other clients; what does not fit its queue is
//! dropped and counted for that client. At most `max_clients` are connected; one more is
//! refused with a log line.

use std::io::{ErrorKind, Read, Write};
use std::net::{IpAddr, Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread;
use std::time::Duration;

use tracing::{info, warn};

use super::queue::{Lane, Queue};
use super::{Event, Inbox};
use crate::schedule::Class;
use crate::wire::{Frame, FrameReader};

/// Clients connected at once unless configured (`--tcp-max-clients`).
pub const DEFAULT_MAX_CLIENTS: usize = 8;
/// Bytes queued towards one client at most, counted as memory ([`frame_cost`]; 64 KB: ~500
/// frames, seconds of expanded telemetry).
pub const CLIENT_QUEUE_BYTES: usize = 64 * 1024;
/// Bytes the writer of one client gathers into one write at most.
const WRITE_BATCH_BYTES: usize = 16 * 1024;
/// A client's partial frame is dropped after this long without a byte from it.
pub const CLIENT_IDLE_GAP: Duration = Duration::from_secs(1);

/// What the TCP endpoint has done, summed over all clients so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TcpCounters {
    /// Clients connected now.
    pub clients: usize,
    /// Connections refused because `max_clients` were connected.
    pub refused: u64,
    /// Bytes for clients dropped because their queue was full (they do not read).
    pub dropped_bytes: u64,
    /// Partial frames from clients dropped after an idle gap.
    pub partials_dropped: u64,
    /// Frames not given to MAVLink 1 clients because MAVLink 1 cannot carry them (ids above
    /// 255), per client.
    pub not_v1: u64,
}

#[derive(Debug)]
struct Client {
    addr: SocketAddr,
    stream: TcpStream,
    out: Queue<Vec<u8>>,
    /// It spoke MAVLink 1 last: it gets its own MAVLink 1 copy of each frame.
    v1: AtomicBool,
}

#[derive(Debug, Default)]
struct Shared {
    clients: Mutex<Vec<Arc<Client>>>,
    refused: AtomicU64,
    /// Dropped bytes of clients gone (those connected count in their queue).
    gone_dropped: AtomicU64,
    partials_dropped: AtomicU64,
    /// Frames a MAVLink 1 client could not be given (per client).
    not_v1: AtomicU64,
}

impl Shared {
    fn clients(&self) -> MutexGuard<'_, Vec<Arc<Client>>> {
        self.clients.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn remove(&self, addr: SocketAddr) {
        let mut clients = self.clients();
        if let Some(i) = clients.iter().position(|c| c.addr == addr) {
            let c = clients.swap_remove(i);
            c.out.close(true);
            self.gone_dropped
                .fetch_add(c.out.stats().dropped_bytes, Ordering::Relaxed);
            let _ = c.stream.shutdown(Shutdown::Both);
        }
    }
}

/// TCP listener towards ground stations.
#[derive(Debug)]
pub struct TcpEndpoint {
    local: SocketAddr,
    shared: Arc<Shared>,
}

impl TcpEndpoint {
    /// Listens on `bind` and starts the accept thread; each client gets a reader thread that
    /// sends [`Event::Tcp`] with one whole frame each, and a writer thread. A connection from
    /// an address `admits` refuses is closed at once: it gets no telemetry and takes no
    /// client slot.
    pub fn spawn(
        bind: SocketAddr,
        max_clients: usize,
        admits: impl Fn(IpAddr) -> bool + Send + 'static,
        tx: Inbox,
        stop: Arc<AtomicBool>,
    ) -> anyhow::Result<Self> {
        let listener = TcpListener::bind(bind)
            .map_err(|e| anyhow::anyhow!("cannot listen on TCP {bind}: {e}"))?;
        let local = listener.local_addr()?;
        info!(%local, max_clients, "TCP endpoint listening");
        let shared = Arc::new(Shared::default());
        let accepted = shared.clone();
        // Blocking accept: no polling while nobody connects; the thread ends with the process.
        thread::Builder::new()
            .name("tcp-accept".into())
            .spawn(move || {
                for stream in listener.incoming() {
                    if stop.load(Ordering::Relaxed) {
                        return;
                    }
                    match stream {
                        Ok(stream) => accept(stream, max_clients, &admits, &accepted, &tx, &stop),
                        Err(e) => {
                            warn!(error = %e, "TCP accept failed");
                            thread::sleep(Duration::from_millis(200));
                        }
                    }
                }
            })?;
        Ok(Self { local, shared })
    }

    /// The address listened on (useful when bound to port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// Connected clients now.
    pub fn clients(&self) -> usize {
        self.shared.clients().len()
    }

    /// The counters now.
    pub fn counters(&self) -> TcpCounters {
        let clients = self.shared.clients();
        let queued: u64 = clients.iter().map(|c| c.out.stats().dropped_bytes).sum();
        TcpCounters {
            clients: clients.len(),
            refused: self.shared.refused.load(Ordering::Relaxed),
            dropped_bytes: queued + self.shared.gone_dropped.load(Ordering::Relaxed),
            partials_dropped: self.shared.partials_dropped.load(Ordering::Relaxed),
            not_v1: self.shared.not_v1.load(Ordering::Relaxed),
        }
    }

    /// The client at `from` sent a frame the ground policy accepted, in `version`: it gets
    /// frames in that version from now on.
    pub fn learn(&self, from: SocketAddr, version: mavlink::MavlinkVersion) {
        if let Some(c) = self.shared.clients().iter().find(|c| c.addr == from) {
            c.v1.store(version == mavlink::MavlinkVersion::V1, Ordering::Relaxed);
        }
    }

    /// Queues one frame for the client at `to` alone (a refused station told why).
    pub fn send_one(&self, bytes: &[u8], to: SocketAddr) {
        if let Some(c) = self.shared.clients().iter().find(|c| c.addr == to) {
            c.out.push_sized(
                bytes.to_vec(),
                bytes.len(),
                frame_cost(bytes.len()),
                Lane::Priority,
            );
        }
    }

    /// Queues one frame for every client, in the version each speaks; never blocks. A
    /// client whose queue is full loses its oldest periodic frames first (counted). A frame
    /// MAVLink 1 cannot carry is dropped for MAVLink 1 clients only (counted).
    pub fn send(&self, bytes: &[u8]) {
        let lane = match Frame::new_checked(bytes).map(|f| Class::of(f.message_id())) {
            Ok(class) if class.is_protocol() => Lane::Priority,
            _ => Lane::Bulk,
        };
        let mut v1: Option<Option<Vec<u8>>> = None;
        for c in self.shared.clients().iter() {
            if !c.v1.load(Ordering::Relaxed) {
                c.out
                    .push_sized(bytes.to_vec(), bytes.len(), frame_cost(bytes.len()), lane);
                continue;
            }
            match v1.get_or_insert_with(|| super::ground_version::as_v1(bytes)) {
                Some(f) => {
                    c.out
                        .push_sized(f.clone(), f.len(), frame_cost(f.len()), lane);
                }
                None => {
                    self.shared.not_v1.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    }
}

/// What a frame of `len` bytes costs while it waits in a client's queue: its slot and its
/// allocation. Counting its length alone let 8 clients that do not read hold 3 times their
/// 64 KB each in small telemetry frames.
fn frame_cost(len: usize) -> usize {
    Queue::<Vec<u8>>::SLOT_BYTES + super::allocation_bytes(len)
}

fn accept(
    stream: TcpStream,
    max_clients: usize,
    admits: &dyn Fn(IpAddr) -> bool,
    shared: &Arc<Shared>,
    tx: &Inbox,
    stop: &Arc<AtomicBool>,
) {
    let from = stream
        .peer_addr()
        .unwrap_or_else(|_| ([0, 0, 0, 0], 0).into());
    if !admits(from.ip()) {
        let n = shared.refused.fetch_add(1, Ordering::Relaxed) + 1;
        if n == 1 || n.is_multiple_of(100) {
            warn!(client = %from, refused = n, "TCP client refused: address not allowed");
        }
        let _ = stream.shutdown(Shutdown::Both);
        return;
    }
    let connected = shared.clients().len();
    if connected >= max_clients {
        let n = shared.refused.fetch_add(1, Ordering::Relaxed) + 1;
        // First refusal and then every 100th: a connection storm must not fill the log.
        if n == 1 || n.is_multiple_of(100) {
            warn!(client = %from, max_clients, refused = n, "TCP client refused: too many clients");
        }
        let _ = stream.shutdown(Shutdown::Both);
        return;
    }
    if let Err(e) = add_client(stream, from, shared, tx, stop) {
        warn!(client = %from, error = %e, "TCP client refused");
    }
}

fn add_client(
    stream: TcpStream,
    from: SocketAddr,
    shared: &Arc<Shared>,
    tx: &Inbox,
    stop: &Arc<AtomicBool>,
) -> std::io::Result<()> {
    stream.set_nodelay(true)?;
    let mut reader = stream.try_clone()?;
    reader.set_read_timeout(Some(CLIENT_IDLE_GAP))?;
    let mut writer = stream.try_clone()?;
    let client = Arc::new(Client {
        addr: from,
        stream,
        out: Queue::new(CLIENT_QUEUE_BYTES),
        v1: AtomicBool::new(false),
    });
    info!(client = %from, "TCP ground station connected");
    shared.clients().push(client.clone());

    let s = shared.clone();
    thread::Builder::new()
        .name(format!("tcp-tx-{from}"))
        .spawn(move || {
            let mut batch = Vec::new();
            while let Ok(frame) = client.out.pop_until(None) {
                // Everything queued by now in one write: frames ready together cost one
                // system call, as on UDP.
                batch.clear();
                batch.extend_from_slice(&frame);
                while batch.len() < WRITE_BATCH_BYTES
                    && let Ok(more) = client.out.pop_until(Some(std::time::Instant::now()))
                {
                    batch.extend_from_slice(&more);
                }
                if let Err(e) = writer.write_all(&batch) {
                    warn!(client = %from, error = %e, "TCP write failed");
                    s.remove(from);
                    return;
                }
            }
        })?;

    let (tx, stop, s) = (tx.clone(), stop.clone(), shared.clone());
    thread::Builder::new()
        .name(format!("tcp-rx-{from}"))
        .spawn(move || {
            let mut frames = FrameReader::new();
            let mut buf = [0u8; 4096];
            // The idle gap is timed only while a partial frame waits: an idle client costs
            // no wake-ups (a stop or a removal shuts the socket, which ends the read).
            let mut timed = true;
            while !stop.load(Ordering::Relaxed) {
                let partial = frames.buffered() > 0;
                if partial != timed {
                    timed = partial;
                    let _ = reader.set_read_timeout(partial.then_some(CLIENT_IDLE_GAP));
                }
                match reader.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => frames.push(&buf[..n]),
                    Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                        if frames.flush_partial() {
                            s.partials_dropped.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    Err(e) if e.kind() == ErrorKind::Interrupted => {}
                    Err(e) => {
                        warn!(client = %from, error = %e, "TCP read failed");
                        break;
                    }
                }
                while let Some(rx) = frames.next_frame() {
                    tx.send(Event::Tcp(rx.frame.into_inner(), from));
                }
            }
            info!(client = %from, "TCP ground station disconnected");
            s.remove(from);
        })?;
    Ok(())
}
