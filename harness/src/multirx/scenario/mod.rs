//! MultiRX scenarios: the paper's A–D (§VI-B), the handover variants that
//! matter for an SLA (failsafe flag vs silence), a six-pilot route, the
//! independent fail-safe override, and faults (a receiver's wire garbled,
//! stuttering or flooding, or unplugged and back on an emulated rig; every receiver dead; MultiRX itself reset). Each runs in both modes on its own
//! freshly started device.

mod all_dead;
mod device_reset;
mod handover;
mod idle;
mod ifs;
mod line_fault;
mod loiter;
mod mission;
mod port_replug;
mod route;

use std::time::Duration;

use anyhow::Result;
use multirx_core::Config;

use crate::measurement::{Declarations, Dimension, Handle, Spec};
use crate::multirx::rigfile::{DeviceKind, Mode};
use crate::multirx::session::{MultirxSession, SessionOptions};
use crate::runner::PhaseContext;

/// One scenario: its measurements (with built-in limits) and its script.
pub struct Scenario {
    /// Short name, unique within a mode: `b_handover`.
    pub name: &'static str,
    /// What it shows, for the report.
    pub summary: &'static str,
    pub options: SessionOptions,
    /// Declares the measurements, with their built-in limits for this mode
    /// and config, and returns the script that records them.
    pub plan: fn(&mut Declarations, &ModeLimits) -> Script,
}

/// A scenario's script, holding the handles of the measurements it declared.
pub type Script =
    Box<dyn FnOnce(&MultirxSession, &mut PhaseContext, &ModeLimits) -> Result<()> + Send>;

/// Everything limits depend on, derived once per mode from its config.
#[derive(Debug, Clone)]
pub struct ModeLimits {
    pub mode: Mode,
    pub receivers: u8,
    pub frame_period_ms: f64,
    /// Parallel: the SLA; scan: the paper's bound, window × receivers + margin.
    pub handover_ms: f64,
    /// Parallel: the SLA for receivers that fall silent; scan: the paper's
    /// bound plus the configured silence timeout, which still bounds the
    /// measured one.
    pub handover_silent_ms: f64,
    /// Emulated device or board: what the frame-gap figures can hold to.
    pub device: DeviceKind,
    /// The receivers' frame period (`[multirx.receivers] period_ms`).
    pub receiver_period_ms: u32,
    /// Scan mode: one turn round every receiver, a listen window each (ms).
    pub scan_cycle_ms: Option<f64>,
}

impl ModeLimits {
    pub fn new(
        mode: Mode,
        config: &Config,
        device: DeviceKind,
        receiver_period_ms: u32,
    ) -> ModeLimits {
        let period = config.frame_period.as_micros() as f64 / 1000.0;
        let window = config.scan_window.as_micros() as f64 / 1000.0;
        let silence = config.silence_timeout.as_micros() as f64 / 1000.0;
        let scan_cycle = window * f64::from(config.receivers);
        let scan_bound = scan_cycle + 500.0;
        // The SLA from before issue 24. Its targets (30 ms for 7 ms receivers, 55 ms
        // for 14 ms) are not met in the worst case by this measure: it runs to the frame the
        // flight controller gets, so it adds the wait for the next output frame (0-7 ms; PX4
        // wants frames at least 7 ms apart, so the frame cannot go sooner) to the device's
        // timeout of three frames, a third of a period for a late frame and a 1 ms margin
        // (24.3-25.5 ms): 29.5-31 ms worst on the emulated rig, 27 ms median. Meeting 30 ms
        // in every phase would need the output's slots to follow the receiver in control.
        let silent_sla = 100.0;
        let (handover_ms, handover_silent_ms) = match mode {
            Mode::Parallel => (50.0, silent_sla),
            Mode::Scan => (scan_bound, scan_bound + silence),
        };
        ModeLimits {
            mode,
            receivers: config.receivers,
            frame_period_ms: period,
            handover_ms,
            handover_silent_ms,
            device,
            receiver_period_ms,
            scan_cycle_ms: (mode == Mode::Scan).then_some(scan_cycle),
        }
    }

    /// The shortest silence after which the device may end a receiver's link
    /// whose line delivers `burst` frames at once (its jitter only adds to it).
    pub fn min_silence_timeout_ms(&self, config: &Config, burst: u8) -> f64 {
        let period = multirx_core::Duration::from_millis(u64::from(self.receiver_period_ms));
        let timeout = multirx_core::mux::measured_silence_timeout(
            period,
            burst,
            multirx_core::Duration::ZERO,
            config.silence_timeout,
        );
        timeout.as_micros() as f64 / 1000.0
    }

