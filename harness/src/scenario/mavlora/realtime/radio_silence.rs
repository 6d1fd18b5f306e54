//! The radio goes silent both ways for 10 s in flight (a hill, a hangar, a radio that
//! browned out) and comes back (issue 10: nothing may stay dead after a stall). The real
//! programs over ptys must carry telemetry again as soon as the air does, and commands sent
//! after it must be acked as on a fresh link: both within SORA's TMPR for medium robustness
//! (C2 latency < 3 s), the bound the C2 scenarios use.

use anyhow::{Result, bail};
use harness_radio::Silence;

use super::{CommandsAfter, Scenario, Script, TMPR_S, Unsigned, ensure_clean, run_session, spec};
use crate::driver::fixture::mavlora_gcs::GcsEvent;
use crate::measurement::{Declarations, Handle};
use crate::scenario::PhaseContext;
use crate::strategy::mavlora::{GcsPlan, SessionDefaults};

const SCENARIO_NAME: &str = "radio_silence";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "10 s of radio silence both ways in flight, then 5 commands: telemetry back and commands acked within SORA's TMPR (3 s)",
    plan,
};

/// When the silence starts, s on the radio's clock, and how long it lasts.
const SILENCE: Silence = Silence {
    at_s: 8.0,
    for_s: 10.0,
    every_s: None,
};

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
    let mut radio = d.clean_radio.clone();
    radio.uplink.silences.push(SILENCE);
    radio.downlink.silences.push(SILENCE);
    let mut o = d.options("radio_silence", &radio, &ctx.dir.join("radio_silence"));
    o.gcs = GcsPlan {
        // Until 6 s after the silence ends (the session takes ~1-2 s to bring telemetry up).
        listen_s: SILENCE.at_s + SILENCE.for_s + 4.0,
        commands: CommandsAfter::COMMANDS,
        ..GcsPlan::default()
    };
    let report = run_session(ctx, o)?;
    let start = report.radio_epoch.as_secs_f64() + SILENCE.at_s;
    let end = start + SILENCE.for_s;
    // The hole the silence made: it began inside the silence (a frame on air at its start
    // may still land) and ended after it.
    let gap = report.gcs_events.iter().find_map(|l| match &l.event {
        GcsEvent::TelemetryGap { t, since, message } => {
            let (t, since) = (t.as_secs_f64(), since.as_secs_f64());
            (since >= start - 1.0 && since <= end && t >= end).then(|| (since, t, message.clone()))
        }
        _ => None,
    });
    let Some((since, back, message)) = gap else {
        bail!(
            "the ground station reported no telemetry hole across the radio's silence \
             ({:.1}..{:.1} s after the radio started): the silence did not take, or telemetry \
             never came back",
            SILENCE.at_s,
            SILENCE.at_s + SILENCE.for_s
        );
    };
    ctx.log(format!(
        "telemetry stopped {:.2} s into the silence, came back {:.2} s after it ended ({message})",
        since - start,
        back - end
    ));
    ctx.record(m.recovery, back - end);
    m.commands.record(ctx, &report)?;
    m.unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)
}
