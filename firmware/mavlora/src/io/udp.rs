//! The ground-station endpoint: a UDP socket that sends to a configured address until a
//! ground station talks to it, then to the last sender the router's ground policy accepted
//! (MAVProxy's `udpin` behaviour seen from the other side, minus strangers: the caller calls
//! [`UdpEndpoint::learn`] only when [`GroundInput::learn_peer`](crate::router::GroundInput)
//! says so).

use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use tracing::{info, warn};

use super::framing::{DatagramFramer, FramingCounters};
use super::{Event, Inbox};

/// UDP endpoint towards ground stations.
#[derive(Debug)]
pub struct UdpEndpoint {
    socket: UdpSocket,
    peer: SocketAddr,
    framing: Arc<FramingCounters>,
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
        socket.set_read_timeout(Some(Duration::from_millis(100)))?;
        let reader = socket.try_clone()?;
        info!(local = %socket.local_addr()?, %peer, "UDP endpoint");
        let framing = Arc::new(FramingCounters::default());
        let counters = framing.clone();
        thread::Builder::new().name("udp".into()).spawn(move || {
            let mut buf = [0u8; 65_536];
            let mut framer = DatagramFramer::default();
            while !stop.load(Ordering::Relaxed) {
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

    /// Sends one frame as one datagram (errors such as "nobody listening" are not fatal).
    pub fn send(&self, bytes: &[u8]) {
        if let Err(e) = self.socket.send_to(bytes, self.peer) {
            tracing::debug!(error = %e, peer = %self.peer, "UDP send failed");
        }
    }
}
