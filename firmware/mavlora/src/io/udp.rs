//! The ground-station endpoint: a UDP socket that sends to a configured address until a
//! ground station talks to it, then to every sender the router's ground policy accepted, up
//! to [`MAX_UDP_PEERS`] (MAVProxy's `udpin` behaviour seen from the other side, minus
//! strangers: the caller calls [`UdpEndpoint::learn`] only when
//! [`GroundInput::learn_peer`](crate::router::GroundInput) says so). Several stations on one
//! machine (QGroundControl and a MAVProxy, a script beside them) each get every frame; the
//! longest silent one gives its place to a new one when all are taken.
//!
//! Each peer gets frames in the MAVLink version it last spoke: MAVLink 2 as the engine makes
//! them, or its own MAVLink 1 copy (a frame MAVLink 1 cannot carry, an id above 255, is
//! dropped for that peer only and counted). One station speaking MAVLink 1 used to turn every
//! station's frames into MAVLink 1.
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

use mavlink::MavlinkVersion;
use tracing::{info, warn};

use super::framing::{DatagramFramer, FramingCounters};
use super::{Event, Inbox};

/// The largest datagram frames are packed into: what an Ethernet frame carries without IP
/// fragmentation (1500 - 20 - 8). A frame longer than this still goes alone.
pub const MAX_DATAGRAM: usize = 1472;

/// Ground stations sent to at once, at most.
pub const MAX_UDP_PEERS: usize = 8;

#[derive(Debug)]
struct Peer {
    addr: SocketAddr,
    version: MavlinkVersion,
    /// When it last sent a frame the ground policy accepted.
    heard: std::time::Instant,
}

/// UDP endpoint towards ground stations.
#[derive(Debug)]
pub struct UdpEndpoint {
    socket: UdpSocket,
    /// Sent to until a station is learned.
    configured: SocketAddr,
    peers: Vec<Peer>,
    framing: Arc<FramingCounters>,
    stop: Arc<AtomicBool>,
    /// Frames waiting for [`flush`](Self::flush), back to back: as made, and as MAVLink 1.
    pending: Vec<u8>,
    pending_v1: Vec<u8>,
    /// Bytes packed into one datagram at most; 0: one frame per datagram.
    pack: usize,
    datagrams: u64,
    not_v1: u64,
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
            configured: peer,
            peers: Vec::new(),
            framing,
            stop,
            pending: Vec::with_capacity(MAX_DATAGRAM),
            pending_v1: Vec::new(),
            pack: MAX_DATAGRAM,
            datagrams: 0,
            not_v1: 0,
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

    /// An accepted ground station sent a frame in `version` from `from`: it gets every frame
    /// from now on, in that version.
    pub fn learn(&mut self, from: SocketAddr, version: MavlinkVersion) {
        let now = std::time::Instant::now();
        if let Some(p) = self.peers.iter_mut().find(|p| p.addr == from) {
            if p.version != version {
                info!(%from, ?version, "ground station changed MAVLink version");
            }
            (p.version, p.heard) = (version, now);
            return;
        }
        if self.peers.len() == MAX_UDP_PEERS
            && let Some(oldest) = (0..self.peers.len()).min_by_key(|&i| self.peers[i].heard)
        {
            let gone = self.peers.swap_remove(oldest);
            info!(from = %gone.addr, "ground station dropped: the longest silent of {MAX_UDP_PEERS}");
        }
        info!(%from, ?version, "ground station address learned");
        self.peers.push(Peer {
            addr: from,
            version,
            heard: now,
        });
    }

    /// Frames not sent to a MAVLink 1 station because MAVLink 1 cannot carry them (ids
    /// above 255), counted once per frame.
    pub fn not_v1(&self) -> u64 {
        self.not_v1
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
        let v1 = self.peers.iter().any(|p| p.version == MavlinkVersion::V1);
        let v1_frame = if v1 {
            let converted = super::ground_version::as_v1(frame);
            if converted.is_none() {
                self.not_v1 += 1;
            }
            converted
        } else {
            None
        };
        let longer = frame.len().max(v1_frame.as_ref().map_or(0, Vec::len));
        let full = |pending: &Vec<u8>| !pending.is_empty() && pending.len() + longer > self.pack;
        if full(&self.pending) || full(&self.pending_v1) {
            self.flush();
        }
        self.pending.extend_from_slice(frame);
        if let Some(f) = v1_frame {
            self.pending_v1.extend_from_slice(&f);
        }
    }

    /// Sends what is queued to every peer in its version (errors such as "nobody
    /// listening" are not fatal).
    pub fn flush(&mut self) {
        let (pending, pending_v1) = (
            std::mem::take(&mut self.pending),
            std::mem::take(&mut self.pending_v1),
        );
        if self.peers.is_empty() {
            self.send_to(&pending, self.configured);
        }
        for i in 0..self.peers.len() {
            let (addr, version) = (self.peers[i].addr, self.peers[i].version);
            match version {
                MavlinkVersion::V1 => self.send_to(&pending_v1, addr),
                MavlinkVersion::V2 => self.send_to(&pending, addr),
            }
        }
        self.pending = pending;
        self.pending.clear();
        self.pending_v1 = pending_v1;
        self.pending_v1.clear();
    }

    /// Sends one frame to `to` alone, at once (a refused station told why: not a peer).
    pub fn send_one(&mut self, frame: &[u8], to: SocketAddr) {
        self.send_to(frame, to);
    }

    fn send_to(&mut self, datagram: &[u8], to: SocketAddr) {
        if datagram.is_empty() {
            return;
        }
        self.datagrams += 1;
        if let Err(e) = self.socket.send_to(datagram, to) {
            tracing::debug!(error = %e, peer = %to, "UDP send failed");
        }
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
