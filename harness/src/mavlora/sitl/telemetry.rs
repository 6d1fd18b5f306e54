//! Steady telemetry from a real autopilot through compact MavLora: what the radio carries
//! each way, and how often and how fresh the ground station's positions are, judged on the
//! vehicle's own clock ([`super::freshness`]).
//!
//! Limits (issue targets, from the paper and SORA): position ≥ 2.9 Hz (the paper's 3 Hz:
//! ≤ 3.4 m between updates at 10 m/s, one missed update in 10 s allowed), age p95 ≤ 1.0 s
//! and no gap over 1.5 s; at 10 % loss ≥ 2.5 Hz and no gap over 3 s; ≤ 68.36 B/s down (a 10 %
//! duty cycle of LoRa SF7, the EU 433 MHz rule).

use std::time::Duration;

use anyhow::{Context, bail};

use super::session::SitlReport;
use super::{Scenario, Script, Target, freshness, options, run};
use crate::clock::Mono;
use crate::mavlora::fixture::sitl::GroundEvent;
use crate::mavlora::session::SessionDefaults;
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "telemetry",
    summary: "Steady compact telemetry from a real autopilot: position >= 2.9 Hz (>= 2.5 at \
              loss), age p95 <= 1.0 s, no gap over 1.5 s (3 s at loss), <= 68.36 B/s down",
    plan,
    radios: |p| &p.telemetry,
};

/// Seconds after the ground station's first heartbeat before the window opens: stream
/// set-up and the autopilot's boot (ArduPilot reports its GPS, EKF origin and the stream
/// rates it was asked for until ~20 s after start): steady telemetry is what follows.
pub const WARMUP_S: f64 = 20.0;
pub const WINDOW_S: f64 = 30.0;
/// 10 % of LoRa SF7's 683.6 B/s (the EU 433 MHz duty-cycle rule).
pub const DOWN_BYTES_MAX: f64 = 68.36;

/// The ground station's arguments for a steady window: [`WARMUP_S`], then [`WINDOW_S`].
pub fn steady_args() -> Vec<String> {
    [
        "--scenario",
        "telemetry",
        "--listen",
        &(WARMUP_S + WINDOW_S).to_string(),
        "--warmup",
        &WARMUP_S.to_string(),
    ]
    .map(String::from)
    .to_vec()
}

/// The longest a steady-window session may take.
pub const STEADY_BUDGET: Duration = Duration::from_secs(WARMUP_S as u64 + WINDOW_S as u64 + 30);

/// The ground station's steady window and what the radio carried each way in it.
pub struct SteadyWindow {
    pub from: Mono,
    pub to: Mono,
    pub seconds: f64,
    pub down_bytes_per_s: f64,
    pub up_bytes_per_s: f64,
}

impl SteadyWindow {
    /// From the ground station's window events and the radio snapshots they carry.
    pub fn of(report: &SitlReport) -> anyhow::Result<SteadyWindow> {
        let (mut start, mut end) = (None, None);
        for l in &report.ground {
            match l.event {
                GroundEvent::WindowStart { t } => start = Some((t, l.snapshot.clone())),
                GroundEvent::WindowEnd { t } => end = Some((t, l.snapshot.clone())),
                _ => {}
            }
        }
        let ((from, s0), (to, s1)) = start.zip(end).context("the ground station's window")?;
        let seconds = to.since(from).as_secs_f64();
        Ok(SteadyWindow {
            from,
            to,
            seconds,
            down_bytes_per_s: (s1.0.bytes_sent - s0.0.bytes_sent) as f64 / seconds,
            up_bytes_per_s: (s1.1.bytes_sent - s0.1.bytes_sent) as f64 / seconds,
        })
    }
}

/// The position figures every scenario that watches telemetry records.
pub struct PositionHandles {
    pub rate: Handle,
    pub age_p50: Handle,
    pub age_p95: Handle,
    pub age_max: Handle,
    pub gap_max: Handle,
}

impl PositionHandles {
    /// Declares them for `t`; `limits` puts the freshness targets on them (telemetry
    /// phases), else only `min_rate` (e.g. during a parameter download).
    pub fn declare(d: &mut Declarations, t: &Target, limits: bool, min_rate: f64) -> Self {
        let lossy = t.lossy();
        let rate = t
            .spec("position_hz", "Hz")
            .describe(
                "new GLOBAL_POSITION_INT samples (distinct time_boot_ms) the ground station got \
                 per second of the window",
            )
            .at_least(min_rate);
        let age = |q: &str| {
            t.spec(&format!("position_age_{q}_s"), "s")
                .describe(format!(
                    "{q} of the positions' age at the ground: arrival minus the sample's \
                 time_boot_ms on the vehicle clock, mapped by the truth connection"
                ))
        };
        let age_p95 = if limits && !lossy {
            age("p95").at_most(1.0)
        } else {
            age("p95")
        };
        let gap = t
            .spec("position_gap_max_s", "s")
            .describe("longest time the ground station got no newer position");
        let gap = match (limits, lossy) {
            (true, false) => gap.at_most(1.5),
            (true, true) => gap.at_most(3.0),
            _ => gap,
        };
        PositionHandles {
            rate: d.declare(rate),
            age_p50: d.declare(age("p50")),
            age_p95: d.declare(age_p95),
            age_max: d.declare(age("max")),
            gap_max: d.declare(gap),
        }
    }

    pub fn record(&self, ctx: &mut PhaseContext, f: &freshness::Freshness) {
        ctx.record(self.rate, f.rate_hz);
        ctx.record(self.age_p50, f.age_p50_s);
        ctx.record(self.age_p95, f.age_p95_s);
        ctx.record(self.age_max, f.age_max_s);
        ctx.record(self.gap_max, f.gap_max_s);
    }
}

fn plan(d: &mut Declarations, t: &Target) -> Script {
    let min_rate = if t.lossy() { 2.5 } else { 2.9 };
    let positions = PositionHandles::declare(d, t, true, min_rate);
    let down = d.declare(
        t.spec("down_bytes_per_s", "B/s")
            .describe("UAV→GCS bytes the emulated radio put on air over the window")
            .at_most(DOWN_BYTES_MAX),
    );
    let up = d.declare(
        t.spec("up_bytes_per_s", "B/s")
            .describe("GCS→UAV bytes the emulated radio put on air over the window"),
    );
    Box::new(move |ctx, defaults: &SessionDefaults, t: &Target| {
        let dir = ctx.dir.clone();
        let report = run(
            ctx,
            options(defaults, t, &dir, steady_args(), STEADY_BUDGET),
        )?;
        let w = SteadyWindow::of(&report)?;
        let (from, to) = (w.from, w.to);
        ctx.record(down, w.down_bytes_per_s);
        ctx.record(up, w.up_bytes_per_s);
        let ground: Vec<_> = report
            .ground_events()
            .filter_map(|e| match e {
                GroundEvent::Position(p) => Some(*p),
                _ => None,
            })
            .collect();
        let Some(f) = freshness::judge(&ground, &report.clock(), from, to) else {
            bail!(
                "no position reached the ground station in the window ({} positions in all, {} \
                 clock samples)",
                ground.len(),
                report.clock().len()
            );
        };
        positions.record(ctx, &f);
        freshness::attach_series(ctx, &f)?;
        Ok(())
    })
}
