//! The ground-station endpoint: a UDP socket that sends to a configured address until a
//! ground station talks to it, then to the last sender the router's ground policy accepted
//! (MAVProxy's `udpin` behaviour seen from the other side, minus strangers: the caller calls
//! [`UdpEndpoint::learn`] only when [`GroundInput::learn_peer`](crate::router::GroundInput)
//! says so).
//!
//! Frames ready at the same moment leave in one datagram of at most [`MAX_DATAGRAM`] bytes:
//! ground stations parse a UDP datagram as a byte stream (QGroundControl, MAVProxy and
//! pymavlink, MAVSDK, mavlink-router), and a datagram per frame cost a `sendto` per frame,
//! most of a forwarder's CPU. A peer that wants one frame per datagram gets it with
//! `--udp-one-frame-per-datagram`. Nothing waits to be packed: [`UdpEndpoint::flush`] is
//! called once the engine has nothing more to send now.

use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;

use tracing::{info, warn};

use super::framing::{DatagramFramer, FramingCounters};
use super::{Event, Inbox};

/// The largest datagram frames are packed into: what an Ethernet frame carries without IP
/// fragmentation (1500 - 20 - 8). A frame longer than this still goes alone.
pub const MAX_DATAGRAM: usize = 1472;

/// UDP endpoint towards ground stations.
#[derive(Debug)]
pub struct UdpEndpoint {
    socket: UdpSocket,
    peer: SocketAddr,
    framing: Arc<FramingCounters>,
    stop: Arc<AtomicBool>,
    /// Frames waiting for [`flush`](Self::flush), back to back.
    pending: Vec<u8>,
    /// Bytes packed into one datagram at most; 0: one frame per datagram.
    pack: usize,
    datagrams: u64,
}

impl UdpEndpoint {
    /// Binds `bind`, sends to `peer` until it learns another, and starts the reader thread,
    /// which sends one [`Event::Udp`] per whole frame (see [`super::framing`]).
    pub fn spawn(
        bind: SocketAddr,
        peer: SocketAddr,
        tx: Inbox,
        stop: Arc<AtomicBool>,
    ) -> anyhow::Result<Self> {
        let socket = UdpSocket::bind(bind)?;
        // The reader blocks with no timeout (no wake-ups on an idle link); `Drop` wakes it
        // with an empty datagram once `stop` is set.
        let reader = socket.try_clone()?;
        info!(local = %socket.local_addr()?, %peer, "UDP endpoint");
        let framing = Arc::new(FramingCounters::default());
        let counters = framing.clone();
        let stopped = stop.clone();
        thread::Builder::new().name("udp".into()).spawn(move || {
            let mut buf = [0u8; 65_536];
            let mut framer = DatagramFramer::default();
            while !stopped.load(Ordering::Relaxed) {
                match reader.recv_from(&mut buf) {
                    Ok((n, from)) => framer.frames(&buf[..n], &counters, |frame| {
                        tx.send(Event::Udp(frame, from));
                    }),
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                        ) => {}
                    // ICMP port unreachable from an earlier send: nobody listens yet.
                    Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
                    Err(e) => warn!(error = %e, "UDP receive failed"),
                }
            }
        })?;
        Ok(Self {
            socket,
            peer,
            framing,
            stop,
            pending: Vec::with_capacity(MAX_DATAGRAM),
            pack: MAX_DATAGRAM,
            datagrams: 0,
        })
    }

    /// What the reader thread's framing has seen.
    pub fn framing(&self) -> &FramingCounters {
        &self.framing
    }

    /// The local address (useful when bound to port 0).
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// An accepted ground station sent from `from`: replies go there from now on.
    pub fn learn(&mut self, from: SocketAddr) {
        if from != self.peer {
            info!(%from, "ground station address learned");
            self.peer = from;
        }
    }

    /// One frame per datagram from now on (for a peer that parses only the first frame of
    /// a datagram).
    pub fn one_frame_per_datagram(&mut self) {
        self.flush();
        self.pack = 0;
    }

    /// Datagrams sent so far.
    pub fn datagrams(&self) -> u64 {
        self.datagrams
    }

    /// Queues one frame; it leaves at the next [`flush`](Self::flush) at the latest, packed
    /// with the frames queued beside it.
    pub fn send(&mut self, frame: &[u8]) {
        if !self.pending.is_empty() && self.pending.len() + frame.len() > self.pack {
            self.flush();
        }
        self.pending.extend_from_slice(frame);
    }

    /// Sends what is queued (errors such as "nobody listening" are not fatal).
    pub fn flush(&mut self) {
        if self.pending.is_empty() {
            return;
        }
        self.datagrams += 1;
        if let Err(e) = self.socket.send_to(&self.pending, self.peer) {
            tracing::debug!(error = %e, peer = %self.peer, "UDP send failed");
        }
        self.pending.clear();
    }
}

impl Drop for UdpEndpoint {
    /// Stops the reader: sets the stop flag and wakes it with an empty datagram to itself.
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Ok(mut local) = self.socket.local_addr() {
            if local.ip().is_unspecified() {
                local.set_ip(match local {
                    SocketAddr::V4(_) => std::net::Ipv4Addr::LOCALHOST.into(),
                    SocketAddr::V6(_) => std::net::Ipv6Addr::LOCALHOST.into(),
                });
            }
            let _ = self.socket.send_to(&[], local);
        }
    }
}
