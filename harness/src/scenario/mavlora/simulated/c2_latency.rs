//! Command-and-control latency under loss (SORA OSO#6 / TMPR: < 3 s at medium robustness):
//! the ground station sends commands one at a time through the MavLora relay and the radio
//! at 10 % loss both ways, resending after 1.5 s without an ack; the router resends on the
//! radio on its own round-trip timeout (the command relay); PX4 acks each copy it gets.
//! Latency: first copy sent → first ack received. A command given up (5 copies, no ack)
//! counts as infinitely late, so it cannot hide in the percentiles.

use timebase::Duration;

use anyhow::Result;
use harness_sim::profiles::PX4_COMPACT_TOML;
use harness_sim::{CommandPlan, CommandStats, Flight, PX4_NORMAL, Px4Fc, Route};
use mavlora::Instant;

use super::{Radios, Scenario, Script, mavlora_configs, quantile, spec};
use crate::measurement::{Declarations, Handle};
use crate::scenario::PhaseContext;
use harness_radio::Direction;
use harness_sim::{World, secs};

pub const SCENARIO: Scenario = Scenario {
    name: "c2_latency",
    summary: "C2 latency: 200 commands (COMMAND_LONG → COMMAND_ACK, ground retries 1.5 s, router resends on the radio's round trip) through the relay at 10 % loss both ways",
    plan,
};

/// Commands measured.
pub const COMMANDS: u64 = 200;
/// SORA medium-robustness C2 latency bound, ms.
pub const TMPR_MEDIUM_MS: f64 = 3000.0;
const WARM_UP_S: f64 = 10.0;

fn plan(d: &mut Declarations, _: &Radios) -> Script {
    let what = "command → ack latency over 200 commands through bridge, radio (10 % loss both \
                ways) and router (resending on the measured round trip), ground station \
                resending after 1.5 s; unacknowledged commands count as infinite";
    let p50 = d.declare(
        spec("c2_latency_p50_ms", "ms")
            .describe(format!("median {what}"))
            .at_most(TMPR_MEDIUM_MS),
    );
    let p99 = d.declare(
        spec("c2_latency_p99_ms", "ms")
            .describe(format!(
                "99th percentile {what}; SORA medium robustness (TMPR) asks < 3 s"
            ))
            .at_most(TMPR_MEDIUM_MS),
    );
    Box::new(move |ctx, radios| run(ctx, radios, [p50, p99]))
}

/// Latencies in ms, sorted, failures as infinity; and the loop's counters.
pub fn measure(radios: &Radios) -> Result<(Vec<f64>, CommandStats)> {
    measure_with(radios, CommandPlan::default(), None)
}

/// As [`measure`], with another ground-station retry policy and, if given, the router's
/// sends per command (1: no resends by the router, the ground's retries only).
pub fn measure_with(
    radios: &Radios,
    plan: CommandPlan,
    router_attempts: Option<u32>,
) -> Result<(Vec<f64>, CommandStats)> {
    let setup = radios.seeded(&radios.c2);
    let preset = setup.preset.resolve()?;
    let fc =
        Px4Fc::new(PX4_NORMAL, Instant::ZERO, radios.seed).with_flight(Flight::Route(Route::PAPER));
    let mut mavlora = mavlora_configs(PX4_COMPACT_TOML, "px4-compact.toml", true, Some(&preset))?;
    if let Some(n) = router_attempts {
        mavlora.1.command_attempts = n;
    }
    let mut w = World::new(fc, Some(mavlora), Some(&setup))?;
    w.run_until(secs(WARM_UP_S));
    w.gcs.start_commands(plan, w.now);
    // Worst case per command: every copy lost, then the pause.
    let worst = plan.retry * plan.attempts + plan.period;
    let cap = w.now + worst * COMMANDS as u32 + Duration::from_secs(10);
    let done = w.run_until_or(cap, |w| {
        let s = w.gcs.command_stats();
        s.acked + s.failed >= COMMANDS
    });
    anyhow::ensure!(done, "{COMMANDS} commands did not finish by {cap:?}");
    let stats = w.gcs.command_stats();
    let mut ms: Vec<f64> = stats
        .latencies
        .iter()
        .map(|d| d.as_secs_f64() * 1000.0)
        .chain((0..stats.failed).map(|_| f64::INFINITY))
        .collect();
    ms.sort_by(f64::total_cmp);
    let link = |d| w.link_stats(d).unwrap_or_default();
    tracing::debug!(down = ?link(Direction::Downlink), up = ?link(Direction::Uplink), "c2 radio");
    Ok((ms, stats))
}

fn run(ctx: &mut PhaseContext, radios: &Radios, [p50_m, p99_m]: [Handle; 2]) -> Result<()> {
    let (ms, stats) = measure(radios)?;
    let p50 = quantile(&ms, 0.50);
    let p99 = quantile(&ms, 0.99);
    ctx.record(p50_m, p50);
    ctx.record(p99_m, p99);
    let retried = stats.copies - stats.started;
    let over = ms.iter().filter(|&&m| m > TMPR_MEDIUM_MS).count();
    let note = format!(
        "{} commands, {} acked, {} given up, {retried} resent copies; {over} above 3 s; \
         best {:.0} ms, worst {:.0} ms",
        stats.started,
        stats.acked,
        stats.failed,
        ms.first().copied().unwrap_or(f64::NAN),
        ms.last().copied().unwrap_or(f64::NAN)
    );
    ctx.annotate(p99_m, &note);
    ctx.log(note);
    // For the reader: the same link without the router's resends, the ground's 1.5 s
    // retries alone (the paper's setup), and with MAVSDK's 0.5 s retries alone.
    for (label, retry) in [("1.5 s", 1500), ("0.5 s", 500)] {
        let plan = CommandPlan {
            retry: Duration::from_millis(retry),
            ..CommandPlan::default()
        };
        let (ms, _) = measure_with(radios, plan, Some(1))?;
        ctx.log(format!(
            "for comparison, without the router's resends, ground retrying after {label}: \
             p50 {:.0} ms, p99 {:.0} ms",
            quantile(&ms, 0.5),
            quantile(&ms, 0.99)
        ));
    }
    Ok(())
}
