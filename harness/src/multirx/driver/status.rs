//! MultiRX's status line: receiver power, link and control changes, and the
//! boot line. The rig honours power events by switching the emulated
//! receivers, keeps every event for the scenarios, and keeps the boot line
//! for the identity check ([`crate::multirx::boot_check`]).

use std::io::{self, Read};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::Result;
use multirx_core::{BootReport, Event, StatusLine, TimedEvent};
use serialport::TTYPort;

use crate::clock::Mono;

/// Called with (receiver, on) for each power event, on the reader thread.
pub type PowerHook = Box<dyn Fn(u8, bool) + Send>;

/// Reads status lines.
pub struct StatusMonitor {
    events: Arc<Mutex<Vec<(Mono, TimedEvent)>>>,
    boots: Arc<Mutex<Vec<(Mono, BootReport)>>>,
    stop: Arc<AtomicBool>,
    reader: Option<JoinHandle<()>>,
}

impl StatusMonitor {
    pub fn start(mut port: TTYPort, on_power: PowerHook) -> Result<StatusMonitor> {
        use serialport::SerialPort;
        port.set_timeout(Duration::from_millis(100))?;
        let events = Arc::new(Mutex::new(Vec::new()));
        let boots = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (sink, boot_sink, flag) = (events.clone(), boots.clone(), stop.clone());
        let reader = std::thread::Builder::new()
            .name("status-monitor".into())
            .spawn(move || {
                let mut line = Vec::new();
                let mut buf = [0u8; 256];
                while !flag.load(Ordering::Relaxed) {
                    let n = match port.read(&mut buf) {
                        Ok(n) => n,
                        Err(e)
                            if matches!(
                                e.kind(),
                                io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                            ) =>
                        {
                            continue;
                        }
                        Err(_) => break,
                    };
                    let at = Mono::now();
                    for &b in &buf[..n] {
                        if b != b'\n' {
                            line.push(b);
                            continue;
                        }
                        let text = String::from_utf8_lossy(&line).into_owned();
                        line.clear();
                        match StatusLine::parse(&text) {
                            Ok(StatusLine::Event(event)) => {
                                if let Event::Power { rx, on } = event.event {
                                    on_power(rx, on);
                                }
                                sink.lock().unwrap().push((at, event));
                            }
                            Ok(StatusLine::Boot(boot)) => {
                                tracing::info!(%boot, "MultiRX boot line");
                                boot_sink.lock().unwrap().push((at, boot));
                            }
                            Err(e) => tracing::warn!(line = text, error = %e, "status line"),
                        }
                    }
                }
            })?;
        Ok(StatusMonitor {
            events,
            boots,
            stop,
            reader: Some(reader),
        })
    }

    /// Every event so far, with when the rig read it.
    pub fn events(&self) -> Vec<(Mono, TimedEvent)> {
        self.events.lock().unwrap().clone()
    }

    /// The first boot line read, waiting up to `timeout` for one.
    pub fn wait_for_boot(&self, timeout: Duration) -> Option<BootReport> {
        let deadline = std::time::Instant::now() + timeout;
        loop {
            if let Some((_, boot)) = self.boots.lock().unwrap().first() {
                return Some(*boot);
            }
            if std::time::Instant::now() >= deadline {
                return None;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// The first boot line read after `after` that `wanted` accepts, waiting up to `timeout`
    /// for one (a device reset in the session boots again; the lines the device wrote before
    /// it may still be read just after).
    pub fn wait_for_boot_after(
        &self,
        after: Mono,
        timeout: Duration,
        wanted: impl Fn(&BootReport) -> bool,
    ) -> Option<BootReport> {
        let deadline = std::time::Instant::now() + timeout;
        loop {
            let boots = self.boots.lock().unwrap();
            if let Some((_, boot)) = boots.iter().find(|(at, b)| *at > after && wanted(b)) {
                return Some(*boot);
            }
            drop(boots);
            if std::time::Instant::now() >= deadline {
                return None;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
    }
}

impl Drop for StatusMonitor {
    fn drop(&mut self) {
        self.stop();
    }
}
