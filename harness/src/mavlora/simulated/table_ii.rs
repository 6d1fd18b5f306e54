//! Table II of the paper (section VI-A): the same 513 s flight (the 4 km route at 10 m/s,
//! 100 m) with four ways of fitting PX4's telemetry to a radio, counted UAV → GCS:
//!
//! - `wired`: PX4's default USB profile ([`PX4_CONFIG`]), no bridge, counted on the wire;
//! - `limit`: the bridge sets PX4's stream rates (`px4-normal.toml`'s `stream_hz` only);
//! - `limit_filter`: `px4-normal.toml` as shipped (rates and radio filter);
//! - `compact`: `px4-compact.toml` with compact telemetry.
//!
//! The same four rows are flown with the ArduPilot-like flight controller
//! ([`ArduPilotFc`], dimension `autopilot = ardupilot`): MAVLink 1, every stream group at
//! 4 Hz (~3.7 kB/s, ardupilotmega messages included) and the stream requests *ignored*, so
//! limiting at the flight controller does nothing and only the bridge's filter and budget
//! count: `limit` is `ardupilot-mavlink1.toml`'s `[data_streams]` only, `limit_filter` the
//! whole file, `compact` `ardupilot-compact.toml`. For those rows the ground's position
//! rate and lag are recorded too (position at the profile's 3 Hz, the paper's position
//! update need; lag p99 <= 1.5 batch periods, the project's bound: 3 s in compact, whose
//! batch is 2 s; 0.5 s in `limit_filter`, whose "batch" is one position frame every 1/3 s).
//!
//! The paper ran the first over a wire and the others over SiK radios 50 cm apart; its
//! figures are what the GCS received, losses excluded. Here the bridge variants are counted
//! at the bridge's radio output, on an ideal wire unless the rig names a radio
//! ([`Radios::table_ii`]): the figures are what each mechanism sends, not what a congested
//! radio lets through.

use anyhow::Result;
use harness_sim::profiles::{
    ARDUPILOT_COMPACT_TOML, ARDUPILOT_MAVLINK1_TOML, PX4_COMPACT_TOML, PX4_NORMAL_TOML, stream_only,
};
use harness_sim::{ArduPilotConfig, ArduPilotFc, Autopilot, Flight, PX4_CONFIG, Px4Fc, Route};
use mavlora::Instant;
use mavlora::compact::CompactConfig;

use super::{Radios, Scenario, Script, mavlora_configs, spec};
use crate::measurement::{Declarations, Dimension, Handle, PX4};
use crate::runner::PhaseContext;
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

/// [`Dimension::Autopilot`] of the ArduPilot-like rows.
pub const ARDUPILOT: &str = "ardupilot";

/// A variant's measurements: bytes and messages per second; for the ArduPilot rows with a
/// bridge, the ground's position rate and lag.
struct Measured {
    autopilot: &'static str,
    variant: &'static str,
    bytes_per_s: Handle,
    msgs_per_s: Handle,
    position: Option<(Handle, Handle)>,
}

fn plan(d: &mut Declarations, radios: &Radios) -> Script {
    let carrier = match &radios.table_ii {
        None => "an ideal wire".to_string(),
        Some(s) => format!("the rig's {} radio", preset_name(s)),
    };
    let mut measured = Vec::new();
    for autopilot in [PX4, ARDUPILOT] {
        for row in paper_table() {
            measured.push(declare(d, autopilot, row, &carrier));
        }
    }
    Box::new(move |ctx, radios| run(ctx, radios, &measured))
}

fn declare(
    d: &mut Declarations,
    autopilot: &'static str,
    row: PaperRow,
    carrier: &str,
) -> Measured {
    let v = row.variant;
    let fc = if autopilot == PX4 {
        "PX4's default profile".to_string()
    } else {
        "the ArduPilot-like FC (MAVLink 1, ~3.7 kB/s over 31 types, stream requests ignored)"
            .to_string()
    };
    let how = if v == "wired" {
        format!(
            "{fc} straight to the ground station over an ideal wire, every frame counted on the wire"
        )
    } else {
        format!(
            "{fc}; frames the bridge hands to the radio, counted at its output (carrier: {carrier}; \
             the paper counted what its GCS received, losses excluded)"
        )
    };
    let variant = |base: &str, unit: &str| {
        spec(base, unit)
            .dim(Dimension::Autopilot, autopilot)
            .dim(Dimension::Variant, v)
    };
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
    let position = (autopilot == ARDUPILOT && matches!(v, "limit_filter" | "compact")).then(|| {
        let hz = d.declare(
            variant("position_hz", "Hz")
                .describe(
                    "GLOBAL_POSITION_INT the ground station received per second, from 10 s \
                     after boot to the end of the flight; the profile asks 3 Hz (paper: 3 Hz \
                     for <= 3.4 m between updates at 10 m/s); 2.9 allows one missed update \
                     in 10 s",
                )
                .at_least(2.9),
        );
        let lag_limit = if v == "compact" {
            1.5 * CompactConfig::default().batch_period.as_secs_f64()
        } else {
            0.5
        };
        let lag = d.declare(
            variant("position_lag_p99_s", "s")
                .describe(format!(
                    "99th percentile of (ground receive time - the position's time_boot_ms); \
                     the project's bound, <= 1.5 batch periods ({lag_limit} s here)"
                ))
                .at_most(lag_limit),
        );
        (hz, lag)
    });
    Measured {
        autopilot,
        variant: v,
        bytes_per_s,
        msgs_per_s,
        position,
    }
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

/// Flies one variant with the PX4-like flight controller.
pub fn fly(radios: &Radios, variant: &'static str) -> Result<Row> {
    let route = Route::PAPER;
    let fc = Px4Fc::new(PX4_CONFIG, Instant::ZERO, radios.seed).with_flight(Flight::Route(route));
    fly_with(radios, variant, fc, [PX4_NORMAL_TOML, PX4_COMPACT_TOML]).map(|(row, _)| row)
}

/// Position at the ground: rate (Hz) from 10 s on, and p99 lag (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionStats {
    /// `GLOBAL_POSITION_INT` received per second.
    pub hz: f64,
    /// 99th percentile lag behind the autopilot's clock, s.
    pub lag_p99_s: f64,
}

