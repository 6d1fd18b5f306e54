//! The flight-controller side of MultiRX: reads its SBUS output, stamps each
//! read, and keeps every frame for the scenarios to query.

use std::io::{self, Read};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Result, bail};
use serialport::TTYPort;

use crate::clock::Mono;
use crate::multirx::px4_rc_input::{FcFrame, SbusStream};

#[derive(Default)]
struct Frames {
    list: Mutex<Vec<FcFrame>>,
    changed: Condvar,
}

/// Records everything the flight controller receives.
pub struct FcMonitor {
    frames: Arc<Frames>,
    stop: Arc<AtomicBool>,
    reader: Option<JoinHandle<u64>>,
}

impl FcMonitor {
    /// Starts reading `port` (a pty master, or the rig's own adapter on a bench).
    pub fn start(mut port: TTYPort) -> Result<FcMonitor> {
        use serialport::SerialPort;
        port.set_timeout(Duration::from_millis(100))?;
        let frames = Arc::new(Frames::default());
        let stop = Arc::new(AtomicBool::new(false));
        let (sink, flag) = (frames.clone(), stop.clone());
        let reader = std::thread::Builder::new()
            .name("fc-monitor".into())
            .spawn(move || {
                // Frame arrival times are what we measure: read promptly.
                hostio::realtime::request("fc-monitor");
                let mut stream = SbusStream::default();
                let mut buf = [0u8; 512];
                while !flag.load(Ordering::Relaxed) {
                    match port.read(&mut buf) {
                        Ok(n) if n > 0 => {
                            let got = stream.push(Mono::now(), &buf[..n]);
                            if !got.is_empty() {
                                sink.list.lock().unwrap().extend(got);
                                sink.changed.notify_all();
                            }
                        }
                        Ok(_) => {}
                        Err(e)
                            if matches!(
                                e.kind(),
                                io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                            ) => {}
                        Err(e) => {
                            tracing::debug!(error = %e, "flight-controller port closed");
                            break;
                        }
                    }
                }
                stream.skipped
            })?;
        Ok(FcMonitor {
            frames,
            stop,
            reader: Some(reader),
        })
    }

    /// Waits for the first frame at or after `since` that satisfies `pred`.
    pub fn wait_for(
        &self,
        since: Mono,
        timeout: Duration,
        what: &str,
        pred: impl Fn(&FcFrame) -> bool,
    ) -> Result<FcFrame> {
        let deadline = std::time::Instant::now() + timeout;
        let mut list = self.frames.list.lock().unwrap();
        let mut checked = 0;
        loop {
            let start = list.partition_point(|f| f.at < since).max(checked);
            if let Some(f) = list[start..].iter().find(|f| pred(f)) {
                return Ok(*f);
            }
            checked = list.len();
            let now = std::time::Instant::now();
            if now >= deadline {
                bail!(
                    "the flight controller did not see {what} within {timeout:?} ({} frames in all)",
                    list.len()
                );
            }
            list = self
                .frames
                .changed
                .wait_timeout(list, deadline - now)
                .unwrap()
                .0;
        }
    }

    /// A copy of every frame so far.
    pub fn frames(&self) -> Vec<FcFrame> {
        self.frames.list.lock().unwrap().clone()
    }

    /// Stops reading; returns bytes skipped as garbage.
    pub fn stop(&mut self) -> u64 {
        self.stop.store(true, Ordering::Relaxed);
        self.reader.take().and_then(|r| r.join().ok()).unwrap_or(0)
    }
}

impl Drop for FcMonitor {
    fn drop(&mut self) {
        self.stop();
    }
}
