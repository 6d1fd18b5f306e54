//! Duty cycle of compact telemetry on LoRa SF7/125 kHz: the share of time each direction's
//! transmitter is on air over the paper's 513 s flight, against the EU 433 MHz SRD rule
//! (ERC/REC 70-03: 10 mW e.r.p., ≤ 10 % duty cycle) that would make the link legal without
//! the special Danish channels the paper needed. The bridge runs as it would on such a
//! channel: compact frames coalesced for 1.5 s so that two position batches (and any status
//! or link-quality report) share one LoRa packet and its ~30 ms of preamble and header;
//! positions are still sampled at 3 Hz, and reach the ground up to 1.5 s later.

use timebase::Duration;

use anyhow::Result;
use harness_sim::profiles::PX4_COMPACT_TOML;
use harness_sim::{Flight, PX4_NORMAL, Px4Fc, Route};
use mavlora::Instant;

use super::{Radios, Scenario, Script, mavlora_configs, spec};
use crate::measurement::{Declarations, Dimension, Handle};
use crate::runner::PhaseContext;
use harness_radio::{Direction, LinkStats};
use harness_sim::{Counts, World};

pub const SCENARIO: Scenario = Scenario {
    name: "duty_cycle",
    summary: "Duty cycle: compact telemetry (px4-compact.toml, bridge --compact --coalesce-ms 1500) on LoRa SF7/125 kHz over the 513 s flight, airtime share per direction against EU 433 MHz SRD's 10 %",
    plan,
};

/// EU 433 MHz SRD duty-cycle limit, %.
pub const EU_SRD_PCT: f64 = 10.0;

fn plan(d: &mut Declarations, _: &Radios) -> Script {
    let lora = |base: &str| spec(base, "%").dim(Dimension::Radio, "lora_sf7");
    let down = d.declare(
        lora("duty_cycle_pct")
            .describe(
                "UAV→GCS airtime ÷ flight time, compact telemetry through the bridge with \
                 frames coalesced for 1.5 s, whole 513 s flight; EU 433 MHz SRD allows 10 %",
            )
            .at_most(EU_SRD_PCT),
    );
    let up = d.declare(lora("uplink_duty_cycle_pct").describe(
        "GCS→UAV airtime ÷ flight time (the router's thinned ground heartbeats and \
         LINK_QUALITY), same flight",
    ));
    Box::new(move |ctx, radios| run(ctx, radios, down, up))
}

/// What the flight put on air.
#[derive(Debug, Clone)]
pub struct Duty {
    /// UAV→GCS airtime share, %.
    pub down_pct: f64,
    /// GCS→UAV airtime share, %.
    pub up_pct: f64,
    /// The radio's counters, UAV→GCS.
    pub down: LinkStats,
    /// The radio's counters, GCS→UAV.
    pub up: LinkStats,
    /// Frames the bridge handed to the radio.
    pub downlink_sent: Counts,
    /// Flight time, s.
    pub flight_s: f64,
}

/// How long the bridge coalesces compact frames on a duty-cycled channel.
pub const COALESCE: Duration = Duration::from_millis(1500);

/// Flies the route and measures the airtime shares, frames coalesced for [`COALESCE`].
pub fn measure(radios: &Radios) -> Result<Duty> {
    measure_with(radios, None, COALESCE)
}

/// As [`measure`], with the bridge's and router's `LINK_QUALITY` period changed and another
/// coalescing time (zero: each frame when ready).
pub fn measure_with(
    radios: &Radios,
    quality_period: Option<Duration>,
    coalesce: Duration,
) -> Result<Duty> {
    let setup = radios.seeded(&radios.duty);
    let preset = setup.preset.resolve()?;
    let route = Route::PAPER;
    let fc = Px4Fc::new(PX4_NORMAL, Instant::ZERO, radios.seed).with_flight(Flight::Route(route));
    let mut mavlora = mavlora_configs(PX4_COMPACT_TOML, "px4-compact.toml", true, Some(&preset))?;
    if let Some(p) = quality_period {
        mavlora.0.quality.period = p;
        mavlora.1.quality.period = p;
    }
    if let Some(c) = &mut mavlora.0.compact {
        c.coalesce = coalesce;
    }
    let mut w = World::new(fc, Some(mavlora), Some(&setup))?;
    w.run_until(Instant::ZERO + route.duration());
    let flight = route.duration().as_secs_f64();
    let down = w.link_stats(Direction::Downlink).unwrap_or_default();
    let up = w.link_stats(Direction::Uplink).unwrap_or_default();
    let pct = |s: &LinkStats| 100.0 * s.airtime.as_secs_f64() / flight;
    Ok(Duty {
        down_pct: pct(&down),
        up_pct: pct(&up),
        down,
        up,
        downlink_sent: w.sent(Direction::Downlink).clone(),
        flight_s: flight,
    })
}

fn run(ctx: &mut PhaseContext, radios: &Radios, down: Handle, up: Handle) -> Result<()> {
    let d = measure(radios)?;
    ctx.record(down, d.down_pct);
    ctx.record(up, d.up_pct);
    let bytes_per_s = d.downlink_sent.total_bytes() as f64 / d.flight_s;
    ctx.annotate(
        down,
        &format!(
            "{bytes_per_s:.1} B/s of frames in {} air packets",
            d.down.packets_sent
        ),
    );
    // For the reader: each frame in its own packet, as the bridge sends by default.
    let single = measure_with(radios, None, Duration::ZERO)?;
    ctx.log(format!(
        "for comparison, without coalescing (one frame per packet): UAV→GCS {:.2} % in {} \
         packets, GCS→UAV {:.2} %",
        single.down_pct, single.down.packets_sent, single.up_pct
    ));
    for (label, s) in [("UAV→GCS", &d.down), ("GCS→UAV", &d.up)] {
        ctx.log(format!(
            "{label}: {} air packets, {} bytes, {:.1} s on air, mean packet {:.1} bytes",
            s.packets_sent,
            s.bytes_sent,
            s.airtime.as_secs_f64(),
            s.bytes_sent as f64 / s.packets_sent.max(1) as f64
        ));
    }
    Ok(())
}
