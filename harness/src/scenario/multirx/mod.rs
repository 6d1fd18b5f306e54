//! MultiRX scenarios: the paper's A–D (§VI-B), the handover variants that
//! matter for an SLA (failsafe flag vs silence), a six-pilot route, and the
//! independent fail-safe override. Each runs in both modes on its own
//! freshly started device.

mod handover;
mod idle;
mod ifs;
mod loiter;
mod mission;
mod route;

use std::time::Duration;

use anyhow::Result;
use multirx_core::Config;

use super::PhaseContext;
use crate::measurement::Measurement;
use crate::rigfile::Mode;
use crate::strategy::multirx::{MultirxSession, SessionOptions};

/// One scenario: its measurements (with built-in limits) and its script.
pub struct Scenario {
    /// Short name, unique within a mode: `b_handover`.
    pub name: &'static str,
    /// What it shows, for the report.
    pub summary: &'static str,
    pub options: SessionOptions,
    /// Measurements with their built-in limits for this mode and config.
    pub measurements: fn(&Limits) -> Vec<Measurement>,
    pub run: fn(&MultirxSession, &mut PhaseContext, &Limits) -> Result<()>,
}

/// Everything limits depend on, derived once per mode from its config.
#[derive(Debug, Clone)]
pub struct Limits {
    pub mode: Mode,
    pub receivers: u8,
    pub frame_period_ms: f64,
    /// Parallel: the SLA; scan: the paper's bound, window × receivers + margin.
    pub handover_ms: f64,
    pub handover_silent_ms: f64,
}

impl Limits {
    pub fn new(mode: Mode, config: &Config) -> Limits {
        let period = config.frame_period.total_micros() as f64 / 1000.0;
        let window = config.scan_window.total_micros() as f64 / 1000.0;
        let silence = config.silence_timeout.total_micros() as f64 / 1000.0;
        let scan_bound = window * f64::from(config.receivers) + 500.0;
        let (handover_ms, handover_silent_ms) = match mode {
            Mode::Parallel => (50.0, 100.0),
            Mode::Scan => (scan_bound, scan_bound + silence),
        };
        Limits {
            mode,
            receivers: config.receivers,
            frame_period_ms: period,
            handover_ms,
            handover_silent_ms,
        }
    }

    /// `multirx.<mode>.<what>`.
    pub fn name(&self, what: &str) -> String {
        format!("multirx.{}.{what}", self.mode.as_str())
    }

    /// Largest output gap allowed: 1.5 frame periods.
    pub fn max_gap_ms(&self) -> f64 {
        1.5 * self.frame_period_ms
    }

    /// Largest gap allowed as the flight controller reads it: never two
    /// frames missing in a row, transport latency included.
    pub fn max_fc_gap_ms(&self) -> f64 {
        3.0 * self.frame_period_ms
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
    ]
}

/// Measurements every scenario records about the whole session.
pub fn session_measurements(limits: &Limits, scenario: &str) -> Vec<Measurement> {
    vec![
        Measurement::new(limits.name(&format!("{scenario}.max_output_gap_ms")), "ms")
            .describe(OUTPUT_GAP)
            .at_most(limits.max_gap_ms()),
        Measurement::new(limits.name(&format!("{scenario}.fc_max_gap_ms")), "ms")
            .describe(FC_GAP)
            .at_most(limits.max_fc_gap_ms()),
        Measurement::new(limits.name(&format!("{scenario}.rc_losses")), "")
            .describe("times PX4 would have declared RC loss (0.5 s without frames, or the failsafe flag)")
            .equal_to(0.0),
    ]
}

/// What `max_output_gap_ms` is, for the report.
pub const OUTPUT_GAP: &str = "longest interval between frames leaving MultiRX (emulated device: its TX probe, \
     a timestamp at each UART write; board: as read at the flight-controller adapter)";
/// What `fc_max_gap_ms` is, for the report.
pub const FC_GAP: &str = "longest interval between frames as the flight-controller side read them, \
     serial transport included (a pty on a 2-vCPU VM adds up to ~4 ms)";

/// Records the session-wide measurements from the TX probe and from PX4's
/// view of the output.
pub fn record_session(
    session: &MultirxSession,
    ctx: &mut PhaseContext,
    limits: &Limits,
    scenario: &str,
) -> Result<()> {
    let report = session.px4_report();
    ctx.log(format!(
        "{} frames at the flight controller, {} RC losses, {} mode changes",
        report.frames,
        report.rc_losses.len(),
        report.mode_changes.len()
    ));
    let fc_gap_ms = report.max_gap.as_secs_f64() * 1000.0;
    ctx.record(
        &limits.name(&format!("{scenario}.fc_max_gap_ms")),
        fc_gap_ms,
    );
    let name = limits.name(&format!("{scenario}.max_output_gap_ms"));
    match session.device_max_gap()? {
        Some(gap) => ctx.record(&name, gap.as_secs_f64() * 1000.0),
        None => {
            ctx.record(&name, fc_gap_ms);
            ctx.annotate(
                &name,
                "no TX probe on a board: measured at the flight-controller adapter",
            );
        }
    }
    ctx.record(
        &limits.name(&format!("{scenario}.rc_losses")),
        report.rc_losses.len() as f64,
    );
    Ok(())
}

/// Settle time between steps, so each pilot's receiver is steadily up.
pub const SETTLE: Duration = Duration::from_millis(600);
