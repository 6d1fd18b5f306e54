//! Scenario B: the active pilot's transmitter goes off while another pilot's
//! is on; control must pass to the other pilot. Timed from the first frame
//! with the failsafe flag (receivers that report loss), or from the last
//! frame (receivers that fall silent).

use anyhow::{Context, Result};

use super::{Limits, SETTLE, Scenario, SessionOptions};
use crate::clock::Mono;
use crate::driver::receiver::Loss;
use crate::measurement::Measurement;
use crate::scenario::PhaseContext;
use crate::strategy::multirx::MultirxSession;

pub const FAILSAFE: Scenario = Scenario {
    name: "b_handover",
    summary: "B: pilot 1 off (receiver raises failsafe), pilot 2 on; pilot 2 gains control",
    options: SessionOptions {
        loss: Loss::Failsafe,
    },
    measurements: failsafe_measurements,
    run: run_failsafe,
};

pub const SILENT: Scenario = Scenario {
    name: "b_handover_silent",
    summary: "B: pilot 1 off (receiver falls silent), pilot 2 on; pilot 2 gains control",
    options: SessionOptions { loss: Loss::Silent },
    measurements: silent_measurements,
    run: run_silent,
};

fn failsafe_measurements(l: &Limits) -> Vec<Measurement> {
    vec![
        Measurement::new(l.name("handover_ms"), "ms")
            .describe("first failsafe frame from pilot 1's receiver → pilot 2's sticks and pilot value at the flight controller")
            .at_most(l.handover_ms),
    ]
}

fn silent_measurements(l: &Limits) -> Vec<Measurement> {
    vec![
        Measurement::new(l.name("handover_silent_ms"), "ms")
            .describe("last frame from pilot 1's receiver → pilot 2's sticks and pilot value at the flight controller")
            .at_most(l.handover_silent_ms),
    ]
}

/// Pilot 1 flying, pilot 2's transmitter on and settled.
fn prepare(s: &MultirxSession, ctx: &mut PhaseContext) -> Result<()> {
    s.fly(0)?;
    s.receiver(1).set_tx(true)?;
    std::thread::sleep(SETTLE);
    ctx.log("pilot 1 in control, pilot 2 standing by");
    Ok(())
}

fn handover_after(s: &MultirxSession, t0: Mono) -> Result<f64> {
    let f =
        s.fc.wait_for(t0, s.acquire_timeout(), "pilot 2 in control", |f| {
            s.shows_pilot(f, 1)
        })?;
    Ok(f.at.ms_since(t0))
}

fn run_failsafe(s: &MultirxSession, ctx: &mut PhaseContext, l: &Limits) -> Result<()> {
    prepare(s, ctx)?;
    let off = Mono::now();
    s.receiver(0).set_tx(false)?;
    let t0 = s
        .receiver(0)
        .first_frame_with_flags(off, 0x08, std::time::Duration::from_secs(1))?;
    ctx.log(format!("pilot 1 off; first failsafe frame at {t0}"));
    ctx.record(&l.name("handover_ms"), handover_after(s, t0)?);
    Ok(())
}

fn run_silent(s: &MultirxSession, ctx: &mut PhaseContext, l: &Limits) -> Result<()> {
    prepare(s, ctx)?;
    let event = s.receiver(0).set_tx(false)?;
    let t0 = event.fields["last_frame"]
        .as_f64()
        .map(Mono::from_secs_f64)
        .context("receiver fixture did not report its last frame")?;
    ctx.log(format!("pilot 1 off; last frame at {t0}"));
    ctx.record(&l.name("handover_silent_ms"), handover_after(s, t0)?);
    Ok(())
}
