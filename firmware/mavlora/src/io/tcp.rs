//! The ground-station endpoint over TCP (QGroundControl's and MAVProxy's `tcp:` links, and
//! scripts): the router listens, every connected client gets every frame for the ground and
//! may send its own.
//!
//! Each client has its own [`FrameReader`], so a frame split across TCP segments is put back
//! together before the router sees it and bytes of two clients (or of UDP) never interleave
//! inside the router's reader: only whole frames cross into the main loop.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use tracing::{info, warn};

use super::Event;
use crate::wire::FrameReader;

/// How long a write to one client may block before that client is dropped: a stalled ground
/// station must not stall the radio side.
const WRITE_TIMEOUT: Duration = Duration::from_millis(200);

/// TCP listener towards ground stations.
#[derive(Debug)]
pub struct TcpEndpoint {
    local: SocketAddr,
    clients: Arc<Mutex<Vec<(SocketAddr, TcpStream)>>>,
}

impl TcpEndpoint {
    /// Listens on `bind` and starts the accept thread; each client gets a reader thread that
    /// sends [`Event::Tcp`] with one whole frame each.
    pub fn spawn(
        bind: SocketAddr,
        tx: Sender<Event>,
        stop: Arc<AtomicBool>,
    ) -> anyhow::Result<Self> {
        let listener = TcpListener::bind(bind)
            .map_err(|e| anyhow::anyhow!("cannot listen on TCP {bind}: {e}"))?;
        // Non-blocking accept, so the thread sees `stop` without a connection arriving.
        listener.set_nonblocking(true)?;
        let local = listener.local_addr()?;
        info!(%local, "TCP endpoint listening");
        let clients: Arc<Mutex<Vec<(SocketAddr, TcpStream)>>> = Arc::default();
        let accepted = clients.clone();
        thread::Builder::new()
            .name("tcp-accept".into())
            .spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    match listener.accept() {
                        Ok((stream, from)) => {
                            if let Err(e) = add_client(stream, from, &accepted, &tx, &stop) {
                                warn!(%from, error = %e, "TCP client refused");
                            }
                        }
                        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                            thread::sleep(Duration::from_millis(50));
                        }
                        Err(e) => {
                            warn!(error = %e, "TCP accept failed");
                            thread::sleep(Duration::from_millis(200));
                        }
                    }
                }
            })?;
        Ok(Self { local, clients })
    }

    /// The address listened on (useful when bound to port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// Connected clients now.
    pub fn clients(&self) -> usize {
        self.clients.lock().map_or(0, |c| c.len())
    }

    /// Sends one frame to every client; a client whose write fails or times out is dropped.
    pub fn send(&self, bytes: &[u8]) {
        let Ok(mut clients) = self.clients.lock() else {
            return;
        };
        clients.retain_mut(|(addr, stream)| match stream.write_all(bytes) {
            Ok(()) => true,
            Err(e) => {
                warn!(client = %addr, error = %e, "TCP client dropped");
                let _ = stream.shutdown(std::net::Shutdown::Both);
                false
            }
        });
    }
}

fn add_client(
    stream: TcpStream,
    from: SocketAddr,
    clients: &Arc<Mutex<Vec<(SocketAddr, TcpStream)>>>,
    tx: &Sender<Event>,
    stop: &Arc<AtomicBool>,
) -> std::io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_nodelay(true)?;
    stream.set_write_timeout(Some(WRITE_TIMEOUT))?;
    let mut reader = stream.try_clone()?;
    reader.set_read_timeout(Some(Duration::from_millis(100)))?;
    info!(client = %from, "TCP ground station connected");
    clients
        .lock()
        .map_err(|_| std::io::Error::other("client list poisoned"))?
        .push((from, stream));
    let (tx, stop, clients) = (tx.clone(), stop.clone(), clients.clone());
    thread::Builder::new()
        .name(format!("tcp-{from}"))
        .spawn(move || {
            let mut frames = FrameReader::new();
            let mut buf = [0u8; 4096];
            while !stop.load(Ordering::Relaxed) {
                match reader.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => {
                        frames.push(&buf[..n]);
                        while let Some(rx) = frames.next_frame() {
                            let bytes = rx.frame.as_bytes().to_vec();
                            if tx.send(Event::Tcp(bytes, from)).is_err() {
                                return;
                            }
                        }
                    }
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                        ) => {}
                    Err(e) => {
                        warn!(client = %from, error = %e, "TCP read failed");
                        break;
                    }
                }
            }
            info!(client = %from, "TCP ground station disconnected");
            if let Ok(mut c) = clients.lock() {
                c.retain(|(addr, _)| *addr != from);
            }
        })?;
    Ok(())
}
