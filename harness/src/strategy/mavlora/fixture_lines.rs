//! A fixture's stdout read as JSON lines on a thread, each stamped with when
//! it was read and the radio's counters at that moment.

use std::io::{BufRead, BufReader};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;

use super::Result;
use crate::clock::Mono;
use crate::driver::radio_emulator::RadioEmulator;
use harness_radio::{Direction, LinkStats};

/// One JSON line a fixture printed, with when the rig read it.
#[derive(Debug, Clone)]
pub struct FixtureLine {
    pub at: Mono,
    pub value: Value,
    /// The radio's (downlink, uplink) counters when the line was read.
    pub radio: Option<(LinkStats, LinkStats)>,
}

impl FixtureLine {
    pub fn event(&self) -> Option<&str> {
        self.value.get("event").and_then(Value::as_str)
    }
}

#[derive(Default)]
struct Lines {
    list: Mutex<Vec<FixtureLine>>,
    changed: Condvar,
    closed: Mutex<bool>,
}

/// Reads a fixture's stdout as JSON lines on a thread.
pub(super) struct LineReader {
    lines: Arc<Lines>,
}

impl LineReader {
    pub(super) fn start(
        name: &str,
        stdout: std::process::ChildStdout,
        radio: Option<Arc<RadioEmulator>>,
    ) -> Result<LineReader> {
        let lines = Arc::new(Lines::default());
        let sink = lines.clone();
        let label = name.to_string();
        std::thread::Builder::new()
            .name(format!("fixture-{name}"))
            .spawn(move || {
                for line in BufReader::new(stdout).lines() {
                    let Ok(line) = line else { break };
                    let at = Mono::now();
                    // Snapshot first: the point is the counters at this moment.
                    let radio = radio
                        .as_ref()
                        .map(|r| (r.stats(Direction::Downlink), r.stats(Direction::Uplink)));
                    match serde_json::from_str::<Value>(&line) {
                        Ok(value) => {
                            sink.list
                                .lock()
                                .unwrap()
                                .push(FixtureLine { at, value, radio });
                            sink.changed.notify_all();
                        }
                        Err(_) => {
                            tracing::warn!(fixture = %label, line, "unparsable fixture output")
                        }
                    }
                }
                *sink.closed.lock().unwrap() = true;
                sink.changed.notify_all();
            })
            .map_err(|e| anyhow::anyhow!("cannot start the reader of {name}: {e}"))?;
        Ok(LineReader { lines })
    }

    /// Waits for the first line matching `pred`.
    pub(super) fn wait_for(
        &self,
        timeout: Duration,
        pred: impl Fn(&FixtureLine) -> bool,
    ) -> Option<FixtureLine> {
        let deadline = Instant::now() + timeout;
        let mut list = self.lines.list.lock().unwrap();
        loop {
            if let Some(l) = list.iter().find(|l| pred(l)) {
                return Some(l.clone());
            }
            let now = Instant::now();
            if now >= deadline || *self.lines.closed.lock().unwrap() {
                return None;
            }
            let wait = (deadline - now).min(Duration::from_millis(100));
            list = self.lines.changed.wait_timeout(list, wait).unwrap().0;
        }
    }

    pub(super) fn all(&self) -> Vec<FixtureLine> {
        self.lines.list.lock().unwrap().clone()
    }
}
