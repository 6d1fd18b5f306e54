//! A part of the link goes away in flight for 3 s and comes back (nothing may stay dead
//! after a fault: in flight, nobody is at hand to reseat a plug or restart the far end):
//!
//! - [`BRIDGE_CRASH`] / [`ROUTER_CRASH`]: a program is killed (SIGKILL: nothing flushed) and
//!   its supervisor starts it again 3 s later (a service manager's restart delay). The new
//!   bridge must find the flight controller, the new router the radio and the ground
//!   station (no datagram from the ground needed first), and each resume signing from the
//!   shared state file so the other end does not take its frames for replays;
//! - [`AIR_REPLUG`] / [`GROUND_REPLUG`]: a USB radio is pulled and put back: its port hangs
//!   up under the program, its stable name (what `/dev/serial/by-id` is to a USB radio)
//!   leads nowhere for 3 s, then to a new device. The program must let go of the dead port,
//!   wait for the name, and reopen it by itself.
//!
//! Either way telemetry and commands must flow within SORA's TMPR for medium robustness
//! (3 s) of the part coming back; the whole outage must stay inside PX4's data-link-loss
//! timeout (`COM_DL_LOSS_T`, 10 s by default), after which the autopilot would start its own
//! failsafe. A restart is not radio loss (no loss alarm on a loss-free radio); frames sent
//! into an unplugged radio are, and the alarms the pilot gets then are recorded.

use std::time::Duration;

use anyhow::{Result, bail};

use super::{
    CommandsAfter, Scenario, Script, TMPR_S, Unsigned, ensure_clean, keep_evidence, loss_alarms,
    spec,
};
use crate::clock::Mono;
use crate::mavlora::fixture::gcs::GcsEvent;
use crate::mavlora::session::{End, GcsPlan, MavloraSession, Program, SessionDefaults};
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;

pub const BRIDGE_CRASH: Scenario = Scenario {
    name: "bridge_crash",
    summary: "The bridge is killed in flight and restarted 3 s later: telemetry back within 3 s of the restart, the outage within PX4's 10 s data-link-loss timeout, commands acked after",
    plan: |d| plan(d, Fault::Crash(Program::Bridge)),
};

pub const ROUTER_CRASH: Scenario = Scenario {
    name: "router_crash",
    summary: "The router is killed in flight and restarted 3 s later: telemetry back at the ground station within 3 s of the restart, the outage within PX4's 10 s data-link-loss timeout, commands acked after",
    plan: |d| plan(d, Fault::Crash(Program::Router)),
};

pub const AIR_REPLUG: Scenario = Scenario {
    name: "radio_replug_air",
    summary: "The drone's USB radio is pulled in flight and put back 3 s later: the bridge reopens it by its stable name, telemetry back within 3 s, the outage within PX4's 10 s data-link-loss timeout, commands acked after",
    plan: |d| plan(d, Fault::Replug(End::Air)),
};

pub const GROUND_REPLUG: Scenario = Scenario {
    name: "radio_replug_ground",
    summary: "The ground's USB radio is pulled in flight and put back 3 s later: the router reopens it by its stable name, telemetry back within 3 s, the outage within PX4's 10 s data-link-loss timeout, commands acked after",
    plan: |d| plan(d, Fault::Replug(End::Ground)),
};

/// Telemetry flows this long before the fault.
const BEFORE: Duration = Duration::from_secs(5);
/// The part is gone this long: a service manager's restart delay, a hand putting a plug
/// back (and longer than the ground station's 2 s telemetry-hole report, so the hole shows).
const DOWN: Duration = Duration::from_secs(3);
/// PX4's `COM_DL_LOSS_T` default: no ground heartbeat for this long starts its failsafe.
const DL_LOSS_S: f64 = 10.0;

/// What goes away.
#[derive(Debug, Clone, Copy)]
enum Fault {
    /// The program is killed and started again.
    Crash(Program),
    /// The radio on that end is unplugged and plugged in again.
    Replug(End),
}

impl Fault {
    /// The scenario's name, and the prefix of its measurements but the crashes' older
    /// recovery and outage names.
    fn name(self) -> String {
        match self {
            Fault::Crash(p) => format!("{p}_crash"),
            Fault::Replug(End::Air) => "radio_replug_air".into(),
            Fault::Replug(End::Ground) => "radio_replug_ground".into(),
        }
    }

    fn recovery_name(self) -> String {
        match self {
            Fault::Crash(p) => format!("{p}_restart_recovery_s"),
            Fault::Replug(_) => format!("{}_recovery_s", self.name()),
        }
    }

