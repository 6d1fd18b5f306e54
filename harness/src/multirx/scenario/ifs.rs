//! The independent fail-safe system (IFS) overrides its channels (e.g. the
//! flight mode, to land or terminate) whoever is flying, and lets go again.

use std::time::Duration;

use anyhow::{Context, Result};

use super::{ModeLimits, Scenario, Script, SessionOptions};
use crate::measurement::{Declarations, Handle};
use crate::multirx::driver::receiver::Loss;
use crate::multirx::session::MultirxSession;
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "ifs_override",
    summary: "the IFS overrides its channels while a pilot flies, then releases them",
    options: SessionOptions {
        loss: Loss::Failsafe,
    },
    plan,
};

/// A value no pilot sends, so the override is unmistakable.
const IFS_VALUE: u16 = 250;

fn plan(d: &mut Declarations, l: &ModeLimits) -> Script {
    let override_ms = d.declare(
        l.spec("ifs_override_ms", "ms")
            .describe("IFS starts sending → its channel values at the flight controller")
            .at_most(50.0),
    );
    let release_ms = d.declare(
        l.spec("ifs_release_ms", "ms")
            .describe("IFS stops sending → the pilot's values back at the flight controller")
            .at_most(200.0),
    );
    Box::new(move |s, ctx, _| run(s, ctx, override_ms, release_ms))
}

fn run(
    s: &MultirxSession,
    ctx: &mut PhaseContext,
    override_ms: Handle,
    release_ms: Handle,
) -> Result<()> {
    let ifs = s.ifs.as_ref().context(
        "this rig's MultiRX config names no [ifs] channels, or [multirx.ports] has no ifs port",
    )?;
    let ch = s
        .config
        .ifs_channels
        .iter()
        .next()
        .context("no IFS channel")?;
    s.fly(0)?;
    ifs.set_channels(&[(ch + 1, IFS_VALUE)])?;
    let on = ifs.set_tx(true)?;
    let t0 = ifs.first_frame_with_flags(on.t(), 0, super::FIXTURE_FIRST_FRAME)?;
    let f =
        s.fc.wait_for(t0, Duration::from_secs(1), "the IFS override", |f| {
            f.channels[usize::from(ch)] == IFS_VALUE && s.shows_pilot(f, 0)
        })?;
    ctx.record(override_ms, f.at.ms_since(t0));
    std::thread::sleep(Duration::from_millis(300));
    let off = ifs.set_tx(false)?;
    let t1 = off.last_frame().unwrap_or(off.t());
    let f =
        s.fc.wait_for(t1, Duration::from_secs(1), "the IFS release", |f| {
            f.channels[usize::from(ch)] != IFS_VALUE && s.shows_pilot(f, 0)
        })?;
    ctx.record(release_ms, f.at.ms_since(t1));
    Ok(())
}
