//! Command-and-control latency under loss (SORA OSO#6 / TMPR: < 3 s at medium robustness):
//! the ground station sends commands one at a time through the MavLora relay and the radio
//! at 10 % loss both ways, resending after 1.5 s without an ack; the router resends on the
//! radio on its own round-trip timeout (the command relay); PX4 acks each copy it gets.
//! Latency: first copy sent → first ack received. A command given up (5 copies, no ack)
//! counts as infinitely late, so it cannot hide in the percentiles.

use timebase::Duration;

use anyhow::Result;
use harness_sim::profiles::PX4_COMPACT_TOML;
use harness_sim::{CommandPlan, CommandStats, Executed, Flight, GcsMock, PX4_NORMAL, Px4Fc, Route};
use mavlora::Instant;

use super::{Radios, Scenario, Script, mavlora_configs, quantile, spec};
use crate::measurement::{Declarations, Dimension, Handle};
use crate::runner::PhaseContext;
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
    let target = |base: &str, unit: &str| spec(base, unit).dim(Dimension::Radio, TARGET_RADIO);
    let what = "command → ack latency over 200 commands (a mix: same id with new parameters, \
                target component 0 or 1) through bridge, SiK 64 kbps radio (10 % loss both \
                ways) and router, ground station resending after 0.5 s; unacknowledged \
                commands count as infinite";
    let fast = [
        d.declare(
            target("c2_latency_p50_ms", "ms")
                .describe(format!(
                    "median {what}; SORA TMPR < 3 s is the limit, the project's 0.5 s target \
                     on SiK the marginal band"
                ))
                .at_most(TMPR_MEDIUM_MS)
                .marginal_above(TARGET_MS),
        ),
        d.declare(
            target("c2_latency_p99_ms", "ms")
                .describe(format!(
                    "99th percentile {what}; SORA TMPR < 3 s is the limit; the project's \
                     engineering target on SiK, <= 0.5 s, is the marginal band (a value above \
                     it is reported MARGINAL: not yet met)"
                ))
                .at_most(TMPR_MEDIUM_MS)
                .marginal_above(TARGET_MS),
        ),
        d.declare(
            target("commands_lost", "commands")
                .describe(
                    "commands of the mix the ground sent that the autopilot never executed \
                     (must be none: every command the pilot sends must take effect)",
                )
                .equal_to(0.0),
        ),
        d.declare(
            target("commands_executed_twice", "commands")
                .describe(
                    "commands of the mix the autopilot executed more than once, late copies \
                     included (must be none: the MAVLink command protocol forbids executing \
                     a retransmission twice)",
                )
                .equal_to(0.0),
        ),
    ];
    Box::new(move |ctx, radios| {
        run(ctx, radios, [p50, p99])?;
        run_target(ctx, radios, fast)
    })
}

/// The project's command-to-ack target on SiK 64 kbps at 10 % loss each way, ms: an
/// engineering target for a responsive link, not a requirement of SORA or the paper, so it
/// marks the marginal band inside the SORA limit rather than failing the run.
pub const TARGET_MS: f64 = 500.0;
/// The radio dimension of the target's measurements.
const TARGET_RADIO: &str = "sik_64k";

fn run_target(
    ctx: &mut PhaseContext,
    radios: &Radios,
    [p50_m, p99_m, lost_m, twice_m]: [Handle; 4],
) -> Result<()> {
    let (ms, stats, integrity) = measure_target(radios)?;
    ctx.record(p50_m, quantile(&ms, 0.50));
    ctx.record(p99_m, quantile(&ms, 0.99));
    ctx.record(lost_m, integrity.lost as f64);
    ctx.record(twice_m, integrity.executed_twice as f64);
    let note = format!(
        "{} commands, {} acked, {} given up, {} resent copies by the ground; {} executions \
         matching no command sent; best {:.0} ms, worst {:.0} ms",
        stats.started,
        stats.acked,
        stats.failed,
        stats.copies - stats.started,
        integrity.unknown,
        ms.first().copied().unwrap_or(f64::NAN),
        ms.last().copied().unwrap_or(f64::NAN)
    );
    ctx.annotate(p99_m, &note);
    ctx.log(format!("SiK 64k command mix: {note}"));
    anyhow::ensure!(
        integrity.unknown == 0,
        "the autopilot executed {} commands nobody sent",
        integrity.unknown
    );
    Ok(())
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
    let (ms, stats, _) = run_commands(radios, &radios.c2, plan, router_attempts)?;
    Ok((ms, stats))
}

