//! The IO driver of the two binaries (feature `cli`): serial ports that reopen, a UDP
//! endpoint that learns its peer, a TCP listener for ground stations, a `.tlog` writer, the
//! wall clock, the status lines (log and JSON, [`StatusReport`]). The engines never see any of
//! it: this module turns IO into `handle_*_bytes(now, bytes)` calls. What both binaries do
//! alike is here once: their options ([`RadioOptions`], [`main`]), start-up ([`Setup`]), main
//! loop ([`Station`]) and the radio link's status ([`RadioCounters`]).

mod clock;
mod framing;
mod ground_version;
mod options;
mod queue;
mod serial;
mod signing_state;
mod station;
mod status;
mod tcp;
mod tlog;
mod udp;
mod wake;

pub use clock::{Clock, signing_epoch_now};
pub use framing::{DatagramFramer, FramingCounters};
pub use options::{
    Decibels, DecibelsError, Percent, PercentError, Program, RadioOptions, RadioSigning, Seconds,
    SecondsError, UsageError, main,
};
pub use queue::{Lane, Order, PopError, Queue, QueueStats};
pub use serial::{SerialCounters, SerialEvent, SerialLink, frame_gap};
pub use signing_state::{SAVE_EVERY, SigningStateFile};
pub use station::{RadioEngine, Setup, Side, Station};
pub use status::{Joined, RadioCounters, RadioGauges, RadioStats, Status, StatusReport};
pub use tcp::{DEFAULT_MAX_CLIENTS, TcpCounters, TcpEndpoint};
pub use tlog::Tlog;
pub use udp::{MAX_DATAGRAM, MAX_UDP_PEERS, UdpEndpoint};

/// What the IO threads tell the main loop.
#[derive(Debug)]
pub enum Event {
    /// Bytes from a serial port (by link name).
    Serial(&'static str, SerialEvent),
    /// One whole frame from a UDP ground station (a datagram's partial frame never comes).
    Udp(Vec<u8>, std::net::SocketAddr),
    /// One whole frame from a TCP ground station.
    Tcp(Vec<u8>, std::net::SocketAddr),
    /// SIGINT or SIGTERM.
    Stop,
}

/// Bytes the main loop's [`Inbox`] holds at most, counted as memory ([`event_cost`]): 512 KB,
/// 2,500 small frames, a 64 KB datagram's 1,600 frames and more; serial ports stop at
/// [`READ_AHEAD`]. What fills it is a flood from the ground, which it drops; its size is most
/// of what a flood adds to either program's RSS, which must stay within 8 MB (the project's
/// target; `tests/cli_flood.rs`).
pub const INBOX_BYTES: usize = 512 * 1024;
/// Bytes a serial reader may have in the [`Inbox`] before it waits for the main loop (64 KB:
/// 16 reads of a pty, 0.7 s of a 921600-baud autopilot).
pub const READ_AHEAD: usize = 64 * 1024;

/// What an event with `payload` bytes costs the process while it waits in the [`Inbox`]: its
/// queue slot ([`Queue::SLOT_BYTES`]) and the payload's own allocation. Counting the payload
/// plus 64 bytes held a flood's 40-byte frames at 2.4 MB of RSS in a "1 MB" inbox: 1.3 MB
/// of slots (16,384 of 80 bytes), the rest allocations.
fn event_cost(payload: usize) -> usize {
    Queue::<Event>::SLOT_BYTES + allocation_bytes(payload)
}

/// What a heap allocation of `len` bytes takes from the allocator (glibc: 8 bytes of header,
/// rounded up to 16, at least 32): a queue of small frames that counts only their length
/// holds 2-3 times its bound.
pub(crate) fn allocation_bytes(len: usize) -> usize {
    (len + 8).next_multiple_of(16).max(32)
}

/// The main loop's bounded event queue: IO threads [`send`](Self::send) without blocking; a
/// full inbox drops the oldest ground telemetry frames first and ground commands last, and
/// hands ground commands to the loop first (see [`Queue`]). Serial bytes, port and stop
/// events are never dropped: serial bytes have a lane of their own, bounded by their reader
/// waiting ([`wait_room`](Self::wait_room)), so a ground station flooding the inbox can
/// neither drop the vehicle's bytes nor stop the radio from being read.
#[derive(Debug, Clone)]
pub struct Inbox(std::sync::Arc<Queue<Event>>);

impl Inbox {
    /// An inbox of `capacity` bytes.
    pub fn new(capacity: usize) -> Self {
        Self(std::sync::Arc::new(Queue::new(capacity)))
    }

