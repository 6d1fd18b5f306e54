//! Scenario C: every transmitter goes off in flight; MultiRX must put the
//! flight controller in auto-loiter with neutral sticks, and it must never
//! see RC loss.

use std::time::Duration;

use anyhow::Result;

use super::{ModeLimits, SETTLE, Scenario, Script, SessionOptions};
use crate::clock::Mono;
use crate::measurement::{Declarations, Handle};
use crate::multirx::driver::receiver::Loss;
use crate::multirx::session::{MultirxSession, POSITION_MODE};
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "c_loiter",
    summary: "C: both transmitters off in manual flight; auto-loiter, no RC loss",
    options: SessionOptions {
        loss: Loss::Failsafe,
    },
    plan,
};

fn plan(d: &mut Declarations, l: &ModeLimits) -> Script {
    let entry = d.declare(
        l.spec("loiter_entry_ms", "ms")
            .describe("first failsafe frame from the last transmitter → flight-mode channel at auto-loiter and pilot channel at 'none'")
            .at_most(100.0),
    );
    Box::new(move |s, ctx, _| run(s, ctx, entry))
}

fn run(s: &MultirxSession, ctx: &mut PhaseContext, entry: Handle) -> Result<()> {
    let fm = s.config.flight_mode_channel + 1;
    for rx in [0, 1] {
        s.receiver(rx).set_channels(&[(fm, POSITION_MODE)])?;
    }
    s.fly(0)?;
    s.receiver(1).set_tx(true)?;
    std::thread::sleep(SETTLE);
    s.receiver(1).set_tx(false)?;
    std::thread::sleep(SETTLE);
    ctx.log("pilot 1 flying in position mode; pilot 2 switched on and off again");
    let off = Mono::now();
    s.receiver(0).set_tx(false)?;
    let t0 = s
        .receiver(0)
        .first_frame_with_flags(off, 0x08, super::FIXTURE_FIRST_FRAME)?;
    let (mode, pilot) = (s.mode_index(), s.pilot_index());
    let f =
        s.fc.wait_for(t0, s.acquire_timeout(), "auto-loiter with no pilot", |f| {
            f.channels[mode] == s.config.auto_loiter_value
                && f.channels[pilot] == s.config.no_receiver_value
        })?;
    ctx.record(entry, f.at.ms_since(t0));
    // Stay a while with nobody in control: the output must go on.
    std::thread::sleep(Duration::from_secs(1));
    Ok(())
}
