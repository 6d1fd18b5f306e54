//! The IO driver of the two binaries (feature `cli`): serial ports that reopen, a UDP
//! endpoint that learns its peer, a TCP listener for ground stations, a `.tlog` writer, the wall clock. The engines never see
//! any of it: this module turns IO into `handle_*_bytes(bytes, now)` calls.

mod clock;
mod options;
mod serial;
mod tcp;
mod tlog;
mod udp;

pub use clock::{Clock, signing_epoch_now, signing_from_key_file};
pub use options::{RadioOptions, Seconds, SecondsError, UsageError, main};
pub use serial::{SerialEvent, SerialLink};
pub use tcp::TcpEndpoint;
pub use tlog::Tlog;
pub use udp::UdpEndpoint;

/// What the IO threads tell the main loop.
#[derive(Debug)]
pub enum Event {
    /// Bytes from a serial port (by link name).
    Serial(&'static str, SerialEvent),
    /// A datagram from the ground-station side.
    Udp(Vec<u8>, std::net::SocketAddr),
    /// One whole frame from a TCP ground station.
    Tcp(Vec<u8>, std::net::SocketAddr),
    /// SIGINT or SIGTERM.
    Stop,
}

/// Installs the SIGINT/SIGTERM handler: it sends [`Event::Stop`] to the main loop.
pub fn on_signal(tx: std::sync::mpsc::Sender<Event>) -> anyhow::Result<()> {
    ctrlc::set_handler(move || {
        let _ = tx.send(Event::Stop);
    })?;
    Ok(())
}

/// A binary's `main`: logging set up, then `run`; an error is logged and exits with status 2
/// if it is a usage error (a [`UsageError`]: an option or config-file value; a
/// [`ProfileError`](crate::filter::ProfileError): the profile), else 1 (clap has already
/// exited with 2 on bad flags).
pub fn run_main(run: impl FnOnce() -> anyhow::Result<()>) -> std::process::ExitCode {
    hostio::logging::init("info");
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!("{e:#}");
            let usage = e
                .chain()
                .any(|c| c.is::<UsageError>() || c.is::<crate::filter::ProfileError>());
            std::process::ExitCode::from(if usage { 2 } else { 1 })
        }
    }
}
