//! Attenuation sweep per radio, as the paper's Fig. 1 (section III-B): a sender emits a
//! MAVLink message of known size at 2 Hz through a step attenuator; the receiver logs how
//! many arrive and how far apart. Here the sender is the simulated flight controller
//! streaming only `HEARTBEAT` at 2 Hz (21 bytes: the radio model's reference packet), the
//! attenuator is the downlink's path loss, stepped 1 dB at a time around the preset's edge.
//!
//! The *nominal edge* is the highest attenuation up to which every step is nominal: at most
//! 1 % lost and a mean arrival period within 5 % of 500 ms. Its free-space range at the
//! preset's frequency is the paper's "range in an ideal world".

use std::fmt::Write as _;
use timebase::Duration;

use anyhow::{Context, Result};
use harness_sim::{Px4Fc, StreamSpec};
use mavlora::Instant;
use mavlora::wire::ids;

use super::{Radios, Scenario, Script, evidence_dir, spec};
use crate::measurement::{Declarations, Dimension, Handle};
use crate::runner::PhaseContext;
use harness_radio::loss::free_space_range_km;
use harness_radio::{Direction, LinkBudget, PathLoss, Preset, RadioSetup};
use harness_sim::{World, secs};

pub const SCENARIO: Scenario = Scenario {
    name: "attenuation_sweep",
    summary: "Fig. 1: HEARTBEAT at 2 Hz through each radio at 1 dB attenuation steps; loss and arrival period per step, nominal edge and its free-space range",
    plan,
};

/// The bench's sender: one 21-byte frame every 500 ms.
pub const SOURCE: &[StreamSpec] = &[StreamSpec {
    id: ids::HEARTBEAT,
    hz: 2.0,
    payload_len: 9,
}];
/// Messages per step: enough that 1 % is 10 messages, not a coin flip on one.
pub const MESSAGES_PER_STEP: u32 = 1000;
/// Largest loss of a nominal step.
pub const NOMINAL_LOSS: f64 = 0.01;
/// Steps below and above the preset's fitted edge.
pub const BELOW_DB: i32 = 8;
pub const ABOVE_DB: i32 = 6;
/// How far (dB) our edge may sit from the paper's and still reproduce it.
pub const EDGE_TOLERANCE_DB: f64 = 3.0;

/// The paper's edge (dB) and free-space range (m) for a preset it measured.
pub fn paper_edge(preset: &str) -> Option<(f64, f64)> {
    match preset {
        "sik-64k" => Some((84.0, 873.0)),
        "lora-sf7" => Some((120.0, 55_100.0)),
        "dmd-dl1" => Some((71.0, 191.0)),
        _ => None,
    }
}

/// `sik-64k` → `sik_64k`.
pub fn key(preset: &str) -> String {
    preset.replace('-', "_")
}

/// A radio's edge and range; `None` for a radio whose preset does not resolve (the sweep
/// fails on it before recording anything).
type Measured = Option<(Handle, Handle)>;

fn plan(d: &mut Declarations, radios: &Radios) -> Script {
    let mut measured = Vec::new();
    for setup in &radios.sweep {
        let Ok(preset) = setup.preset.resolve() else {
            measured.push(None);
            continue;
        };
        let radio =
            |base: &str, unit: &str| spec(base, unit).dim(Dimension::Radio, key(&preset.name));
        let mut edge = radio("nominal_edge_db", "dB").describe(
            "highest attenuation up to which every 1 dB step lost ≤ 1 % of 1000 HEARTBEATs sent \
             at 2 Hz with their mean arrival period within 5 % of 500 ms",
        );
        let mut range = radio("nominal_range_m", "m").describe(
            "free-space distance at the preset's frequency whose path loss is the nominal edge \
             (0 dBi antennas): the paper's \"range in an ideal world\"",
        );
        if let Some((db, m)) = paper_edge(&preset.name) {
            edge = edge.between(db - EDGE_TOLERANCE_DB, db + EDGE_TOLERANCE_DB);
            let f = 10f64.powf(EDGE_TOLERANCE_DB / 20.0);
            range = range.between((m / f).round(), (m * f).round());
        }
        measured.push(Some((d.declare(edge), d.declare(range))));
    }
    Box::new(move |ctx, radios| run(ctx, radios, &measured))
}

/// One attenuation step.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// Attenuation, dB.
    pub attenuation_db: f64,
    /// Messages sent.
    pub sent: u64,
    /// Messages received.
    pub received: u64,
    /// Mean time between arrivals, ms (NaN with fewer than two).
    pub mean_period_ms: f64,
    /// Longest time between arrivals, ms.
    pub max_period_ms: f64,
}

impl Step {
    /// Lost share.
    pub fn loss(&self) -> f64 {
        1.0 - self.received as f64 / self.sent.max(1) as f64
    }

