//! Faults on the wire from the flying pilot's receiver: a burst of noise (often a torn
//! frame) before every frame, frames delivered three at a time (a USB-serial adapter's
//! latency timer), every frame ten times over. Each frame the receiver meant still arrives,
//! so the pilot must keep control throughout, nothing but the pilot's sticks may reach the
//! flight controller, and it must never see RC loss (the session's `rc_losses`).

use std::time::Duration;

use anyhow::{Result, bail};

use super::{ModeLimits, Scenario, Script, SessionOptions};
use crate::clock::Mono;
use crate::measurement::{Declarations, Handle};
use crate::multirx::driver::receiver::Loss;
use crate::multirx::driver::sbus_receiver::ReceiverEvent;
use crate::multirx::session::{MultirxSession, pilot_stick};
use crate::runner::PhaseContext;

pub const GARBAGE: Scenario = fault(
    "fault_receiver_garbage",
    "Noise and torn frames before every frame of the flying pilot's receiver for 3 s: pilot keeps control, no foreign sticks, no RC loss",
    |d, l| plan(d, l, "fault_receiver_garbage", "garbage"),
);

pub const STUTTER: Scenario = fault(
    "fault_receiver_stutter",
    "The flying pilot's frames arrive three at a time (21 ms clumps) for 3 s: pilot keeps control, output cadence holds, no RC loss",
    |d, l| plan(d, l, "fault_receiver_stutter", "stutter"),
);

pub const FLOOD: Scenario = fault(
    "fault_receiver_flood",
    "Every frame of the flying pilot's receiver ten times over for 3 s: pilot keeps control, output cadence holds, no RC loss",
    |d, l| plan(d, l, "fault_receiver_flood", "flood"),
);

/// A line-fault scenario: receivers that report a lost transmitter with the failsafe flag.
const fn fault(
    name: &'static str,
    summary: &'static str,
    plan: fn(&mut Declarations, &ModeLimits) -> Script,
) -> Scenario {
    Scenario {
        name,
        summary,
        options: SessionOptions {
            loss: Loss::Failsafe,
        },
        plan,
    }
}

/// How long the wire misbehaves.
const FAULT: Duration = Duration::from_secs(3);

/// Fault windows at most: one more when the fixture playing the receiver was itself held past
/// the device's silence timeout (then the device lost a link that truly went silent).
const WINDOWS: u32 = 2;

struct Handles {
    lost_control: Handle,
    foreign: Handle,
    stimulus_gap: Handle,
}

fn plan(d: &mut Declarations, l: &ModeLimits, name: &str, fault: &'static str) -> Script {
    let spec = |base: &str| l.session_spec(base, "", Some(name));
    let h = Handles {
        lost_control: d.declare(
            spec("control_lost_frames")
                .describe(
                    "frames at the flight controller, while the wire was faulty, not showing the \
                     flying pilot in control (every frame the receiver meant still arrived)",
                )
                .equal_to(0.0),
        ),
        foreign: d.declare(
            spec("foreign_stick_frames")
                .describe(
                    "frames at the flight controller, while the wire was faulty, whose sticks are \
                     neither the pilot's nor neutral: noise taken for a frame",
                )
                .equal_to(0.0),
        ),
        stimulus_gap: d.declare(l.session_spec("stimulus_max_gap_ms", "ms", Some(name)).describe(
            "longest interval between two writes of the receiver fixture in the counted window \
             (the host holding the stimulus, not the device); a window in which it exceeded the \
             device's silence timeout is repeated once, as the log says",
        )),
    };
    Box::new(move |s, ctx, _| run(s, ctx, fault, h))
}

fn run(s: &MultirxSession, ctx: &mut PhaseContext, fault: &str, h: Handles) -> Result<()> {
    let silence_ms = s.config.silence_timeout.as_secs_f64() * 1000.0;
    let mut gap_ms = 0.0;
    for window in 1..=WINDOWS {
        let (from, to, gap) = fault_window(s, ctx, fault)?;
        gap_ms = gap;
        if gap_ms <= silence_ms {
            count(s, ctx, fault, &h, from, to);
            ctx.record(h.stimulus_gap, gap_ms);
            if window > 1 {
                ctx.annotate(
                    h.lost_control,
                    &format!("window {window}: the earlier ones had a held stimulus (log)"),
                );
            }
            return Ok(());
        }
        ctx.log(format!(
            "window {window}: the host held the receiver fixture {gap_ms:.1} ms, past the \
             device's {silence_ms} ms silence timeout, so the link truly went silent; not counted"
        ));
    }
    // No verdict on the device from a stimulus the rig could not deliver: an error.
    bail!(
        "the receiver fixture was held past the device's {silence_ms} ms silence timeout in all \
         {WINDOWS} fault windows (last: {gap_ms:.1} ms): the host, not the device, broke the link"
    )
}

/// Pilot 1 flying, the fault on its receiver's wire for [`FAULT`]: the window's bounds and the
/// fixture's longest interval between writes in it (ms).
fn fault_window(
    s: &MultirxSession,
    ctx: &mut PhaseContext,
    fault: &str,
) -> Result<(Mono, Mono, f64)> {
    s.fly(0)?;
    ctx.log("pilot 1 in control");
    let from = Mono::now();
    s.receiver(0).set_line(fault)?;
    std::thread::sleep(FAULT);
    let clean = s.receiver(0).set_line("clean")?;
    let to = Mono::now();
    let ReceiverEvent::Line {
        noise_redrawn,
        max_write_gap_ms,
        ..
    } = clean
    else {
        unreachable!("set_line waits for a line event")
    };
    ctx.log(format!(
        "noise bursts drawn again because they framed as a frame: {noise_redrawn}; longest \
         interval between the fixture's writes: {max_write_gap_ms:.1} ms"
    ));
    Ok((from, to, max_write_gap_ms))
}

/// Records what reached the flight controller in the window: frames without the pilot, frames
/// with foreign sticks.
fn count(
    s: &MultirxSession,
    ctx: &mut PhaseContext,
    fault: &str,
    h: &Handles,
    from: Mono,
    to: Mono,
) {
    // Frames already on their way when the fault began or ended are the wire's, too.
    std::thread::sleep(Duration::from_millis(100));
    let during: Vec<_> =
        s.fc.frames()
            .into_iter()
            .filter(|f| f.at >= from && f.at <= to)
            .collect();
    let lost = during.iter().filter(|f| !s.shows_pilot(f, 0)).count();
    // Sticks are channels 1-4: the pilot's value, or neutral once nobody has control.
    let foreign = during
        .iter()
        .filter(|f| {
            (0..4).any(|k| f.channels[k] != pilot_stick(0) && f.channels[k] != s.config.neutral[k])
        })
        .count();
    ctx.log(format!(
        "line {fault} for {FAULT:?}: {} frames at the flight controller, {lost} without pilot 1, {foreign} with foreign sticks",
        during.len()
    ));
    ctx.record(h.lost_control, lost as f64);
    ctx.record(h.foreign, foreign as f64);
}
