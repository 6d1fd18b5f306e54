//! One of the MavLora programs crashes in flight (SIGKILL: nothing flushed) and its
//! supervisor starts it again 3 s later (a service manager's restart delay) (issue 10: a
//! killed process must not leave the link dead):
//!
//! - [`BRIDGE`]: the drone's bridge. The new one must find the flight controller and resume
//!   signing from the shared state file (the router must not take its frames for replays);
//! - [`ROUTER`]: the ground's router. The new one must find the radio and the ground
//!   station again (no datagram from the ground needed first) and resume signing, so the
//!   bridge takes its frames.
//!
//! Either way telemetry and commands must flow within SORA's TMPR for medium robustness
//! (3 s) of the restart; the whole outage must stay inside PX4's data-link-loss timeout
//! (`COM_DL_LOSS_T`, 10 s by default), after which the autopilot would start its own
//! failsafe; and a restart is not radio loss (no loss alarm on a loss-free radio).

use std::time::Duration;

use anyhow::{Context, Result, bail};

use super::{CommandsAfter, Scenario, Script, TMPR_S, Unsigned, ensure_clean, keep_evidence, spec};
use crate::clock::Mono;
use crate::driver::fixture::mavlora_gcs::GcsEvent;
use crate::measurement::{Declarations, Handle};
use crate::scenario::PhaseContext;
use crate::strategy::mavlora::{GcsPlan, MavloraSession, Program, SessionDefaults};

pub const BRIDGE: Scenario = Scenario {
    name: "bridge_crash",
    summary: "The bridge is killed in flight and restarted 3 s later: telemetry back within 3 s of the restart, the outage within PX4's 10 s data-link-loss timeout, commands acked after",
    plan: |d| plan(d, Program::Bridge),
};

pub const ROUTER: Scenario = Scenario {
    name: "router_crash",
    summary: "The router is killed in flight and restarted 3 s later: telemetry back at the ground station within 3 s of the restart, the outage within PX4's 10 s data-link-loss timeout, commands acked after",
    plan: |d| plan(d, Program::Router),
};

/// Telemetry flows this long before the crash.
const BEFORE: Duration = Duration::from_secs(5);
/// The program is down this long: a service manager's restart delay (and longer than the
/// ground station's 2 s telemetry-hole report, so the hole shows).
const DOWN: Duration = Duration::from_secs(3);
/// PX4's `COM_DL_LOSS_T` default: no ground heartbeat for this long starts its failsafe.
const DL_LOSS_S: f64 = 10.0;

struct Measured {
    which: Program,
    unsigned: Unsigned,
    false_alarms: Handle,
    recovery: Handle,
    outage: Handle,
    commands: CommandsAfter,
}

fn plan(d: &mut Declarations, which: Program) -> Script {
    let m = Measured {
        which,
        unsigned: Unsigned::declare(d, &format!("{which}_crash")),
        false_alarms: d.declare(
            spec(&format!("{which}_crash_loss_alarms"), "")
                .describe(format!(
                    "'degraded: N% lost' link announcements the router made over the session, \
                     on a loss-free radio: a restarted {which} numbers its frames from 0 again, \
                     which is not loss"
                ))
                .equal_to(0.0),
        ),
        recovery: d.declare(
            spec(&format!("{which}_restart_recovery_s"), "s")
                .describe(format!(
                    "a new {which} started after the old one was killed → the next autopilot \
                     message at the pymavlink ground station; limit: SORA TMPR medium (3 s)"
                ))
                .at_most(TMPR_S),
        ),
        outage: d.declare(
            spec(&format!("{which}_crash_outage_s"), "s")
                .describe(format!(
                    "last autopilot message before the kill → first after the restart, with the \
                     {which} down 3 s; limit: PX4's data-link-loss timeout (COM_DL_LOSS_T, 10 s)"
                ))
                .at_most(DL_LOSS_S),
        ),
        commands: CommandsAfter::declare(d, &format!("{which}_crash"), "the restart"),
    };
    Box::new(move |ctx, defaults| run(ctx, defaults, &m))
}

fn run(ctx: &mut PhaseContext, d: &SessionDefaults, m: &Measured) -> Result<()> {
    let which = m.which;
    let name = format!("{which}_crash");
    let mut o = d.options(&name, &d.clean_radio, &ctx.dir.join(&name));
    o.gcs = GcsPlan {
        // The crash and restart, then time for telemetry to settle.
        listen_s: (BEFORE + DOWN).as_secs_f64() + 8.0,
        commands: CommandsAfter::COMMANDS,
        ..GcsPlan::default()
    };
    let mut session = MavloraSession::start(o)?;
    std::thread::sleep(BEFORE.saturating_sub(Mono::now().since(session.telemetry_at)));
    let killed = Mono::now();
    let restarted = session.crash_and_restart(which, DOWN)?;
    ctx.log(format!(
        "{which} killed {:.1} s after telemetry began, restarted {:.2} s later",
        killed.since(session.telemetry_at).as_secs_f64(),
        restarted.since(killed).as_secs_f64()
    ));
    // The router's announcements over the session: the crashed one's and the new one's.
    let router_logs: Vec<_> = match which {
        Program::Router => vec![
            session.options.out_dir.join("router.log"),
            session
                .log_of(Program::Router)
                .context("the session runs no router")?
                .to_path_buf(),
        ],
        Program::Bridge => vec![
            session
                .log_of(Program::Router)
                .context("the session runs no router")?
                .to_path_buf(),
        ],
    };
    let report = session.finish()?;
    keep_evidence(ctx, &name, &report);
    let gap = report.gcs_events.iter().find_map(|l| match &l.event {
        GcsEvent::TelemetryGap { t, since, message } if *t >= restarted => {
            Some((*since, *t, message.clone()))
        }
        _ => None,
    });
    let Some((since, back, message)) = gap else {
        bail!(
            "the ground station reported no telemetry hole across the {which}'s crash: \
             telemetry never stopped (was the {which} killed?) or never came back"
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
    let mut alarms = 0;
    for path in &router_logs {
        let log =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        for a in log.lines().filter(|l| {
            l.contains("link announcement") && l.contains("% lost") && l.contains("degraded")
        }) {
            ctx.log(format!("router: {a}"));
            alarms += 1;
        }
    }
    ctx.record(m.false_alarms, f64::from(alarms));
    m.unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)
}
