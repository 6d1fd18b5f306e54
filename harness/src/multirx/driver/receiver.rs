//! Drives `fixtures/sbus_receiver.py`, which plays one RC receiver: the rig
//! sends it commands (power, transmitter on/off, sticks) and waits for its
//! timestamped events ([`ReceiverEvent`]) through the fixture driver.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

pub use super::sbus_receiver::Loss;
use super::sbus_receiver::ReceiverEvent;
use crate::clock::Mono;
use crate::driver::fixture::{Fixture, FixtureError};

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

/// A running receiver fixture.
pub struct ReceiverFixture {
    fixture: Fixture<ReceiverEvent>,
}

impl ReceiverFixture {
    /// Starts the fixture and waits until it has opened its port.
    pub fn start(
        python: &Path,
        script: &Path,
        spec: &ReceiverSpec,
        log_dir: &Path,
    ) -> Result<Self, FixtureError> {
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
        let fixture = Fixture::start(&spec.name, command, &log)?;
        let receiver = ReceiverFixture { fixture };
        let ready = receiver.wait_for(spawned, "ready event", Duration::from_secs(10), |e| {
            matches!(e, ReceiverEvent::Ready { .. })
        });
        match ready {
            Ok(ReceiverEvent::Ready {
                realtime: false, ..
            }) => {
                tracing::info!(
                    port = %spec.port,
                    "receiver fixture refused real-time priority: its frames follow host load"
                );
                Ok(receiver)
            }
            Ok(_) => Ok(receiver),
            // Exited early (a bad argument): its log says why.
            Err(e) => Err(match receiver.fixture.check_running() {
                Err(early) => {
                    FixtureError::Spawn(early.context(format!("receiver fixture on {}", spec.port)))
                }
                Ok(()) => e,
            }),
        }
    }

    pub fn name(&self) -> &str {
        self.fixture.name()
    }

    /// Sends one command line (see fixtures/README.md).
    pub fn send(&self, command: &str) -> Result<(), FixtureError> {
        self.fixture.send(command)
    }

    /// Waits for the first event the fixture stamped at or after `since`
    /// matching `pred`.
    pub fn wait_for(
        &self,
        since: Mono,
        what: &str,
        timeout: Duration,
        pred: impl Fn(&ReceiverEvent) -> bool,
    ) -> Result<ReceiverEvent, FixtureError> {
        // Events carry the fixture's own timestamps; allow for the event that
        // answers a command being stamped a hair before we asked.
        let since = Mono::from_secs_f64(since.as_secs_f64() - 0.001);
        self.fixture
            .wait_for(what, timeout, |l| l.event.t() >= since && pred(&l.event))
            .map(|l| l.event)
    }

    /// Turns the pilot's transmitter on or off; returns the fixture's event.
    pub fn set_tx(&self, on: bool) -> Result<ReceiverEvent, FixtureError> {
        let since = Mono::now();
        self.send(if on { "tx on" } else { "tx off" })?;
        self.wait_for(
            since,
            "tx event",
            Duration::from_secs(2),
            |e| matches!(e, ReceiverEvent::Tx { on: now, .. } if *now == on),
        )
    }

    /// Switches the receiver's power; returns the fixture's event.
    pub fn set_power(&self, on: bool) -> Result<ReceiverEvent, FixtureError> {
        let since = Mono::now();
        self.send(if on { "power on" } else { "power off" })?;
        self.wait_for(
            since,
            "power event",
            Duration::from_secs(2),
            |e| matches!(e, ReceiverEvent::Power { on: now, .. } if *now == on),
        )
    }

    /// What the wire between this receiver and MultiRX does from now on: `clean`,
    /// `garbage`, `stutter` or `flood` (fixtures/sbus_receiver.py); returns the fixture's
    /// event.
    pub fn set_line(&self, fault: &str) -> Result<ReceiverEvent, FixtureError> {
        let since = Mono::now();
        self.send(&format!("line {fault}"))?;
        self.wait_for(
            since,
            "line event",
            Duration::from_secs(2),
            |e| matches!(e, ReceiverEvent::Line { fault: f, .. } if f == fault),
        )
    }

    /// Sets channels (1-based); returns the fixture's event.
    pub fn set_channels(&self, channels: &[(u8, u16)]) -> Result<ReceiverEvent, FixtureError> {
        let since = Mono::now();
        let pairs: Vec<String> = channels.iter().map(|(c, v)| format!("{c}={v}")).collect();
        self.send(&format!("set {}", pairs.join(" ")))?;
        self.wait_for(since, "set event", Duration::from_secs(2), |e| {
            matches!(e, ReceiverEvent::Set { .. })
        })
    }

    /// The first frame the fixture wrote at or after `since` with flags
    /// matching `mask` (e.g. 0x08 = failsafe).
    pub fn first_frame_with_flags(
        &self,
        since: Mono,
        mask: u8,
        timeout: Duration,
    ) -> Result<Mono, FixtureError> {
        let e = self.wait_for(
            since,
            "a first frame with those flags",
            timeout,
            |e| matches!(e, ReceiverEvent::FirstFrame { flags, .. } if flags & mask == mask),
        )?;
        Ok(e.t())
    }

    pub fn log_path(&self) -> PathBuf {
        self.fixture.log_path().to_path_buf()
    }

    /// Asks the fixture to quit and waits for it.
    pub fn stop(&self) {
        let _ = self.send("quit");
        self.fixture.stop(Duration::from_secs(2));
    }
}