    /// A measurement of MultiRX in this mode.
    pub fn spec(&self, base: &str, unit: &str) -> Spec {
        Spec::new(base, unit)
            .dim(Dimension::Device, "multirx")
            .dim(Dimension::Mode, self.mode.as_str())
    }

    /// A session measurement: of `scenario`, or of the whole run (`None`).
    pub fn session_spec(&self, base: &str, unit: &str, scenario: Option<&str>) -> Spec {
        let spec = self.spec(base, unit);
        match scenario {
            Some(name) => spec.dim(Dimension::Scenario, name),
            None => spec,
        }
    }

    /// Largest output gap allowed: 1.5 frame periods.
    pub fn max_gap_ms(&self) -> f64 {
        1.5 * self.frame_period_ms
    }

    /// Largest gap allowed as the flight controller reads it: never two
    /// frames missing in a row, transport latency included. Held on a board
    /// only: on an emulated rig the "transport" is a pty between two
    /// processes of a shared host, whose stalls (10-40 ms on a 2-vCPU VM, for
    /// any program) are the host's, not the device's; there the figure is
    /// recorded without a limit, the device's cadence is judged in device
    /// time (`max_output_gap_ms`) and PX4's own criterion (`rc_losses`) holds.
    pub fn max_fc_gap_ms(&self) -> Option<f64> {
        (self.device == DeviceKind::Board).then_some(3.0 * self.frame_period_ms)
    }
}

/// Every MultiRX scenario, in the order they run.
pub fn scenarios() -> Vec<Scenario> {
    vec![
        idle::SCENARIO,
        handover::FAILSAFE,
        handover::SILENT,
        loiter::SCENARIO,
        mission::SCENARIO,
        route::SCENARIO,
        ifs::SCENARIO,
        line_fault::GARBAGE,
        line_fault::STUTTER,
        line_fault::FLOOD,
        all_dead::SCENARIO,
        device_reset::SCENARIO,
    ]
}

/// Scenarios only an emulated device can run: the rig pulls out wires it made.
pub fn emulated_only() -> Vec<Scenario> {
    vec![port_replug::SCENARIO]
}

/// What every scenario records about its whole session, and the whole-run
/// phase about every scenario of a mode together.
pub struct SessionMeasurements {
    output_gap: Handle,
    fc_gap: Handle,
    rc_losses: Handle,
    /// Emulated device only: the host's longest hold of the device clock.
    host_hold: Option<Handle>,
    /// Per scenario only: the device's own boot-to-first-frame figure.
    first_frame: Option<Handle>,
}

/// Boot to first SBUS frame must stay well inside PX4's 0.5 s RC-loss timeout
/// (COM_RC_LOSS_T), so that a reset in flight never shows as RC loss; 50 ms, a
/// tenth of it, is the project's target for that margin.
pub const FIRST_FRAME_MAX_MS: f64 = 50.0;

impl SessionMeasurements {
    /// Declares them for `scenario`, or for the whole run of the mode (`None`).
    pub fn declare(d: &mut Declarations, limits: &ModeLimits, scenario: Option<&str>) -> Self {
        let [output_gap, fc_gap, rc_losses] = session_specs(limits, scenario).map(|s| d.declare(s));
        let host_hold = host_hold_spec(limits, scenario).map(|s| d.declare(s));
        let first_frame = scenario.map(|name| {
            d.declare(
                limits
                    .spec("boot_to_first_frame_ms", "ms")
                    .dim(Dimension::Scenario, name)
                    .describe(
                        "from the device's clock start to its first SBUS frame, as its boot line reports it",
                    )
                    .at_most(FIRST_FRAME_MAX_MS),
            )
        });
        SessionMeasurements {
            output_gap,
            fc_gap,
            rc_losses,
            host_hold,
            first_frame,
        }
    }

    /// Records the worst gaps and the total RC losses (the whole run's
    /// figures over its scenarios').
    pub fn record(&self, ctx: &mut PhaseContext, worst: &SessionFigures) {
        ctx.record(self.output_gap, worst.output_gap_ms);
        ctx.record(self.fc_gap, worst.fc_gap_ms);
        ctx.record(self.rc_losses, worst.rc_losses);
        if let (Some(h), Some(v)) = (self.host_hold, worst.host_hold_ms) {
            ctx.record(h, v);
        }
    }
}

