//! A route with a pilot at every receiver: each pilot switches on before the
//! previous one switches off, and control walks down the line.

use anyhow::Result;

use super::{ModeLimits, SETTLE, Scenario, Script, SessionOptions};
use crate::clock::Mono;
use crate::measurement::{Declarations, Handle};
use crate::multirx::driver::receiver::Loss;
use crate::multirx::session::MultirxSession;
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "route_handover_chain",
    summary: "control handed along every receiver in turn, as pilots along a route",
    options: SessionOptions {
        loss: Loss::Failsafe,
    },
    plan,
};

fn plan(d: &mut Declarations, l: &ModeLimits) -> Script {
    let slowest = d.declare(
        l.spec("route_handover_max_ms", "ms")
            .describe(
                "slowest handover along the route, first failsafe frame → next pilot in control",
            )
            .at_most(l.handover_ms),
    );
    let handovers = d.declare(
        l.spec("route_handovers", "")
            .describe("handovers completed along the route")
            .equal_to(f64::from(l.receivers.saturating_sub(1))),
    );
    Box::new(move |s, ctx, l| run(s, ctx, l, slowest, handovers))
}

fn run(
    s: &MultirxSession,
    ctx: &mut PhaseContext,
    l: &ModeLimits,
    slowest: Handle,
    handovers: Handle,
) -> Result<()> {
    s.fly(0)?;
    let mut worst: f64 = 0.0;
    let mut done = 0;
    for k in 1..l.receivers {
        s.receiver(k).set_tx(true)?;
        std::thread::sleep(SETTLE);
        let off = Mono::now();
        s.receiver(k - 1).set_tx(false)?;
        let t0 = s
            .receiver(k - 1)
            .first_frame_with_flags(off, 0x08, super::FIXTURE_FIRST_FRAME)?;
        let f = s.fc.wait_for(
            t0,
            s.acquire_timeout(),
            &format!("pilot {} in control", k + 1),
            |f| s.shows_pilot(f, k),
        )?;
        let ms = f.at.ms_since(t0);
        ctx.log(format!("pilot {} → pilot {}: {ms:.1} ms", k, k + 1));
        worst = worst.max(ms);
        done += 1;
    }
    ctx.record(slowest, worst);
    ctx.record(handovers, f64::from(done));
    Ok(())
}
