//! Table II of the paper (section VI-A): the same 513 s flight (the 4 km route at 10 m/s,
//! 100 m) with four ways of fitting PX4's telemetry to a radio, counted UAV → GCS:
//!
//! - `wired`: PX4's default USB profile ([`PX4_CONFIG`]), no bridge, counted on the wire;
//! - `limit`: the bridge sets PX4's stream rates (`px4-normal.toml`'s `stream_hz` only);
//! - `limit_filter`: `px4-normal.toml` as shipped (rates and radio filter);
//! - `compact`: `px4-compact.toml` with compact telemetry.
//!
//! The paper ran the first over a wire and the others over SiK radios 50 cm apart; its
//! figures are what the GCS received, losses excluded. Here the bridge variants are counted
//! at the bridge's radio output, on an ideal wire unless the rig names a radio
//! ([`Radios::table_ii`]): the figures are what each mechanism sends, not what a congested
//! radio lets through.

use anyhow::Result;
use harness_sim::profiles::{PX4_COMPACT_TOML, PX4_NORMAL_TOML, stream_only};
use harness_sim::{Flight, PX4_CONFIG, Px4Fc, Route};
use mavlora::Instant;

use super::{Radios, Scenario, Script, mavlora_configs, spec};
use crate::measurement::{Declarations, Dimension, Handle};
use crate::scenario::PhaseContext;
use harness_radio::{Direction, Preset, RadioSetup};
use harness_sim::World;

pub const SCENARIO: Scenario = Scenario {
    name: "table_ii",
    summary: "Table II: the paper's 513 s flight with PX4's default profile, wired / stream limiting / limiting + filtering / compact telemetry, UAV→GCS bytes and messages per second",
    plan,
};

/// The variants, in the paper's order of decreasing traffic.
pub const VARIANTS: [&str; 4] = ["wired", "limit", "limit_filter", "compact"];

/// One row of the paper's Table II.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperRow {
    /// Variant name, as in [`VARIANTS`].
    pub variant: &'static str,
    /// Messages per second, when the paper gives it.
    pub msgs_per_s: Option<f64>,
    /// Bytes per second (for `compact` an upper bound: "< 100 B/s", future work).
    pub bytes_per_s: f64,
    /// Whether `bytes_per_s` is only a bound.
    pub bound: bool,
}

/// The paper's figures, next to which ours are printed.
pub fn paper_table() -> [PaperRow; 4] {
    [
        PaperRow {
            variant: "wired",
            msgs_per_s: Some(278.13),
            bytes_per_s: 11_440.0,
            bound: false,
        },
        PaperRow {
            variant: "limit",
            msgs_per_s: Some(45.65),
            bytes_per_s: 1_536.0,
            bound: false,
        },
        PaperRow {
            variant: "limit_filter",
            msgs_per_s: Some(35.23),
            bytes_per_s: 951.0,
            bound: false,
        },
        PaperRow {
            variant: "compact",
            msgs_per_s: None,
            bytes_per_s: 100.0,
            bound: true,
        },
    ]
}

/// One variant's result.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Variant name.
    pub variant: &'static str,
    /// Flight time, s.
    pub flight_s: f64,
    /// UAV → GCS messages per second.
    pub msgs_per_s: f64,
    /// UAV → GCS bytes per second.
    pub bytes_per_s: f64,
    /// Messages that reached the ground side of the carrier (equal to those sent on a wire).
    pub received_msgs: u64,
    /// Virtual-clock steps (for profiling).
    pub steps: u64,
}

/// A variant's measurements: bytes and messages per second.
struct Measured {
    variant: &'static str,
    bytes_per_s: Handle,
    msgs_per_s: Handle,
}

fn plan(d: &mut Declarations, radios: &Radios) -> Script {
    let carrier = match &radios.table_ii {
        None => "an ideal wire".to_string(),
        Some(s) => format!("the rig's {} radio", preset_name(s)),
    };
    let mut measured = Vec::new();
    for row in paper_table() {
        let v = row.variant;
        let how = if v == "wired" {
            "PX4's USB profile straight to the ground station over an ideal wire, every frame \
             counted on the wire"
                .to_string()
        } else {
            format!(
                "frames the bridge hands to the radio, counted at its output (carrier: {carrier}; \
                 the paper counted what its GCS received, losses excluded)"
            )
        };
        let variant = |base: &str, unit: &str| spec(base, unit).dim(Dimension::Variant, v);
        let bytes = variant("bytes_per_s", "B/s").describe(format!(
            "UAV→GCS bytes per second over the paper's 513 s flight (4 km at 10 m/s, 100 m), \
             variant {v}: {how}; paper: {}{} B/s",
            if row.bound { "< " } else { "" },
            row.bytes_per_s
        ));
        let bytes = match v {
            "limit_filter" => bytes.at_most(951.0),
            "compact" => bytes.at_most(50.0),
            _ => bytes,
        };
        let bytes_per_s = d.declare(bytes);
        let msgs_per_s = d.declare(variant("msgs_per_s", "msg/s").describe(format!(
            "UAV→GCS MAVLink messages per second, same flight and counting, variant {v}; \
             paper: {}",
            row.msgs_per_s
                .map_or("not given".to_string(), |m| format!("{m} msg/s"))
        )));
        measured.push(Measured {
            variant: v,
            bytes_per_s,
            msgs_per_s,
        });
    }
    Box::new(move |ctx, radios| run(ctx, radios, &measured))
}

