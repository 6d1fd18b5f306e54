//! Drives `fixtures/sbus_receiver.py`, which plays one RC receiver: the rig
//! sends it commands (power, transmitter on/off, sticks) and collects its
//! timestamped events.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{ChildStdin, Command};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use serde_json::Value;

use super::process::Process;
use crate::clock::Mono;

/// How a receiver reports that its pilot's transmitter is gone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Loss {
    /// Frames continue with the failsafe flag.
    Failsafe,
    /// Frames stop.
    Silent,
}

impl Loss {
    pub fn as_str(self) -> &'static str {
        match self {
            Loss::Failsafe => "failsafe",
            Loss::Silent => "silent",
        }
    }
}

/// How to start a receiver fixture.
#[derive(Debug, Clone)]
pub struct ReceiverSpec {
    pub name: String,
    pub port: String,
    pub period_ms: u32,
    pub boot_ms: u32,
    /// Extra boot time, uniform in [0, this], so frame phases are not locked
    /// to the power command (see the fixture's README).
    pub boot_jitter_ms: u32,
    pub loss: Loss,
    pub powered: bool,
    /// 1-based channel → raw value.
    pub channels: Vec<(u8, u16)>,
}

/// One line the fixture printed.
#[derive(Debug, Clone)]
pub struct FixtureEvent {
    pub t: Mono,
    pub event: String,
    pub fields: Value,
}

#[derive(Default)]
struct Events {
    list: Mutex<Vec<FixtureEvent>>,
    changed: Condvar,
}

/// A running receiver fixture.
pub struct ReceiverFixture {
    name: String,
    stdin: Mutex<ChildStdin>,
    events: Arc<Events>,
    process: Mutex<Process>,
}

