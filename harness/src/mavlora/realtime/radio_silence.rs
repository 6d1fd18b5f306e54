//! The radio goes silent both ways for 10 s in flight (a hill, a hangar, a radio that
//! browned out) and comes back (nothing may stay dead after a stall: in flight, nobody can
//! restart a program). The real programs over ptys must carry telemetry again as soon as
//! the air does, and commands sent after it must be acked as on a fresh link: both within
//! SORA's TMPR for medium robustness (C2 latency < 3 s), the bound the C2 scenarios use.

use anyhow::{Result, bail};
use std::time::Duration;

use super::{CommandsAfter, Scenario, Script, TMPR_S, Unsigned, ensure_clean, keep_evidence, spec};
use crate::clock::Mono;
use crate::mavlora::fixture::gcs::GcsEvent;
use crate::mavlora::session::{GcsPlan, MavloraSession, SessionDefaults};
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;

const SCENARIO_NAME: &str = "radio_silence";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "10 s of radio silence both ways in flight, then 5 commands: telemetry back and commands acked within SORA's TMPR (3 s)",
    plan,
};

/// How long the telemetry flows before the silence, and how long the silence lasts. The
/// silence starts from when telemetry reached the ground, not at a fixed time on the radio's
/// clock: a slow start on a loaded machine must not move it before the traffic.
const BEFORE: Duration = Duration::from_secs(5);
const SILENCE: Duration = Duration::from_secs(10);

struct Measured {
    unsigned: Unsigned,
    recovery: Handle,
    commands: CommandsAfter,
}

fn plan(d: &mut Declarations) -> Script {
    let m = Measured {
        unsigned: Unsigned::declare(d, SCENARIO_NAME),
        recovery: d.declare(
            spec("radio_silence_telemetry_recovery_s", "s")
                .describe(
                    "end of a 10 s silence of the radio both ways → the next vehicle message at \
                     the pymavlink ground station; limit: SORA TMPR medium (3 s)",
                )
                .at_most(TMPR_S),
        ),
        commands: CommandsAfter::declare(d, "radio_silence", "the silence"),
    };
    Box::new(move |ctx, defaults| run(ctx, defaults, &m))
}

fn run(ctx: &mut PhaseContext, d: &SessionDefaults, m: &Measured) -> Result<()> {
    let mut o = d.options(
        "radio_silence",
        &d.clean_radio,
        &ctx.dir.join("radio_silence"),
    );
    o.gcs = GcsPlan {
        // The silence, then time for telemetry to come back and settle.
        listen_s: (BEFORE + SILENCE).as_secs_f64() + 6.0,
        commands: CommandsAfter::COMMANDS,
        ..GcsPlan::default()
    };
    let session = MavloraSession::start(o)?;
    std::thread::sleep(BEFORE.saturating_sub(Mono::now().since(session.telemetry_at)));
    let start = session.silence_radio(SILENCE)?;
    let end = start + SILENCE;
    ctx.log(format!(
        "radio silent both ways from {:.1} s after telemetry began, for {} s",
        start.since(session.telemetry_at).as_secs_f64(),
        SILENCE.as_secs()
    ));
    let report = session.finish()?;
    keep_evidence(ctx, "radio_silence", &report);
    // The hole the silence made: it began inside the silence (a frame on air at its start
    // may still land, and the ground's gap starts at the last frame before it) and ended
    // after it.
    let gap = report.gcs_events.iter().find_map(|l| match &l.event {
        GcsEvent::TelemetryGap { t, since, message }
            if *since + Duration::from_secs(1) >= start && *since <= end && *t >= end =>
        {
            Some((*since, *t, message.clone()))
        }
        _ => None,
    });
    let Some((since, back, message)) = gap else {
        bail!(
            "the ground station reported no telemetry hole across the radio's {} s silence: \
             the silence did not take, or telemetry never came back",
            SILENCE.as_secs()
        );
    };
    ctx.log(format!(
        "telemetry stopped {:.2} s into the silence, came back {:.2} s after it ended ({message})",
        since.as_secs_f64() - start.as_secs_f64(),
        back.since(end).as_secs_f64()
    ));
    ctx.record(m.recovery, back.since(end).as_secs_f64());
    m.commands.record(ctx, &report)?;
    m.unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)
}
