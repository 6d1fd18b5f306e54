//! The drone's bridge crashes in flight (SIGKILL: nothing flushed) and its supervisor starts
//! it again 3 s later (a service manager's restart delay) (issue 10: a killed process must not leave the link dead). The
//! new bridge must find the flight controller, resume signing from the shared state file
//! (the router must not take its frames for replays) and carry telemetry and commands
//! within SORA's TMPR for medium robustness (3 s) of being started; the whole outage must
//! stay inside PX4's data-link-loss timeout (`COM_DL_LOSS_T`, 10 s by default), after which
//! the autopilot would start its own failsafe.

use std::time::Duration;

use anyhow::{Context, Result, bail};

use super::{CommandsAfter, Scenario, Script, TMPR_S, Unsigned, ensure_clean, keep_evidence, spec};
use crate::clock::Mono;
use crate::driver::fixture::mavlora_gcs::GcsEvent;
use crate::measurement::{Declarations, Handle};
use crate::scenario::PhaseContext;
use crate::strategy::mavlora::{GcsPlan, MavloraSession, SessionDefaults};

const SCENARIO_NAME: &str = "bridge_crash";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "The bridge is killed in flight and restarted 3 s later: telemetry back within 3 s of the restart, the outage within PX4's 10 s data-link-loss timeout, commands acked after",
    plan,
};

/// Telemetry flows this long before the crash.
const BEFORE: Duration = Duration::from_secs(5);
/// The bridge is down this long: a service manager's restart delay (and longer than the
/// ground station's 2 s telemetry-hole report, so the hole shows).
const DOWN: Duration = Duration::from_secs(3);
/// PX4's `COM_DL_LOSS_T` default: no ground heartbeat for this long starts its failsafe.
const DL_LOSS_S: f64 = 10.0;

struct Measured {
    unsigned: Unsigned,
    false_alarms: Handle,
    recovery: Handle,
    outage: Handle,
    commands: CommandsAfter,
}

fn plan(d: &mut Declarations) -> Script {
    let m = Measured {
        unsigned: Unsigned::declare(d, SCENARIO_NAME),
        false_alarms: d.declare(
            spec("bridge_crash_loss_alarms", "")
                .describe(
                    "'degraded: N% lost' link announcements the router made over the session, \
                     on a loss-free radio: a restarted bridge numbers its frames from 0 again, \
                     which is not loss",
                )
                .equal_to(0.0),
        ),
        recovery: d.declare(
            spec("bridge_restart_recovery_s", "s")
                .describe(
                    "a new bridge started after the old one was killed → the next autopilot \
                     message at the pymavlink ground station; limit: SORA TMPR medium (3 s)",
                )
                .at_most(TMPR_S),
        ),
        outage: d.declare(
            spec("bridge_crash_outage_s", "s")
                .describe(
                    "last autopilot message before the kill → first after the restart, with the \
                     bridge down 3 s; limit: PX4's data-link-loss timeout (COM_DL_LOSS_T, 10 s)",
                )
                .at_most(DL_LOSS_S),
        ),
        commands: CommandsAfter::declare(d, "bridge_crash", "the restart"),
    };
    Box::new(move |ctx, defaults| run(ctx, defaults, &m))
}

fn run(ctx: &mut PhaseContext, d: &SessionDefaults, m: &Measured) -> Result<()> {
    let mut o = d.options(
        "bridge_crash",
        &d.clean_radio,
        &ctx.dir.join("bridge_crash"),
    );
    o.gcs = GcsPlan {
        // The crash and restart, then time for telemetry to settle.
        listen_s: (BEFORE + DOWN).as_secs_f64() + 8.0,
        commands: CommandsAfter::COMMANDS,
        ..GcsPlan::default()
    };
    let mut session = MavloraSession::start(o)?;
    std::thread::sleep(BEFORE.saturating_sub(Mono::now().since(session.telemetry_at)));
    let killed = Mono::now();
    let restarted = session.crash_and_restart_bridge(DOWN)?;
    ctx.log(format!(
        "bridge killed {:.1} s after telemetry began, restarted {:.2} s later",
        killed.since(session.telemetry_at).as_secs_f64(),
        restarted.since(killed).as_secs_f64()
    ));
    let report = session.finish()?;
    keep_evidence(ctx, "bridge_crash", &report);
    let gap = report.gcs_events.iter().find_map(|l| match &l.event {
        GcsEvent::TelemetryGap { t, since, message } if *t >= restarted => {
            Some((*since, *t, message.clone()))
        }
        _ => None,
    });
    let Some((since, back, message)) = gap else {
        bail!(
            "the ground station reported no telemetry hole across the bridge's crash: \
             telemetry never stopped (was the bridge killed?) or never came back"
        );
    };
    ctx.log(format!(
        "telemetry stopped {:.2} s before the kill, back {:.2} s after the restart ({message})",
        killed.as_secs_f64() - since.as_secs_f64(),
        back.since(restarted).as_secs_f64()
    ));
    ctx.record(m.recovery, back.since(restarted).as_secs_f64());
    ctx.record(m.outage, back.since(since).as_secs_f64());
    m.commands.record(ctx, &report)?;
    let router_log = report
        .exits
        .iter()
        .find(|e| e.name == "mavlora-router")
        .map(|e| e.log.clone())
        .context("the session ran no router")?;
    let log = std::fs::read_to_string(&router_log)
        .with_context(|| format!("reading {}", router_log.display()))?;
    let alarms: Vec<&str> = log
        .lines()
        .filter(|l| {
            l.contains("link announcement") && l.contains("% lost") && l.contains("degraded")
        })
        .collect();
    for a in &alarms {
        ctx.log(format!("router: {a}"));
    }
    ctx.record(m.false_alarms, alarms.len() as f64);
    m.unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)
}