impl ReceiverFixture {
    /// Starts the fixture and waits until it has opened its port.
    pub fn start(
        python: &Path,
        script: &Path,
        spec: &ReceiverSpec,
        log_dir: &Path,
    ) -> Result<Self> {
        let mut command = Command::new(python);
        command
            .arg(script)
            .args(["--port", &spec.port, "--name", &spec.name])
            .args(["--period-ms", &spec.period_ms.to_string()])
            .args(["--boot-ms", &spec.boot_ms.to_string()])
            .args(["--boot-jitter-ms", &spec.boot_jitter_ms.to_string()])
            .args(["--loss", spec.loss.as_str()])
            .args(["--power", if spec.powered { "on" } else { "off" }])
            .args(["--tx", "off"]);
        for (ch, value) in &spec.channels {
            command.args(["--set", &format!("{ch}={value}")]);
        }
        let log = log_dir.join(format!("{}.log", spec.name));
        let spawned = Mono::now();
        let mut process = Process::spawn(&spec.name, command, &log)?;
        let stdin = process.take_stdin().context("fixture stdin")?;
        let stdout = process.take_stdout().context("fixture stdout")?;
        let events = Arc::new(Events::default());
        let sink = events.clone();
        let name = spec.name.clone();
        std::thread::Builder::new()
            .name(format!("fixture-{name}"))
            .spawn(move || {
                for line in BufReader::new(stdout).lines() {
                    let Ok(line) = line else { break };
                    match parse_event(&line) {
                        Some(event) => {
                            sink.list.lock().unwrap().push(event);
                            sink.changed.notify_all();
                        }
                        None => tracing::warn!(fixture = %name, line, "unparsable fixture output"),
                    }
                }
            })?;
        let fixture = ReceiverFixture {
            name: spec.name.clone(),
            stdin: Mutex::new(stdin),
            events,
            process: Mutex::new(process),
        };
        fixture
            .wait_for(spawned, Duration::from_secs(10), |e| e.event == "ready")
            .map_err(|e| {
                let early = fixture.process.lock().unwrap().check_running().err();
                match early {
                    Some(early) => early,
                    None => e,
                }
            })
            .with_context(|| format!("receiver fixture {} on {}", spec.name, spec.port))?;
        Ok(fixture)
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Sends one command line (see fixtures/README.md).
    pub fn send(&self, command: &str) -> Result<()> {
        let mut stdin = self.stdin.lock().unwrap();
        writeln!(stdin, "{command}")
            .and_then(|_| stdin.flush())
            .with_context(|| format!("fixture {} stopped taking commands", self.name))
    }

    /// Waits for the first event at or after `since` matching `pred`.
    pub fn wait_for(
        &self,
        since: Mono,
        timeout: Duration,
        pred: impl Fn(&FixtureEvent) -> bool,
    ) -> Result<FixtureEvent> {
        let deadline = std::time::Instant::now() + timeout;
        // Events carry the fixture's own timestamps; allow for the event that
        // answers a command being stamped a hair before we asked.
        let since = Mono::from_secs_f64(since.as_secs_f64() - 0.001);
        let mut list = self.events.list.lock().unwrap();
        loop {
            if let Some(e) = list.iter().find(|e| e.t >= since && pred(e)) {
                return Ok(e.clone());
            }
            if let Some(e) = list.iter().rev().find(|e| e.event == "error") {
                bail!("fixture {} reported an error: {}", self.name, e.fields);
            }
            let now = std::time::Instant::now();
            if now >= deadline {
                bail!(
                    "fixture {}: no matching event within {timeout:?}",
                    self.name
                );
            }
            list = self
                .events
                .changed
                .wait_timeout(list, deadline - now)
                .unwrap()
                .0;
        }
    }

    /// Turns the pilot's transmitter on or off; returns the fixture's event.
    pub fn set_tx(&self, on: bool) -> Result<FixtureEvent> {
        let since = Mono::now();
        self.send(if on { "tx on" } else { "tx off" })?;
        self.wait_for(since, Duration::from_secs(2), |e| {
            e.event == "tx" && e.fields["on"] == on
        })
    }

    /// Sets channels (1-based); returns the fixture's event.
    pub fn set_channels(&self, channels: &[(u8, u16)]) -> Result<FixtureEvent> {
        let since = Mono::now();
        let pairs: Vec<String> = channels.iter().map(|(c, v)| format!("{c}={v}")).collect();
        self.send(&format!("set {}", pairs.join(" ")))?;
        self.wait_for(since, Duration::from_secs(2), |e| e.event == "set")
    }

    /// The first frame the fixture wrote at or after `since` with flags
    /// matching `mask` (e.g. 0x08 = failsafe).
    pub fn first_frame_with_flags(&self, since: Mono, mask: u8, timeout: Duration) -> Result<Mono> {
        let e = self.wait_for(since, timeout, |e| {
            e.event == "first_frame"
                && e.fields["flags"]
                    .as_u64()
                    .is_some_and(|f| f as u8 & mask == mask)
        })?;
        Ok(e.t)
    }

    pub fn log_path(&self) -> std::path::PathBuf {
        self.process.lock().unwrap().log_path().to_path_buf()
    }

    /// Asks the fixture to quit and waits for it.
    pub fn stop(&self) {
        let _ = self.send("quit");
        self.process.lock().unwrap().stop(Duration::from_secs(2));
    }
}

fn parse_event(line: &str) -> Option<FixtureEvent> {
    let fields: Value = serde_json::from_str(line).ok()?;
    let t = Mono::from_secs_f64(fields.get("t")?.as_f64()?);
    let event = fields.get("event")?.as_str()?.to_string();
    Some(FixtureEvent { t, event, fields })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_fixture_lines() {
        let e = parse_event(
            r#"{"t": 12.5, "name": "rx0", "event": "tx", "on": false, "last_frame": 12.49}"#,
        )
        .unwrap();
        assert_eq!(e.event, "tx");
        assert_eq!(e.t, Mono::from_secs_f64(12.5));
        assert_eq!(e.fields["last_frame"].as_f64(), Some(12.49));
        assert!(parse_event("not json").is_none());
        assert!(parse_event(r#"{"event": "tx"}"#).is_none());
    }
}
