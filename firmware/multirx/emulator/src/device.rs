//! The emulated device's loop: the same engine as the firmware, with host
//! threads standing in for UART interrupts and a [`DeviceClock`] for the timer.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::Instant as HostInstant;

use multirx_core::boot::{BootReport, ImageKind, ResetCause, build_id};

/// The source id of this program's input files, from `build.rs` (16 hex digits).
pub const SOURCE_ID: &str = env!("MULTIRX_SOURCE_ID");

/// The build id this program reports with a config hashing to `config_hash`: the emulated
/// image of this core, from the source `build.rs` hashed.
pub fn emulated_build_id(config_hash: u64) -> u64 {
    let source = u64::from_str_radix(SOURCE_ID, 16).expect("build.rs writes 16 hex digits");
    build_id(ImageKind::Emulated, config_hash, source)
}
use multirx_core::{Config, Instant, Multiplexer};

use hostio::status::{Kind, StatusWriter};
use serde::Serialize;

use crate::clock::DeviceClock;
use crate::ports::{Input, Output, Source};
use crate::tap::TxTap;

/// How long before a deadline the loop stops sleeping and polls. Costs up
/// to SPIN of CPU per output period; buys a steady cadence on hosts whose
/// timer wake-ups are late (virtual machines).
const SPIN: std::time::Duration = std::time::Duration::from_micros(1500);

/// Longest sleep, so the loop notices `stop`.
const STOP_CHECK: std::time::Duration = std::time::Duration::from_millis(100);

/// How often the boot line is repeated.
const BOOT_LINE_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// What the device counts: on its status lines (`firmware/hostio/STATUS-JSON.md`) and the
/// log line it ends with, by the same names.
#[derive(Debug, Default, Clone, Serialize)]
pub struct Counters {
    /// Frames handed whole to the flight controller's port.
    pub frames_out: u64,
    /// Frames the flight controller's port did not take (full, failed or gone).
    pub frames_dropped: u64,
    /// Status lines written to the status port.
    pub status_lines: u64,
    /// Longest interval between two frames handed to the output port, as the
    /// device itself timed it (ms): separates our cadence from transport jitter.
    pub max_gap_ms: f64,
    /// How long the host held the device clock in all ([`DeviceClock`]), ms.
    pub host_held_ms: f64,
}

/// A status of the emulated device: its counters; it has no gauges.
#[derive(Debug, Default, Clone, Serialize)]
pub struct Status {
    pub counters: Counters,
    pub gauges: Gauges,
}

/// No levels to report (an empty `gauges` object, as every program's status line has).
#[derive(Debug, Default, Clone, Serialize)]
pub struct Gauges {}

/// How a run ended.
#[derive(Debug, Default)]
pub struct RunStats {
    pub status: Status,
    /// Why the run ended early: the flight-controller port is gone for good.
    pub fc_gone: Option<String>,
}

/// Status lines written to a file every `every` while the device runs.
pub struct StatusJson<'a> {
    pub writer: &'a mut StatusWriter,
    pub every: std::time::Duration,
}

/// [`StatusJson`] as the loop keeps it.
struct Periodic<'a> {
    json: StatusJson<'a>,
    next: HostInstant,
}

pub struct Device {
    clock: DeviceClock,
    /// Whether the loop did anything since the clock's last accounting
    /// (handled input, wrote a frame, an event or the boot line), or only
    /// polled: see [`DeviceClock::idled`].
    worked: bool,
    /// The last input's device time: bytes that arrived during a hold map to
    /// before it, and must not take a receiver's clock backwards.
    last_input: Instant,
    mux: Multiplexer,
    fc: Output,
    status: Option<Output>,
    last_frame_at: Option<HostInstant>,
    max_gap: std::time::Duration,
    tap: Option<TxTap>,
    /// The boot line, written once the first frame is out and then every
    /// [`BOOT_LINE_EVERY`] (as the firmware does, so a rig that opens the
    /// status port later still learns what runs here).
    boot: BootReport,
    next_boot_line: Option<HostInstant>,
}

impl Device {
    pub fn new(
        config: Config,
        fc: Output,
        status: Option<Output>,
        tap: Option<TxTap>,
        reset: ResetCause,
    ) -> Self {
        let config_hash = config.identity_hash();
        let boot = BootReport {
            at: Instant::ZERO,
            build_id: emulated_build_id(config_hash),
            config_hash,
            reset,
            first_frame: Default::default(),
        };
        Device {
            boot,
            next_boot_line: None,
            clock: DeviceClock::new(),
            worked: true,
            last_input: Instant::ZERO,
            mux: Multiplexer::new(config, Instant::ZERO),
            fc,
            status,
            last_frame_at: None,
            max_gap: std::time::Duration::ZERO,
            tap,
        }
    }

    fn to_core(&self, t: HostInstant) -> Instant {
        self.clock.device(t)
    }

    fn to_host(&self, t: Instant) -> HostInstant {
        self.clock.host(t)
    }