fn preset_name(s: &RadioSetup) -> String {
    s.preset
        .resolve()
        .map(|p| p.name)
        .unwrap_or_else(|_| "?".into())
}

/// Flies the four variants and returns their rows in [`VARIANTS`] order.
pub fn reproduce(radios: &Radios) -> Result<Vec<Row>> {
    VARIANTS.iter().map(|v| fly(radios, v)).collect()
}

/// Flies one variant.
pub fn fly(radios: &Radios, variant: &'static str) -> Result<Row> {
    let route = Route::PAPER;
    let fc = Px4Fc::new(PX4_CONFIG, Instant::ZERO, radios.seed).with_flight(Flight::Route(route));
    let radio = radios.table_ii.as_ref().map(|s| radios.seeded(s));
    let preset: Option<Preset> = match &radio {
        Some(s) => Some(s.preset.resolve()?),
        None => None,
    };
    let mavlora = match variant {
        "wired" => None,
        "limit" => Some(mavlora_configs(
            &stream_only(PX4_NORMAL_TOML),
            "px4-normal.toml (stream_hz only)",
            false,
            preset.as_ref(),
        )?),
        "limit_filter" => Some(mavlora_configs(
            PX4_NORMAL_TOML,
            "px4-normal.toml",
            false,
            preset.as_ref(),
        )?),
        "compact" => Some(mavlora_configs(
            PX4_COMPACT_TOML,
            "px4-compact.toml",
            true,
            preset.as_ref(),
        )?),
        other => anyhow::bail!("unknown Table II variant {other}"),
    };
    let carrier = if variant == "wired" {
        None
    } else {
        radio.as_ref()
    };
    let mut w = World::new(fc, mavlora, carrier)?;
    let end = Instant::ZERO + route.duration();
    w.run_until(end);
    let flight_s = route.duration().as_secs_f64();
    Ok(Row {
        variant,
        flight_s,
        msgs_per_s: w.sent(Direction::Downlink).total_frames() as f64 / flight_s,
        bytes_per_s: w.sent(Direction::Downlink).total_bytes() as f64 / flight_s,
        received_msgs: w.received(Direction::Downlink).total_frames(),
        steps: w.steps(),
    })
}

/// Our rows next to the paper's, as a text table.
pub fn render(rows: &[Row]) -> String {
    let mut s = format!(
        "{:<13} {:>10} {:>10}   {:>10} {:>10}\n",
        "variant", "B/s", "msg/s", "paper B/s", "paper msg/s"
    );
    for row in rows {
        let paper = paper_table().into_iter().find(|p| p.variant == row.variant);
        let (pb, pm) = paper.map_or(("-".into(), "-".into()), |p| {
            (
                format!("{}{}", if p.bound { "< " } else { "" }, p.bytes_per_s),
                p.msgs_per_s.map_or("-".into(), |m| format!("{m}")),
            )
        });
        s.push_str(&format!(
            "{:<13} {:>10.1} {:>10.2}   {:>10} {:>10}\n",
            row.variant, row.bytes_per_s, row.msgs_per_s, pb, pm
        ));
    }
    s
}

fn run(ctx: &mut PhaseContext, radios: &Radios, measured: &[Measured]) -> Result<()> {
    let mut rows = Vec::new();
    for m in measured {
        let wall = std::time::Instant::now();
        let row = fly(radios, m.variant)?;
        ctx.record(m.bytes_per_s, row.bytes_per_s);
        ctx.record(m.msgs_per_s, row.msgs_per_s);
        ctx.log(format!(
            "{}: {:.1} s flight, {} messages reached the ground side, {} clock steps, {:.2} s \
             wall",
            row.variant,
            row.flight_s,
            row.received_msgs,
            row.steps,
            wall.elapsed().as_secs_f64()
        ));
        rows.push(row);
    }
    for line in render(&rows).lines() {
        ctx.log(line.to_string());
    }
    Ok(())
}
