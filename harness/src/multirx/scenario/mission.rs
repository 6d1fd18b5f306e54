//! Scenario D: a mission flight with nobody in control; a pilot takes over.
//! Every transmitter's mode switch sits at auto-loiter, so the handover itself
//! must not change the flight mode (PX4 acts on changes only) and the mission
//! goes on until the pilot moves the switch.

use std::time::Duration;

use anyhow::Result;

use super::{ModeLimits, SETTLE, Scenario, Script, SessionOptions};
use crate::clock::Mono;
use crate::measurement::{Declarations, Handle};
use crate::multirx::driver::receiver::Loss;
use crate::multirx::px4_rc_input::mode_slot;
use crate::multirx::session::{MultirxSession, POSITION_MODE};
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "d_mission_takeover",
    summary: "D: mission flight, a pilot takes control without changing the flight mode, then switches mode",
    options: SessionOptions {
        loss: Loss::Failsafe,
    },
    plan,
};

/// The measurements [`run`] records.
struct Measured {
    takeover_ms: Handle,
    mode_changes: Handle,
    mode_switch_ms: Handle,
}

fn plan(d: &mut Declarations, l: &ModeLimits) -> Script {
    let m = Measured {
        takeover_ms: d.declare(
            l.spec("takeover_ms", "ms")
                .describe("pilot 2's transmitter on → pilot 2 in control at the flight controller")
                .at_most(match l.mode {
                    crate::multirx::rigfile::Mode::Parallel => 500.0,
                    crate::multirx::rigfile::Mode::Scan => l.handover_ms,
                }),
        ),
        mode_changes: d.declare(
            l.spec("mode_changes_on_takeover", "")
                .describe("flight-mode slot changes PX4 saw while control passed to the pilot")
                .equal_to(0.0),
        ),
        mode_switch_ms: d.declare(
            l.spec("mode_switch_ms", "ms")
                .describe("pilot moves the mode switch → new mode slot at the flight controller")
                .at_most(50.0),
        ),
    };
    Box::new(move |s, ctx, _| run(s, ctx, &m))
}

fn run(s: &MultirxSession, ctx: &mut PhaseContext, m: &Measured) -> Result<()> {
    // Nobody in control yet: the mission flies on MultiRX's auto-loiter value.
    std::thread::sleep(SETTLE);
    let on = Mono::now();
    let tx = s.receiver(1).set_tx(true)?;
    let f =
        s.fc.wait_for(on, s.acquire_timeout(), "pilot 2 in control", |f| {
            s.shows_pilot(f, 1)
        })?;
    ctx.record(m.takeover_ms, f.at.ms_since(tx.t()));
    std::thread::sleep(SETTLE);
    let changes = s.px4_report().mode_changes.len();
    ctx.record(m.mode_changes, changes as f64);

    let fm = s.config.flight_mode_channel + 1;
    let set = s.receiver(1).set_channels(&[(fm, POSITION_MODE)])?;
    let slot = mode_slot(POSITION_MODE);
    let f = s.fc.wait_for(
        set.t(),
        Duration::from_secs(1),
        "the pilot's mode switch",
        |f| mode_slot(f.channels[s.mode_index()]) == slot,
    )?;
    ctx.record(m.mode_switch_ms, f.at.ms_since(set.t()));
    Ok(())
}