    /// Runs until `stop` is set or the flight-controller port is gone for good
    /// (nobody can be served: the emulated device ends instead of idling on).
    /// With `json`, writes a status line every period.
    pub fn run(
        &mut self,
        inputs: Receiver<Input>,
        stop: &AtomicBool,
        json: Option<StatusJson>,
    ) -> RunStats {
        self.flush();
        let mut periodic = json.map(|json| Periodic {
            next: HostInstant::now() + json.every,
            json,
        });
        let mut fc_gone = None;
        while !stop.load(Ordering::Relaxed) {
            if let Some(why) = self.fc.gone() {
                fc_gone = Some(why);
                break;
            }
            if let Some(p) = &mut periodic {
                self.status_line(p);
            }
            self.account();
            let due = self.mux.poll_timeout().expect("the output never stops");
            let deadline = self.to_host(due);
            let now = HostInstant::now();
            let wait = deadline
                .saturating_duration_since(now)
                // Wake now and then to notice `stop`.
                .min(STOP_CHECK);
            if wait <= SPIN {
                // Close to a deadline: poll instead of sleeping, since waking a
                // sleeping thread on a virtual machine can take milliseconds.
                match inputs.try_recv() {
                    Ok(input) => self.handle_input(input),
                    Err(_) => std::hint::spin_loop(),
                }
                self.service();
                continue;
            }
            // Sleep until SPIN before the deadline: account for the pass so far
            // first (a hold in it moves the deadline, it must not become device
            // time), then ask for a time fixed by the deadline, never one
            // computed from a clock read that a hold may have made late.
            self.account();
            let slept = HostInstant::now();
            let asked = (self.to_host(due) - SPIN).min(now + STOP_CHECK).max(slept);
            let input = inputs.recv_timeout(asked - slept);
            if let Err(RecvTimeoutError::Disconnected) = input {
                // No reader left: keep the output going all the same,
                // as the board would with every receiver unplugged.
                std::thread::sleep(asked.saturating_duration_since(HostInstant::now()));
            }
            match input {
                Ok(input) => {
                    // Woken by input: runnable from when it came (already
                    // queued: from when we went to sleep).
                    let came = match &input {
                        Input::Bytes { at, .. } => (*at).clamp(slept, asked),
                        _ => asked,
                    };
                    self.clock.woke(came);
                    self.handle_input(input);
                }
                Err(_) => {
                    self.clock.woke(asked);
                }
            }
            self.service();
        }
        RunStats {
            status: self.snapshot(),
            fc_gone,
        }
    }

    /// The counters now.
    fn snapshot(&self) -> Status {
        Status {
            counters: Counters {
                frames_out: self.fc.written,
                frames_dropped: self.fc.dropped,
                status_lines: self.status.as_ref().map_or(0, |s| s.written),
                max_gap_ms: self.max_gap.as_secs_f64() * 1000.0,
                host_held_ms: self.clock.held().as_secs_f64() * 1000.0,
            },
            gauges: Gauges {},
        }
    }

    /// Writes a status line when one is due. The write is the host's work, held whole like a
    /// port's; a failed one is logged, never stops the device.
    fn status_line(&mut self, p: &mut Periodic) {
        let now = HostInstant::now();
        if now < p.next {
            return;
        }
        p.next = now + p.json.every;
        let status = self.snapshot();
        self.clock.ran();
        p.json.writer.write_periodic(Kind::Status, &status);
        self.clock.handed_off();
        self.worked = true;
    }

    /// Brings the device clock up to now: a hold in the pass so far must be
    /// out of the time the engine is about to be given.
    fn account(&mut self) -> HostInstant {
        if std::mem::take(&mut self.worked) {
            self.clock.ran()
        } else {
            self.clock.idled()
        }
    }

    /// Handles due deadlines and sends what they produced.
    fn service(&mut self) {
        let at = self.account();
        let now = self.to_core(at);
        if self.mux.poll_timeout().is_some_and(|due| now >= due) {
            self.worked = true;
            self.mux.handle_timeout(now);
        }
        self.flush();
    }

    fn handle_input(&mut self, input: Input) {
        self.worked = true;
        match input {
            Input::Bytes { source, at, bytes } => {
                let at = self.to_core(at).max(self.last_input);
                self.last_input = at;
                match source {
                    Source::Receiver(rx) => self.mux.handle_receiver_bytes(at, rx, &bytes),
                    Source::Ifs => self.mux.handle_ifs_bytes(at, &bytes),
                }
            }
            Input::Closed { source, error } => {
                tracing::warn!(?source, %error, "input closed; silent until it reopens");
            }
            Input::Waiting => {}
        }
    }

    /// Writes the boot line when it is due.
    fn boot_line(&mut self) {
        let now = HostInstant::now();
        let Some(due) = self.next_boot_line.filter(|&due| now >= due) else {
            return;
        };
        self.next_boot_line = Some(due + BOOT_LINE_EVERY);
        self.worked = true;
        self.boot.at = self.to_core(now);
        let line = format!("{}\n", self.boot);
        tracing::debug!(boot = line.trim_end(), "boot line");
        if let Some(status) = &mut self.status {
            self.clock.ran();
            status.send(line.as_bytes());
            self.clock.handed_off();
        }
    }

    fn flush(&mut self) {
        while let Some(frame) = self.mux.poll_transmit() {
            // Up to this instant: a hold in the engine's work just now is
            // the host's too; the frame leaves at this instant.
            let now = self.clock.ran();
            if let Some(last) = self.last_frame_at {
                self.max_gap = self.max_gap.max(now - last);
            }
            self.last_frame_at = Some(now);
            if let Some(tap) = &mut self.tap {
                tap.frame_sent(self.clock.monotonic(now), self.clock.held());
            }
            self.fc.send(&frame);
            self.clock.handed_off();
            if self.next_boot_line.is_none() {
                self.boot.first_frame = self.to_core(now).since_epoch();
                self.next_boot_line = Some(now);
            }
        }
        self.boot_line();
        while let Some(event) = self.mux.poll_event() {
            self.worked = true;
            tracing::debug!(%event, "status");
            if let Some(status) = &mut self.status {
                let line = format!("{event}\n");
                self.clock.ran();
                status.send(line.as_bytes());
                self.clock.handed_off();
            }
        }
    }
}