/// Flies one variant with the ArduPilot-like flight controller that ignores stream requests.
pub fn fly_ardupilot(radios: &Radios, variant: &'static str) -> Result<(Row, PositionStats)> {
    let config = ArduPilotConfig {
        obey_stream_requests: false,
        ..ArduPilotConfig::default()
    };
    let fc = ArduPilotFc::new(config, Instant::ZERO, radios.seed)
        .with_flight(Flight::Route(Route::PAPER));
    fly_with(
        radios,
        variant,
        fc,
        [ARDUPILOT_MAVLINK1_TOML, ARDUPILOT_COMPACT_TOML],
    )
}

fn fly_with<A: Autopilot>(
    radios: &Radios,
    variant: &'static str,
    fc: A,
    [normal, compact]: [&str; 2],
) -> Result<(Row, PositionStats)> {
    let route = Route::PAPER;
    let radio = radios.table_ii.as_ref().map(|s| radios.seeded(s));
    let preset: Option<Preset> = match &radio {
        Some(s) => Some(s.preset.resolve()?),
        None => None,
    };
    let mavlora = match variant {
        "wired" => None,
        "limit" => Some(mavlora_configs(
            &stream_only(normal),
            "profile (stream rates only)",
            false,
            preset.as_ref(),
        )?),
        "limit_filter" => Some(mavlora_configs(normal, "profile", false, preset.as_ref())?),
        "compact" => Some(mavlora_configs(
            compact,
            "compact profile",
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
    let from = Instant::from_millis(10_000);
    let mut lags: Vec<f64> = w
        .gcs
        .positions
        .iter()
        .filter(|(t, _)| *t >= from)
        .map(|(t, ms)| {
            t.saturating_duration_since(Instant::from_millis(u64::from(*ms)))
                .as_secs_f64()
        })
        .collect();
    let hz = lags.len() as f64 / end.saturating_duration_since(from).as_secs_f64();
    lags.sort_by(f64::total_cmp);
    let lag_p99_s = if lags.is_empty() {
        f64::NAN
    } else {
        super::quantile(&lags, 0.99)
    };
    let row = Row {
        variant,
        flight_s,
        msgs_per_s: w.sent(Direction::Downlink).total_frames() as f64 / flight_s,
        bytes_per_s: w.sent(Direction::Downlink).total_bytes() as f64 / flight_s,
        received_msgs: w.received(Direction::Downlink).total_frames(),
        steps: w.steps(),
    };
    Ok((row, PositionStats { hz, lag_p99_s }))
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
    let mut ardupilot_rows = Vec::new();
    for m in measured {
        let wall = std::time::Instant::now();
        let (row, position) = if m.autopilot == PX4 {
            (fly(radios, m.variant)?, None)
        } else {
            let (row, position) = fly_ardupilot(radios, m.variant)?;
            (row, Some(position))
        };
        ctx.record(m.bytes_per_s, row.bytes_per_s);
        ctx.record(m.msgs_per_s, row.msgs_per_s);
        if let (Some((hz, lag)), Some(p)) = (m.position, position) {
            ctx.record(hz, p.hz);
            ctx.record(lag, p.lag_p99_s);
        }
        ctx.log(format!(
            "{} {}: {:.1} s flight, {} messages reached the ground side, {} clock steps, {:.2} s \
             wall",
            m.autopilot,
            row.variant,
            row.flight_s,
            row.received_msgs,
            row.steps,
            wall.elapsed().as_secs_f64()
        ));
        if m.autopilot == PX4 {
            rows.push(row);
        } else {
            ardupilot_rows.push(row);
        }
    }
    for line in render(&rows).lines() {
        ctx.log(line.to_string());
    }
    ctx.log("ArduPilot-like flight controller (stream requests ignored):".to_string());
    for line in render(&ardupilot_rows).lines() {
        ctx.log(line.to_string());
    }
    Ok(())
}
