//! `mavlora::bench::attenuation_sweep`: the paper's Fig. 1 on the rig's RF path (section
//! III-B): at each step of the attenuator, HEARTBEATs at a fixed rate through the drone's
//! radio, counted at the ground's; loss and arrival period per step, what the radios said of
//! the link (`RADIO_STATUS`), and the nominal edge: the highest attenuation up to which every
//! step lost at most 1 %.
//!
//! The attenuator is driven through its real driver (Mini-Circuits over Telnet), in CI too
//! (the emulated unit steps the radio emulator). A step the attenuator refuses, or a unit that
//! goes away mid-sweep, ends the sweep with an error naming the unit; the points measured
//! before it are kept in the CSV and the report.

use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};

use super::path::{Emulated, RfPath};
use super::probe::{Probe, StepCount};
use super::rigfile::BenchPlan;
use crate::driver::attenuator::AttenuatorRecord;
use crate::mavlora::simulated::sweep::{EDGE_TOLERANCE_DB, NOMINAL_LOSS, key, paper_edge};
use crate::measurement::{Declarations, Dimension, Handle, Spec};
use crate::runner::PhaseContext;

pub const NAME: &str = "attenuation_sweep";
pub const SUMMARY: &str = "Fig. 1 on the rig's RF path: HEARTBEATs through the radios at each attenuator step (real driver), loss, period and RADIO_STATUS per step, and the nominal edge";

/// How long after a step's last send its frames may still land (the radio's latency and
/// buffer: SiK's TDM holds a frame up to a few hundred ms).
const DRAIN: Duration = Duration::from_secs(1);

/// One measured step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// Total path attenuation (pads plus attenuator), dB.
    pub path_db: f64,
    /// What the attenuator confirmed, dB.
    pub attenuator_db: f64,
    pub count: StepCount,
}

impl Point {
    pub fn loss(&self) -> f64 {
        1.0 - self.count.received as f64 / self.count.sent.max(1) as f64
    }

    pub fn nominal(&self) -> bool {
        self.loss() <= NOMINAL_LOSS
    }
}

/// A sweep's outcome: the points measured, and the error that stopped it early.
pub struct Outcome {
    pub points: Vec<Point>,
    pub attenuator: AttenuatorRecord,
    /// Both SiK radios, when the path's radios run SiK.
    pub sik: Option<crate::driver::sik::SikRecord>,
    pub error: Option<anyhow::Error>,
}

/// The highest attenuation with every step up to it nominal.
pub fn nominal_edge(points: &[Point]) -> Option<f64> {
    points
        .iter()
        .take_while(|p| p.nominal())
        .last()
        .map(|p| p.path_db)
}

/// Runs the sweep of `plan` (with emulated `parts` other than the plan's, for tests).
pub fn run_sweep(plan: &BenchPlan, parts: Emulated) -> Result<Outcome> {
    let mut path = RfPath::open_with(plan, parts)?;
    let attenuator = path.attenuator.record();
    let sik = path.sik.clone();
    let mut probe = Probe::open(&path.air_port, &path.ground_port, path.baud)?;
    let mut points = Vec::new();
    for (i, path_db) in plan.sweep.points().into_iter().enumerate() {
        let wanted = path_db - plan.fixed_db;
        let setting = match path.attenuator.set_db(wanted) {
            Ok(s) => s,
            Err(e) => {
                return Ok(Outcome {
                    points,
                    attenuator,
                    sik,
                    error: Some(anyhow::Error::new(e).context(format!(
                        "attenuator step to {wanted} dB (path {path_db} dB, step {} of {})",
                        i + 1,
                        plan.sweep.points().len()
                    ))),
                });
            }
        };
        let step = u16::try_from(i).context("more than 65,535 steps")?;
        let count = probe.step(step, plan.sweep.messages, plan.sweep.hz, DRAIN)?;
        tracing::info!(
            path_db,
            attenuator_db = setting.db,
            sent = count.sent,
            received = count.received,
            "bench sweep step"
        );
        points.push(Point {
            path_db: plan.fixed_db + setting.db,
            attenuator_db: setting.db,
            count,
        });
    }
    Ok(Outcome {
        points,
        attenuator,
        sik,
        error: None,
    })
}

/// The sweep as CSV.
pub fn csv(points: &[Point]) -> String {
    let mut csv = String::from(
        "path_db,attenuator_db,sent,received,loss_pct,mean_period_ms,nominal,radio_reports,rssi,remrssi,noise,min_txbuf\n",
    );
    for p in points {
        let r = p.count.radio;
        let _ = writeln!(
            csv,
            "{},{},{},{},{:.2},{:.1},{},{},{:.1},{:.1},{:.1},{}",
            p.path_db,
            p.attenuator_db,
            p.count.sent,
            p.count.received,
            100.0 * p.loss(),
            p.count.mean_period_ms,
            p.nominal(),
            r.reports,
            r.rssi,
            r.remrssi,
            r.noise,
            r.min_txbuf
        );
    }
    csv
}