    /// What comes back, for the texts: "a new bridge started after the old one was killed".
    fn back(self) -> &'static str {
        match self {
            Fault::Crash(Program::Bridge) => "a new bridge started after the old one was killed",
            Fault::Crash(Program::Router) => "a new router started after the old one was killed",
            Fault::Replug(End::Air) => "the drone's radio plugged in again",
            Fault::Replug(End::Ground) => "the ground's radio plugged in again",
        }
    }

    /// What goes away, for the texts.
    fn part(self) -> &'static str {
        match self {
            Fault::Crash(Program::Bridge) => "bridge",
            Fault::Crash(Program::Router) => "router",
            Fault::Replug(End::Air) => "drone's radio",
            Fault::Replug(End::Ground) => "ground's radio",
        }
    }
}

struct Measured {
    fault: Fault,
    unsigned: Unsigned,
    false_alarms: Handle,
    recovery: Handle,
    outage: Handle,
    commands: CommandsAfter,
}

fn plan(d: &mut Declarations, fault: Fault) -> Script {
    let (name, part) = (fault.name(), fault.part());
    let m = Measured {
        fault,
        unsigned: Unsigned::declare(d, &name),
        false_alarms: d.declare(match fault {
            Fault::Crash(_) => spec(&format!("{name}_loss_alarms"), "")
                .describe(format!(
                    "'degraded: N% lost' link announcements the router made over the session, \
                     on a loss-free radio: a restarted {part} numbers its frames from 0 again, \
                     which is not loss"
                ))
                .equal_to(0.0),
            // Frames the far end sent into the unplugged radio crossed the air and reached
            // nobody: real loss, which the pilot may rightly be told of. Recorded.
            Fault::Replug(_) => spec(&format!("{name}_loss_alarms"), "").describe(format!(
                "'degraded: N% lost' link announcements the router made over the session: \
                 what the far end sent while the {part} was out is lost for real"
            )),
        }),
        recovery: d.declare(
            spec(&fault.recovery_name(), "s")
                .describe(format!(
                    "{} → the next autopilot message at the pymavlink ground station; limit: \
                     SORA TMPR medium (3 s)",
                    fault.back()
                ))
                .at_most(TMPR_S),
        ),
        outage: d.declare(
            spec(&format!("{name}_outage_s"), "s")
                .describe(format!(
                    "last autopilot message before the fault → first after it, with the {part} \
                     gone 3 s; limit: PX4's data-link-loss timeout (COM_DL_LOSS_T, 10 s)"
                ))
                .at_most(DL_LOSS_S),
        ),
        commands: CommandsAfter::declare(
            d,
            &name,
            match fault {
                Fault::Crash(_) => "the restart",
                Fault::Replug(_) => "the radio was back",
            },
        ),
    };
    Box::new(move |ctx, defaults| run(ctx, defaults, &m))
}

fn run(ctx: &mut PhaseContext, d: &SessionDefaults, m: &Measured) -> Result<()> {
    let (fault, name, part) = (m.fault, m.fault.name(), m.fault.part());
    let mut o = d.options(&name, &d.clean_radio, &ctx.dir.join(&name));
    o.gcs = GcsPlan {
        // The fault, then time for telemetry to settle.
        listen_s: (BEFORE + DOWN).as_secs_f64() + 8.0,
        commands: CommandsAfter::COMMANDS,
        ..GcsPlan::default()
    };
    let mut session = MavloraSession::start(o)?;
    std::thread::sleep(BEFORE.saturating_sub(Mono::now().since(session.telemetry_at)));
    let gone = Mono::now();
    let back = match fault {
        Fault::Crash(program) => session.crash_and_restart(program, DOWN)?,
        Fault::Replug(end) => session.replug_radio(end, DOWN)?,
    };
    ctx.log(format!(
        "{part} gone {:.1} s after telemetry began, back {:.2} s later",
        gone.since(session.telemetry_at).as_secs_f64(),
        back.since(gone).as_secs_f64()
    ));
    let report = session.finish()?;
    keep_evidence(ctx, &name, &report);
    let gap = report.gcs_events.iter().find_map(|l| match &l.event {
        GcsEvent::TelemetryGap { t, since, message } if *t >= back => {
            Some((*since, *t, message.clone()))
        }
        _ => None,
    });
    let Some((since, seen, message)) = gap else {
        bail!(
            "the ground station reported no telemetry hole across the {part}'s outage: \
             telemetry never stopped (did the fault take?) or never came back"
        );
    };
    ctx.log(format!(
        "telemetry stopped {:.2} s before the fault, back {:.2} s after the {part} was \
         ({message})",
        gone.as_secs_f64() - since.as_secs_f64(),
        seen.since(back).as_secs_f64()
    ));
    ctx.record(m.recovery, seen.since(back).as_secs_f64());
    ctx.record(m.outage, seen.since(since).as_secs_f64());
    m.commands.record(ctx, &report)?;
    // The router's announcements over the session: a crashed router's and the new one's.
    let alarms = loss_alarms(ctx, &report);
    ctx.record(m.false_alarms, f64::from(alarms));
    m.unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)
}
