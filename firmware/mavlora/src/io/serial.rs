//! A serial port read by its own thread, reopened with backoff when it disappears (USB radios
//! re-enumerate; a pty whose other side closed reads EOF or EIO).

use std::io::{ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use serialport::SerialPort;
use tracing::{info, warn};

use super::Event;

/// What happened on a port.
#[derive(Debug)]
pub enum SerialEvent {
    /// The port is open (first time or again).
    Opened,
    /// Bytes read.
    Bytes(Vec<u8>),
    /// The port failed or vanished; the reader is trying to reopen it.
    Closed,
}

type Port = Arc<Mutex<Option<Box<dyn SerialPort>>>>;

/// One serial port with a reader thread.
#[derive(Debug)]
pub struct SerialLink {
    name: &'static str,
    writer: Port,
    /// Bytes dropped because the port was closed when they were to be written.
    pub dropped_bytes: u64,
    /// Times the port was (re)opened.
    pub opens: Arc<std::sync::atomic::AtomicU64>,
}

impl SerialLink {
    /// Starts the reader thread for `path` at `baud`; events go to `tx`.
    pub fn spawn(
        name: &'static str,
        path: String,
        baud: u32,
        tx: Sender<Event>,
        stop: Arc<AtomicBool>,
    ) -> Self {
        let writer: Port = Arc::new(Mutex::new(None));
        let opens = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let (w, o) = (writer.clone(), opens.clone());
        thread::Builder::new()
            .name(format!("serial-{name}"))
            .spawn(move || reader(name, &path, baud, &tx, &stop, &w, &o))
            .expect("spawn serial reader");
        Self {
            name,
            writer,
            dropped_bytes: 0,
            opens,
        }
    }

    /// Writes a frame; returns `false` (and counts it) if the port is not open.
    pub fn write(&mut self, bytes: &[u8]) -> bool {
        let mut guard = self.writer.lock().unwrap_or_else(|e| e.into_inner());
        let Some(port) = guard.as_mut() else {
            self.dropped_bytes += bytes.len() as u64;
            return false;
        };
        if let Err(e) = port.write_all(bytes) {
            warn!(port = self.name, error = %e, "write failed, waiting for reopen");
            *guard = None;
            self.dropped_bytes += bytes.len() as u64;
            return false;
        }
        true
    }
}

fn reader(
    name: &'static str,
    path: &str,
    baud: u32,
    tx: &Sender<Event>,
    stop: &AtomicBool,
    writer: &Port,
    opens: &std::sync::atomic::AtomicU64,
) {
    let mut backoff = Duration::from_millis(100);
    while !stop.load(Ordering::Relaxed) {
        let mut port = match serialport::new(path, baud)
            .timeout(Duration::from_millis(50))
            .open()
        {
            Ok(port) => port,
            Err(e) => {
                warn!(port = name, path, error = %e, retry_in = ?backoff, "cannot open serial port");
                thread::sleep(backoff);
                backoff = (backoff * 2).min(Duration::from_secs(5));
                continue;
            }
        };
        backoff = Duration::from_millis(100);
        match port.try_clone() {
            Ok(clone) => *writer.lock().unwrap_or_else(|e| e.into_inner()) = Some(clone),
            Err(e) => {
                warn!(port = name, error = %e, "cannot clone port for writing");
                thread::sleep(backoff);
                continue;
            }
        }
        opens.fetch_add(1, Ordering::Relaxed);
        info!(port = name, path, baud, "serial port open");
        if tx.send(Event::Serial(name, SerialEvent::Opened)).is_err() {
            return;
        }
        let mut buf = [0u8; 1024];
        loop {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            match port.read(&mut buf) {
                Ok(0) => {
                    warn!(port = name, "end of file on serial port");
                    break;
                }
                Ok(n) => {
                    if tx
                        .send(Event::Serial(name, SerialEvent::Bytes(buf[..n].to_vec())))
                        .is_err()
                    {
                        return;
                    }
                }
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::Interrupted) => {}
                Err(e) => {
                    warn!(port = name, error = %e, "serial port failed");
                    break;
                }
            }
        }
        *writer.lock().unwrap_or_else(|e| e.into_inner()) = None;
        if tx.send(Event::Serial(name, SerialEvent::Closed)).is_err() {
            return;
        }
        // A pty or a USB device that just vanished: give it a moment before reopening.
        thread::sleep(backoff);
    }
}