/// The phase's measurements.
pub struct Measured {
    edge: Handle,
    points: Handle,
}

fn spec(base: &str, unit: &str, radio: &str) -> Spec {
    Spec::new(base, unit)
        .dim(Dimension::Device, "mavlora")
        .dim(Dimension::Transport, "bench")
        .dim(Dimension::Radio, key(radio))
}

/// Declares the sweep's measurements: the edge, against the paper's where the path is a
/// radio the paper measured (emulated), recorded without a limit for real radios (their
/// edge is what the bench is for); and every point measured.
pub fn declare(d: &mut Declarations, plan: &BenchPlan) -> Measured {
    let radio = plan.path.label();
    let mut edge = spec("nominal_edge_db", "dB", &radio).describe(
        "highest total path attenuation (pads plus attenuator) up to which every step lost at \
         most 1 % of its HEARTBEATs",
    );
    if let Some((db, _)) = plan.path.preset().and_then(|p| paper_edge(&p.name)) {
        edge = edge.between(db - EDGE_TOLERANCE_DB, db + EDGE_TOLERANCE_DB);
    }
    let n = plan.sweep.points().len() as f64;
    let points = spec("sweep_points", "", &radio)
        .describe("attenuator steps measured; fewer than planned: the attenuator stopped the sweep")
        .equal_to(n);
    Measured {
        edge: d.declare(edge),
        points: d.declare(points),
    }
}

/// The phase's script.
pub fn run(ctx: &mut PhaseContext, plan: &BenchPlan, m: &Measured) -> Result<()> {
    let outcome = run_sweep(plan, Emulated::default())?;
    let dir = ctx.dir.join("bench");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    keep(ctx, &dir, plan, &outcome)?;
    ctx.record(m.points, outcome.points.len() as f64);
    match nominal_edge(&outcome.points) {
        Some(db) => ctx.record(m.edge, db),
        None => {
            ctx.record(m.edge, f64::NAN);
            ctx.annotate(m.edge, "not nominal even at the lowest step");
        }
    }
    if let Some((db, _)) = plan.path.preset().and_then(|p| paper_edge(&p.name)) {
        ctx.annotate(m.edge, &format!("paper: {db} dB"));
    }
    match outcome.error {
        Some(e) => Err(e.context(format!(
            "the sweep stopped after {} of {} points (kept in bench/attenuation_sweep.csv)",
            outcome.points.len(),
            plan.sweep.points().len()
        ))),
        None => Ok(()),
    }
}

fn keep(ctx: &mut PhaseContext, dir: &Path, plan: &BenchPlan, outcome: &Outcome) -> Result<()> {
    let csv_path = dir.join("attenuation_sweep.csv");
    std::fs::write(&csv_path, csv(&outcome.points))
        .with_context(|| format!("writing {}", csv_path.display()))?;
    ctx.attach(
        "bench sweep (loss, period, RADIO_STATUS per step)",
        csv_path,
        "text/csv",
    );
    let resources = serde_json::json!({
        "radio": plan.path.label(),
        "fixed_db": plan.fixed_db,
        "attenuator": outcome.attenuator,
        "sik": outcome.sik,
    });
    let json_path = dir.join("resources.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&resources)?)
        .with_context(|| format!("writing {}", json_path.display()))?;
    ctx.attach(
        "bench resources (attenuator, radios)",
        json_path,
        "application/json",
    );
    if let Some(sik) = &outcome.sik {
        ctx.log(format!(
            "SiK radios on {}: local {:?}, remote {:?}",
            sik.port, sik.local.banner, sik.remote.banner
        ));
    }
    let a = &outcome.attenuator;
    ctx.log(format!(
        "attenuator: {} {} serial {} at {}, {}..{} dB in {} dB steps",
        a.vendor, a.model, a.serial, a.address, a.range_db.min, a.range_db.max, a.step_db
    ));
    Ok(())
}

/// The phase for `plan`.
pub fn phase(plan: Arc<BenchPlan>) -> crate::runner::Phase {
    let mut declared = Declarations::new();
    let measured = declare(&mut declared, &plan);
    crate::runner::Phase::measured(
        format!("mavlora::bench::{NAME}"),
        SUMMARY,
        declared,
        move |ctx| run(ctx, &plan, &measured),
    )
}

#[cfg(test)]
mod tests;
