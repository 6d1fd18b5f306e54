//! Paper Table II in real time: UAV → GCS bandwidth on a loss-free SiK radio
//! with the bridge's compact telemetry and with limiting + filtering, from a
//! flight controller on PX4's USB "Config" profile (the streams closest to
//! the paper's unfiltered 11,440 B/s).

use anyhow::{Context, Result};

use super::{
    Scenario, Script, Unsigned, ensure_clean, lora_sf7_link_quality_period, run_sessions, spec,
};
use crate::mavlora::fixture::fc::FcEvent;
use crate::mavlora::session::{FcProfile, GcsPlan, SessionDefaults};
use crate::measurement::{Declarations, Dimension, Handle};
use crate::runner::PhaseContext;

const SCENARIO_NAME: &str = "table_ii";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "Table II over ptys, radio signed: radio B/s of compact telemetry (<= 68.4, 10 % of LoRa SF7; marginal above our 50) and of limiting + filtering (<= 951), loss-free SiK",
    plan,
};

/// (variant, profile file, `--compact`, B/s limit, B/s target above which it is marginal)
///
/// Compact's limit is the EU 433 MHz SRD rule (ERC/REC 70-03: a 10 % duty cycle) on a
/// LoRa SF7 channel of 683.6 B/s; 50 B/s is the project's target for compact telemetry, which
/// leaves room under that rule for commands, missions and link monitoring, with every frame
/// carrying signing's 13-byte trailer (why a position batch carries 2 s of samples, not 1 s).
const VARIANTS: [(&str, &str, bool, f64, Option<f64>); 2] = [
    ("compact", "px4-compact.toml", true, 68.36, Some(50.0)),
    ("limit_filter", "px4-normal.toml", false, 951.0, None),
];

/// Seconds before the counting window: FC boot, the bridge's
/// SET_MESSAGE_INTERVAL round (acked within ~1 s) and the first compact frames.
const WARMUP_S: f64 = 4.0;
/// Counting window: a multiple of 10 s, so the 5 s LINK_QUALITY and 10 s
/// MAVLORA_STATUS periods fall into it a whole number of times. What is left
/// is phase: a window holds one compact batch (42 B) more or less depending
/// on where it starts, ±1.4 B/s over 30 s. Both variants run side by side,
/// each on its own radio, to keep the wall time at ~40 s.
const WINDOW_S: f64 = 30.0;

/// Far above both limits (SiK 64k carries ~3 kB/s each way), so the limits
/// measure what the profile lets through, not the scheduler's budget.
const RATE: u32 = 3000;

const HOW: &str = "UAV→GCS bytes the emulated radio put on air (its LinkStats, serial bytes), \
     over a 30 s steady-state window that opens 4 s after the GCS starts listening: \
     after the bridge configured the flight controller's stream rates; the start-up \
     traffic (configuration commands and acks, PX4's boot rates) is outside it. \
     FC fixture on PX4's USB Config profile flying the 4 km route; bridge --rate 3000";

/// A variant's measurements: radio bytes and GCS messages per second.
struct Measured {
    bytes_per_s: Handle,
    msgs_per_s: Handle,
}

fn plan(d: &mut Declarations) -> Script {
    let measured: Vec<Measured> = VARIANTS
        .iter()
        .map(|(v, _, _, limit, target)| {
            let variant = |base: &str, unit: &str| spec(base, unit).dim(Dimension::Variant, *v);
            let bytes = variant("bytes_per_s", "B/s")
                .describe(format!("{v}: {HOW}"))
                .at_most(*limit);
            Measured {
                bytes_per_s: d.declare(match target {
                    Some(t) => bytes.marginal_above(*t),
                    None => bytes,
                }),
                msgs_per_s: d.declare(variant("msgs_per_s", "msg/s").describe(format!(
                    "{v}: messages the pymavlink GCS decoded per second over the same window \
                     (after the router's expansion of compact frames; paper: 35.23 with limiting + filtering)"
                ))),
            }
        })
        .collect();
    let unsigned = Unsigned::declare(d, SCENARIO_NAME);
    Box::new(move |ctx, defaults| run(ctx, defaults, &measured, &unsigned))
}

fn run(
    ctx: &mut PhaseContext,
    d: &SessionDefaults,
    measured: &[Measured],
    unsigned: &Unsigned,
) -> Result<()> {
    let mut options = Vec::new();
    for (variant, profile, compact, ..) in VARIANTS {
        let mut o = d.options(
            &format!("table_ii-{variant}"),
            &d.clean_radio,
            &ctx.dir.join(variant),
        );
        o.bridge_profile = d.profile_dir.join(profile);
        o.compact = compact;
        o.rate = RATE;
        o.link_quality_period = Some(lora_sf7_link_quality_period());
        o.fc_profile = FcProfile::Config;
        o.gcs = GcsPlan {
            listen_s: WARMUP_S + WINDOW_S,
            warmup_s: WARMUP_S,
            ..GcsPlan::default()
        };
        options.push(o);
    }
    let reports = run_sessions(ctx, options)?;
    for (((variant, ..), report), m) in VARIANTS.iter().zip(&reports).zip(measured) {
        let (bytes_per_s, secs) = report
            .downlink_rate()
            .context("the GCS reported no counting window")?;
        let t = report
            .gcs
            .telemetry
            .as_ref()
            .context("the GCS fixture ran no telemetry phase")?;
        let msgs = t.msgs_per_s();
        ctx.log(format!(
            "{variant}: window {secs:.2} s; radio {bytes_per_s:.1} B/s; GCS {msgs:.2} msg/s, {:.1} B/s after expansion; by type {:?}",
            t.bytes_per_s(),
            t.by_type
        ));
        ctx.record(m.bytes_per_s, bytes_per_s);
        // Steady state means after the bridge's SET_MESSAGE_INTERVAL round: check it.
        let configured = report
            .fc_events
            .iter()
            .filter(|l| matches!(l.event, FcEvent::Interval { .. }))
            .map(|l| l.at)
            .max();
        let opened = report.window().map(|(start, _)| start.at);
        match (configured, opened) {
            (Some(c), Some(w)) if c <= w => ctx.log(format!(
                "{variant}: stream rates configured {:.2} s before the window opened",
                w.since(c).as_secs_f64()
            )),
            (Some(_), Some(_)) => ctx.annotate(
                m.bytes_per_s,
                "the bridge was still configuring stream rates when the window opened",
            ),
            _ => ctx.annotate(
                m.bytes_per_s,
                "the bridge configured no stream rate (check bridge.log)",
            ),
        }
        ctx.record(m.msgs_per_s, msgs);
    }
    unsigned.record(ctx, &reports.iter().collect::<Vec<_>>())?;
    for r in &reports {
        ensure_clean(ctx, r)?;
    }
    Ok(())
}
