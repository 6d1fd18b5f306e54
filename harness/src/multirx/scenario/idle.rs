//! Scenario A: the idle pilot switches on while another pilot flies; the idle
//! pilot must gain no control.

use std::time::Duration;

use anyhow::Result;

use super::{ModeLimits, Scenario, Script, SessionOptions};
use crate::clock::Mono;
use crate::measurement::{Declarations, Handle};
use crate::multirx::session::MultirxSession;
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "a_idle_takeover",
    summary: "A: pilot 2 switches on while pilot 1 flies; pilot 2 must gain no control",
    options: SessionOptions {
        loss: crate::multirx::driver::receiver::Loss::Failsafe,
    },
    plan,
};

const WATCH: Duration = Duration::from_secs(3);

fn plan(d: &mut Declarations, l: &ModeLimits) -> Script {
    let takeovers = d.declare(
        l.spec("idle_takeovers", "")
            .describe(
                "frames at the flight controller showing pilot 2 while pilot 1 still had a link",
            )
            .equal_to(0.0),
    );
    Box::new(move |s, ctx, _| run(s, ctx, takeovers))
}

fn run(s: &MultirxSession, ctx: &mut PhaseContext, idle_takeovers: Handle) -> Result<()> {
    s.fly(0)?;
    ctx.log("pilot 1 in control");
    let on = Mono::now();
    s.receiver(1).set_tx(true)?;
    std::thread::sleep(WATCH);
    let takeovers =
        s.fc.frames()
            .iter()
            .filter(|f| f.at >= on && f.channels[s.pilot_index()] != s.pilot_value(0))
            .count();
    ctx.log(format!("watched {WATCH:?} after pilot 2 switched on"));
    ctx.record(idle_takeovers, takeovers as f64);
    Ok(())
}
