//! Scenario B: the active pilot's transmitter goes off while another pilot's
//! is on; control must pass to the other pilot. Timed from the first frame
//! with the failsafe flag (receivers that report loss), or from the last
//! frame (receivers that fall silent). Control goes back and forth several
//! times and the worst handover is the measurement.

use anyhow::{Context, Result};

use super::{ModeLimits, SETTLE, Scenario, Script, SessionOptions};
use crate::clock::Mono;
use crate::measurement::{Declarations, Handle};
use crate::multirx::driver::receiver::Loss;
use crate::multirx::session::MultirxSession;
use crate::runner::PhaseContext;

pub const FAILSAFE: Scenario = Scenario {
    name: "b_handover",
    summary: "B: active pilot off (receiver raises failsafe), other pilot on; control passes, 6 times back and forth",
    options: SessionOptions {
        loss: Loss::Failsafe,
    },
    plan: plan_failsafe,
};

pub const SILENT: Scenario = Scenario {
    name: "b_handover_silent",
    summary: "B: active pilot off (receiver falls silent), other pilot on; control passes, 6 times back and forth",
    options: SessionOptions { loss: Loss::Silent },
    plan: plan_silent,
};

/// Handovers per scenario: two receivers, so two frame phases per session.
const ROUNDS: usize = 6;

fn plan_failsafe(d: &mut Declarations, l: &ModeLimits) -> Script {
    let worst = d.declare(
        l.spec("handover_ms", "ms")
            .describe(
                "worst of 6 handovers: first failsafe frame from the active pilot's receiver → \
                 the other pilot's sticks and pilot value at the flight controller",
            )
            .at_most(l.handover_ms),
    );
    Box::new(move |s, ctx, _| run(s, ctx, failsafe_mark, worst))
}

fn plan_silent(d: &mut Declarations, l: &ModeLimits) -> Script {
    let worst = d.declare(
        l.spec("handover_silent_ms", "ms")
            .describe(
                "worst of 6 handovers: last frame from the active pilot's receiver → \
                 the other pilot's sticks and pilot value at the flight controller",
            )
            .at_most(l.handover_silent_ms),
    );
    Box::new(move |s, ctx, _| run(s, ctx, silent_mark, worst))
}

/// When the active pilot's receiver told (or stopped telling) MultiRX that
/// its transmitter is gone.
type LossMark = fn(&MultirxSession, u8) -> Result<Mono>;

fn failsafe_mark(s: &MultirxSession, rx: u8) -> Result<Mono> {
    let off = Mono::now();
    s.receiver(rx).set_tx(false)?;
    Ok(s.receiver(rx)
        .first_frame_with_flags(off, 0x08, super::FIXTURE_FIRST_FRAME)?)
}

fn silent_mark(s: &MultirxSession, rx: u8) -> Result<Mono> {
    s.receiver(rx)
        .set_tx(false)?
        .last_frame()
        .context("receiver fixture did not report its last frame")
}

/// Hands control back and forth; returns every handover in ms.
fn handovers(s: &MultirxSession, ctx: &mut PhaseContext, mark: LossMark) -> Result<Vec<f64>> {
    s.fly(0)?;
    s.receiver(1).set_tx(true)?;
    std::thread::sleep(SETTLE);
    let mut samples = Vec::new();
    for round in 0..ROUNDS {
        let (from, to) = if round % 2 == 0 { (0, 1) } else { (1, 0) };
        let t0 = mark(s, from)?;
        let f = s.fc.wait_for(
            t0,
            s.acquire_timeout(),
            &format!("pilot {} in control", to + 1),
            |f| s.shows_pilot(f, to),
        )?;
        let ms = f.at.ms_since(t0);
        ctx.log(format!("pilot {} → pilot {}: {ms:.3} ms", from + 1, to + 1));
        samples.push(ms);
        s.receiver(from).set_tx(true)?;
        std::thread::sleep(SETTLE);
    }
    Ok(samples)
}

fn record_worst(ctx: &mut PhaseContext, m: Handle, mut samples: Vec<f64>) {
    samples.sort_by(f64::total_cmp);
    let worst = samples.last().copied().unwrap_or(f64::NAN);
    ctx.record(m, worst);
    ctx.annotate(
        m,
        &format!(
            "worst of {}; median {:.3} ms, best {:.3} ms",
            samples.len(),
            samples[samples.len() / 2],
            samples[0]
        ),
    );
}

fn run(s: &MultirxSession, ctx: &mut PhaseContext, mark: LossMark, worst: Handle) -> Result<()> {
    let samples = handovers(s, ctx, mark)?;
    record_worst(ctx, worst, samples);
    Ok(())
}
