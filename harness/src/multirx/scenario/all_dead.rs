//! Every receiver dies in flight (a shared supply browns out, all pilots out of range at
//! once): no frames at all, not even failsafe ones. MultiRX must put the flight controller
//! in auto-loiter with neutral sticks within its silence timeout, and the flight controller
//! must never see RC loss (the session's `rc_losses`); when power comes back, the pilot
//! gets control again.

use std::time::Duration;

use anyhow::Result;

use super::{ModeLimits, Scenario, Script, SessionOptions};
use crate::clock::Mono;
use crate::measurement::{Declarations, Handle};
use crate::multirx::driver::receiver::Loss;
use crate::multirx::session::{MultirxSession, POSITION_MODE};
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "fault_all_receivers_dead",
    summary: "Every receiver loses power in flight for 2 s: auto-loiter with neutral sticks, no RC loss, the pilot back in control after power returns",
    options: SessionOptions {
        loss: Loss::Failsafe,
    },
    plan,
};

/// How long every receiver stays dead.
const DEAD: Duration = Duration::from_secs(2);

struct Handles {
    entry: Handle,
    back: Handle,
}

fn plan(d: &mut Declarations, l: &ModeLimits) -> Script {
    let h = Handles {
        entry: d.declare(
            l.spec("all_dead_loiter_entry_ms", "ms")
                .describe(
                    "every receiver's power off → flight-mode channel at auto-loiter, neutral \
                     sticks and pilot channel at 'none'; limit: the silent-loss bound of this mode",
                )
                .at_most(l.handover_silent_ms),
        ),
        back: d.declare(
            l.spec("all_dead_recovery_ms", "ms")
                // No requirement bounds it beyond "control comes back" (the script fails if
                // it does not within the session's acquire timeout): recorded.
                .describe(
                    "power back on → the pilot in control again, the receiver's own boot \
                     (300 ms) included",
                ),
        ),
    };
    Box::new(move |s, ctx, _| run(s, ctx, h))
}

fn run(s: &MultirxSession, ctx: &mut PhaseContext, h: Handles) -> Result<()> {
    let fm = s.config.flight_mode_channel + 1;
    s.receiver(0).set_channels(&[(fm, POSITION_MODE)])?;
    s.fly(0)?;
    ctx.log("pilot 1 in control in position mode");
    let off = Mono::now();
    for rx in 0..s.config.receivers {
        s.receiver(rx).set_power(false)?;
    }
    let loiter =
        s.fc.wait_for(off, s.acquire_timeout(), "auto-loiter with no pilot", |f| {
            s.shows_loiter(f)
        })?;
    ctx.record(h.entry, loiter.at.ms_since(off));
    std::thread::sleep(DEAD);
    let on = Mono::now();
    for rx in 0..s.config.receivers {
        s.receiver(rx).set_power(true)?;
    }
    let back =
        s.fc.wait_for(on, s.acquire_timeout(), "pilot 1 in control again", |f| {
            s.shows_pilot(f, 0)
        })?;
    ctx.record(h.back, back.at.ms_since(on));
    ctx.log(format!(
        "all receivers off for {DEAD:?}: loiter after {:.0} ms, pilot 1 back {:.0} ms after power returned",
        loiter.at.ms_since(off),
        back.at.ms_since(on)
    ));
    Ok(())
}