/// The session measurements of `scenario`, or of the whole run (`None`): the
/// same base names, told apart by the `scenario` dimension.
pub fn session_specs(limits: &ModeLimits, scenario: Option<&str>) -> [Spec; 3] {
    let (over, rc_losses) = match scenario {
        Some(_) => (
            "",
            "times PX4 would have declared RC loss (0.5 s without frames, or the failsafe flag)",
        ),
        None => (
            ", over every scenario of this mode",
            "RC losses PX4 would have declared over every scenario of this mode",
        ),
    };
    let spec = |base: &str, unit: &str| limits.session_spec(base, unit, scenario);
    [
        spec("max_output_gap_ms", "ms")
            .describe(format!("{OUTPUT_GAP}{over}"))
            .at_most(limits.max_gap_ms()),
        {
            let fc = spec("fc_max_gap_ms", "ms").describe(format!("{FC_GAP}{over}"));
            match limits.max_fc_gap_ms() {
                Some(max) => fc.at_most(max),
                None => fc,
            }
        },
        spec("rc_losses", "").describe(rc_losses).equal_to(0.0),
    ]
}

/// The host's longest hold of an emulated device (`None` on a board): the
/// emulation's floor, recorded without a limit (no requirement applies to the
/// host).
pub fn host_hold_spec(limits: &ModeLimits, scenario: Option<&str>) -> Option<Spec> {
    (limits.device == DeviceKind::Emulated).then(|| {
        limits
            .session_spec("host_hold_ms", "ms", scenario)
            .describe(HOST_HOLD)
    })
}

/// What `max_output_gap_ms` is, for the report.
pub const OUTPUT_GAP: &str = "longest interval between frames leaving MultiRX (emulated device: its TX probe, \
     a timestamp at each UART write, in device time, i.e. with the host's holds taken out; \
     board: as read at the flight-controller adapter)";
/// What `fc_max_gap_ms` is, for the report.
pub const FC_GAP: &str = "longest interval between frames as the flight-controller side read them, \
     serial transport included (emulated rig: a pty on a shared host, its stalls included; \
     no limit there, three frame periods on a board)";
/// What `host_hold_ms` is, for the report.
pub const HOST_HOLD: &str = "longest time the host did not run the emulated device past a deadline it \
     was waiting for (its clock stood still meanwhile): the emulation's floor, not the device's figure";

/// A session's (or a whole run's worst) figures behind [`SessionMeasurements`].
#[derive(Debug, Clone, Copy, Default)]
pub struct SessionFigures {
    pub output_gap_ms: f64,
    pub fc_gap_ms: f64,
    pub rc_losses: f64,
    pub host_hold_ms: Option<f64>,
}

/// Records the session-wide measurements from the TX probe and from PX4's
/// view of the output.
pub fn record_session(
    session: &MultirxSession,
    ctx: &mut PhaseContext,
    m: &SessionMeasurements,
) -> Result<()> {
    let report = session.px4_report();
    ctx.log(format!(
        "{} frames at the flight controller, {} RC losses, {} mode changes",
        report.frames,
        report.rc_losses.len(),
        report.mode_changes.len()
    ));
    let fc_gap_ms = report.max_gap.as_secs_f64() * 1000.0;
    ctx.record(m.fc_gap, fc_gap_ms);
    match session.device_cadence()? {
        Some(cadence) => {
            ctx.record(m.output_gap, cadence.max_gap.as_secs_f64() * 1000.0);
            if let Some(h) = m.host_hold {
                ctx.record(h, cadence.max_hold.as_secs_f64() * 1000.0);
            }
        }
        None => {
            ctx.record(m.output_gap, fc_gap_ms);
            ctx.annotate(
                m.output_gap,
                "no TX probe on a board: measured at the flight-controller adapter",
            );
        }
    }
    ctx.record(m.rc_losses, report.rc_losses.len() as f64);
    if let (Some(h), Some(boot)) = (m.first_frame, session.boot) {
        ctx.record(h, boot.first_frame.as_secs_f64() * 1000.0);
    }
    Ok(())
}

/// Settle time between steps, so each pilot's receiver is steadily up.
pub const SETTLE: Duration = Duration::from_millis(600);

/// Longest wait for a receiver fixture to report the first frame it wrote after a change (a
/// transmitter off: its first failsafe frame). The fixture stamps the frame when it writes
/// it, and measurements run from that stamp, so this only bounds a fixture that stalls: a
/// second was too short for a fixture under CI's load once (scan c_loiter).
pub const FIXTURE_FIRST_FRAME: Duration = Duration::from_secs(3);