/// The project's target: the command mix ([`CommandPlan::mix`]: same id with new parameters,
/// target component 0 or 1, ground retries with `confirmation` > 0) over
/// [`Radios::c2_target`]; latencies as [`measure`], and what the autopilot executed.
pub fn measure_target(radios: &Radios) -> Result<(Vec<f64>, CommandStats, Integrity)> {
    // MAVSDK's 0.5 s retry: the ground's own copies (confirmation > 0) are part of the mix.
    measure_mix(radios, Duration::from_millis(500))
}

/// As [`measure_target`], with the ground retrying after `retry` without an ack.
pub fn measure_mix(
    radios: &Radios,
    retry: Duration,
) -> Result<(Vec<f64>, CommandStats, Integrity)> {
    let plan = CommandPlan {
        mix: true,
        retry,
        ..CommandPlan::default()
    };
    let (ms, stats, executed) = run_commands(radios, &radios.c2_target, plan, None)?;
    Ok((ms, stats.clone(), Integrity::of(&stats, &executed)))
}

/// Exactly once, counted from the autopilot's log of executions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Integrity {
    /// Commands the ground sent that the autopilot never executed.
    pub lost: u64,
    /// Commands the autopilot executed more than once.
    pub executed_twice: u64,
    /// Executions that match no command the ground sent (a wrong parameter or target).
    pub unknown: u64,
}

impl Integrity {
    /// Counted from the ground's command stats and the autopilot's executions (the mix).
    pub fn of(stats: &CommandStats, executed: &[Executed]) -> Self {
        let (runs, unknown) = Self::runs(stats, executed);
        Self {
            lost: runs.iter().filter(|&&n| n == 0).count() as u64,
            executed_twice: runs.iter().filter(|&&n| n > 1).count() as u64,
            unknown,
        }
    }

    /// How often the autopilot executed each command the ground started (by serial), and
    /// the executions that match none.
    pub fn runs(stats: &CommandStats, executed: &[Executed]) -> (Vec<u64>, u64) {
        let mut runs = vec![0u64; stats.started as usize];
        let mut unknown = 0;
        for e in executed {
            // The mix carries its serial in param7; the rest must be what that command said.
            let serial = e.params[6] as usize;
            let sent = GcsMock::planned_command(serial as u64, true);
            let same = serial < runs.len()
                && sent.command == e.command
                && sent.target_component == e.target_component
                && [sent.param1, sent.param2, sent.param3] == e.params[..3];
            if same {
                runs[serial] += 1;
            } else {
                unknown += 1;
            }
        }
        (runs, unknown)
    }
}

fn run_commands(
    radios: &Radios,
    setup: &harness_radio::RadioSetup,
    plan: CommandPlan,
    router_attempts: Option<u32>,
) -> Result<(Vec<f64>, CommandStats, Vec<Executed>)> {
    let setup = radios.seeded(setup);
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
    w.gcs.stop_commands();
    // Late copies still on the radio may yet reach the autopilot: let them, so a second
    // execution cannot hide after the last ack.
    let drain = w.now + DRAIN;
    w.run_until(drain);
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
    Ok((ms, stats, w.fc.executed().to_vec()))
}

/// How long the world runs on after the last command finished (the router's whole
/// retransmission window).
const DRAIN: Duration = mavlora::command::RETRANSMIT_WINDOW;

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
