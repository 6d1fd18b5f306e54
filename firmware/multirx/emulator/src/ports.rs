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
    /// is silent from now on, which the engine treats as link loss.
    Closed { source: Source, error: String },
}

/// Opens `path` with SBUS settings ([`hostio::sbus::port`]).
pub fn open_sbus(path: &str, timeout: Duration) -> Result<TTYPort> {
    hostio::sbus::port(path)
        .timeout(timeout)
        .open_native()
        .with_context(|| format!("cannot open serial port {path}"))
}

/// Starts a thread forwarding everything read from `port` to `tx`.
pub fn spawn_reader(source: Source, mut port: TTYPort, tx: Sender<Input>) -> Result<()> {
    let name = format!("read-{source:?}");
    thread::Builder::new().name(name).spawn(move || {
        hostio::realtime::request("input");
        let mut buf = [0u8; 256];
        loop {
            match port.read(&mut buf) {
                Ok(0) => continue,
                Ok(n) => {
                    let input = Input::Bytes {
                        source,
                        at: Instant::now(),
                        bytes: buf[..n].to_vec(),
                    };
                    if tx.send(input).is_err() {
                        return; // engine gone
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::TimedOut => continue,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    let _ = tx.send(Input::Closed {
                        source,
                        error: e.to_string(),
                    });
                    return;
                }
            }
        }
    })?;
    Ok(())
}

/// An output that drops what it cannot write at once instead of blocking:
/// a flight controller that stops reading must not stop MultiRX.
pub struct Output {
    name: String,
    port: TTYPort,
    pub written: u64,
    pub dropped: u64,
    failing: bool,
}

impl Output {
    pub fn new(name: &str, port: TTYPort) -> Self {
        Output {
            name: name.to_string(),
            port,
            written: 0,
            dropped: 0,
            failing: false,
        }
    }

    /// Writes `bytes` whole or counts them dropped.
    pub fn send(&mut self, bytes: &[u8]) {
        match self.port.write_all(bytes) {
            Ok(()) => {
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
            }
        }
    }
}