    /// Queues an event; `false` if it was dropped.
    pub fn send(&self, event: Event) -> bool {
        use crate::schedule::Class;
        let (bytes, lane) = match &event {
            // Its reader waits for room in this lane alone: never dropped, never behind a flood.
            Event::Serial(_, SerialEvent::Bytes(b)) => (b.len(), Lane::Keep),
            Event::Udp(f, _) | Event::Tcp(f, _) => {
                let lane = match crate::wire::Frame::new_checked(f.as_slice()) {
                    Ok(f) if Class::of(f.message_id()).is_protocol() => Lane::Priority,
                    _ => Lane::Bulk,
                };
                (f.len(), lane)
            }
            Event::Serial(..) | Event::Stop => (0, Lane::Keep),
        };
        self.0.push_sized(event, bytes, event_cost(bytes), lane)
    }

    /// Waits until the inbox holds at most [`READ_AHEAD`] bytes of serial data, at most until
    /// `deadline`: a serial port is read no further ahead of the main loop (what is not read
    /// waits in the kernel and the device, and the process's memory stays small whatever the
    /// rate). Ground frames do not count: a flood of them once kept the inbox above
    /// [`READ_AHEAD`] for as long as it lasted, and the radio went unread.
    pub fn wait_room(&self, deadline: std::time::Instant) -> bool {
        self.0.wait_room_in(Lane::Keep, READ_AHEAD, deadline)
    }

    /// The next event, waiting at most `timeout`.
    pub fn recv_timeout(&self, timeout: std::time::Duration) -> Result<Event, PopError> {
        self.0.pop_until(Some(std::time::Instant::now() + timeout))
    }

    /// What the inbox has dropped.
    pub fn stats(&self) -> QueueStats {
        self.0.stats()
    }
}

/// Installs the SIGINT/SIGTERM handler: it sends [`Event::Stop`] to the main loop.
pub fn on_signal(inbox: Inbox) -> anyhow::Result<()> {
    ctrlc::set_handler(move || {
        inbox.send(Event::Stop);
    })?;
    Ok(())
}

/// A binary's `main`: logging set up, then `run`; an error is logged and exits with the
/// status [`exit_code`] gives it (clap has already exited with 2 on bad flags).
pub fn run_main(run: impl FnOnce() -> anyhow::Result<()>) -> std::process::ExitCode {
    hostio::logging::init("info");
    let result = run();
    if let Err(e) = &result {
        tracing::error!("{e:#}");
    }
    std::process::ExitCode::from(exit_code(&result))
}

/// The exit status for a binary's result: 0, 2 for a usage error (a [`UsageError`]: an option
/// or config-file value; a [`ProfileError`](crate::filter::ProfileError): the profile), else 1.
pub fn exit_code(result: &anyhow::Result<()>) -> u8 {
    match result {
        Ok(()) => 0,
        Err(e)
            if e.chain()
                .any(|c| c.is::<UsageError>() || c.is::<crate::filter::ProfileError>()) =>
        {
            2
        }
        Err(_) => 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ground station flooding the router keeps its inbox full: the radio's reader must
    /// still get room at once, and none of the radio's bytes may be dropped for the flood.
    #[test]
    fn a_ground_flood_neither_drops_serial_bytes_nor_holds_their_reader_back() {
        let inbox = Inbox::new(INBOX_BYTES);
        let from: std::net::SocketAddr = "127.0.0.1:14550".parse().unwrap();
        let now = std::time::Instant::now;
        let (mut sent, mut got) = (Vec::new(), Vec::new());
        let take = |event: Event, got: &mut Vec<Vec<u8>>| {
            if let Event::Serial(_, SerialEvent::Bytes(b)) = event {
                got.push(b);
            }
        };
        for round in 0..200u32 {
            // Four times what the inbox holds, between two reads of the radio.
            for _ in 0..(4 * INBOX_BYTES / event_cost(40)) {
                inbox.send(Event::Udp(vec![0xfd; 40], from));
            }
            assert!(
                inbox.wait_room(now()),
                "round {round}: the radio's reader waited behind the flood"
            );
            let bytes = round.to_le_bytes().to_vec();
            sent.push(bytes.clone());
            assert!(inbox.send(Event::Serial("radio", SerialEvent::Bytes(bytes))));
            // The main loop takes a little, as it would under a flood.
            for _ in 0..100 {
                if let Ok(event) = inbox.recv_timeout(std::time::Duration::ZERO) {
                    take(event, &mut got);
                }
            }
        }
        while let Ok(event) = inbox.recv_timeout(std::time::Duration::ZERO) {
            take(event, &mut got);
        }
        assert_eq!(got, sent, "serial bytes lost or out of order");
        assert!(inbox.stats().dropped_items > 0, "the flood was not dropped");
    }
}