    /// Whether the link is nominal at this step.
    pub fn nominal(&self) -> bool {
        self.loss() <= NOMINAL_LOSS && (self.mean_period_ms / 500.0 - 1.0).abs() <= 0.05
    }
}

/// Runs one step: a fresh world at `db` on the downlink.
pub fn step(radios: &Radios, setup: &RadioSetup, db: f64) -> Result<Step> {
    let mut s = radios.seeded(setup);
    // every step draws its own losses
    s.downlink.seed = super::mix(s.downlink.seed, db.to_bits());
    s.downlink.budget = LinkBudget {
        path: PathLoss::AttenuationDb(db),
        ..s.downlink.budget
    };
    let fc = Px4Fc::new(SOURCE, Instant::ZERO, radios.seed);
    let mut w = World::new(fc, None, Some(&s))?;
    let end = secs(f64::from(MESSAGES_PER_STEP) / 2.0);
    let mut arrivals: Vec<Instant> = Vec::new();
    let mut seen = 0;
    w.run_until_or(end, |w| {
        let n = w.gcs.received.get(&ids::HEARTBEAT).copied().unwrap_or(0);
        if n > seen {
            seen = n;
            arrivals.push(w.now);
        }
        false
    });
    // the last frames sent are still on their way at the end: let them land
    w.fc = Px4Fc::new(&[], w.now, 0);
    let drain = w.now + Duration::from_secs(2);
    w.run_until_or(drain, |w| {
        let n = w.gcs.received.get(&ids::HEARTBEAT).copied().unwrap_or(0);
        if n > seen {
            seen = n;
            arrivals.push(w.now);
        }
        false
    });
    let gaps: Vec<f64> = arrivals
        .windows(2)
        .map(|p| p[1].saturating_duration_since(p[0]).as_secs_f64() * 1000.0)
        .collect();
    let mean = if gaps.is_empty() {
        f64::NAN
    } else {
        gaps.iter().sum::<f64>() / gaps.len() as f64
    };
    Ok(Step {
        attenuation_db: db,
        sent: w.sent(Direction::Downlink).frames_of(&[ids::HEARTBEAT]),
        received: w.gcs.received.get(&ids::HEARTBEAT).copied().unwrap_or(0),
        mean_period_ms: mean,
        max_period_ms: gaps.iter().copied().fold(f64::NAN, f64::max),
    })
}

/// The whole sweep of one radio.
pub fn sweep(radios: &Radios, setup: &RadioSetup) -> Result<(Preset, Vec<Step>)> {
    let preset = setup.preset.resolve()?;
    let centre = preset.nominal_edge_db().round() as i32;
    let steps = (centre - BELOW_DB..=centre + ABOVE_DB)
        .map(|db| step(radios, setup, f64::from(db)))
        .collect::<Result<Vec<_>>>()?;
    Ok((preset, steps))
}

/// The highest attenuation with every step up to it nominal.
pub fn nominal_edge(steps: &[Step]) -> Option<f64> {
    steps
        .iter()
        .take_while(|s| s.nominal())
        .last()
        .map(|s| s.attenuation_db)
}

fn run(ctx: &mut PhaseContext, radios: &Radios, measured: &[Measured]) -> Result<()> {
    let mut csv = String::from(
        "preset,attenuation_db,free_space_range_m,sent,received,loss_pct,mean_period_ms,max_period_ms,nominal\n",
    );
    for (setup, m) in radios.sweep.iter().zip(measured) {
        let (preset, steps) = sweep(radios, setup)?;
        let (edge, range) = (*m).context("a radio without measurements")?;
        for s in &steps {
            writeln!(
                csv,
                "{},{},{:.1},{},{},{:.2},{:.1},{:.1},{}",
                preset.name,
                s.attenuation_db,
                free_space_range_km(s.attenuation_db, preset.frequency_mhz) * 1000.0,
                s.sent,
                s.received,
                100.0 * s.loss(),
                s.mean_period_ms,
                s.max_period_ms,
                s.nominal()
            )?;
        }
        match nominal_edge(&steps) {
            Some(db) => {
                ctx.record(edge, db);
                ctx.record(
                    range,
                    free_space_range_km(db, preset.frequency_mhz) * 1000.0,
                );
            }
            None => {
                ctx.record(edge, f64::NAN);
                ctx.record(range, f64::NAN);
                ctx.annotate(edge, "not nominal even at the lowest step");
            }
        }
        if let Some((db, m)) = paper_edge(&preset.name) {
            ctx.annotate(edge, &format!("paper: {db} dB"));
            ctx.annotate(range, &format!("paper: {m} m"));
        }
    }
    let dir = evidence_dir(ctx)?;
    let path = dir.join("attenuation_sweep.csv");
    std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))?;
    ctx.attach(
        "attenuation sweep (loss and period per step)",
        path,
        "text/csv",
    );
    Ok(())
}
