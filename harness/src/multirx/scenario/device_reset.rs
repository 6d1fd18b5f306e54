//! MultiRX itself resets in flight (a panic, the watchdog, a debugger): the chip stops,
//! its power-switch gates float and their pull-downs switch every receiver off, and the
//! firmware boots again and powers them back on, 20 ms apart. Decided (issue 24): a reset
//! costs the pilot the receivers' own boot and bind; meanwhile the flight controller gets
//! neutral sticks at auto-loiter from the first frame after the reset, and never RC loss.
//! Keeping the receivers powered through a reset would need switches that default to on,
//! which also power all six at once at every power-up (`samd21/README.md`, "A reset in
//! flight").
//!
//! A board is reset through its debug probe (a system reset request, as a panic makes); an
//! emulated device's program is killed and started again, its receivers switched off as the
//! reset would.

use std::time::Duration;

use anyhow::{Context, Result};
use multirx_core::boot::ResetCause;

use super::{FIRST_FRAME_MAX_MS, ModeLimits, SETTLE, Scenario, Script, SessionOptions};
use crate::measurement::{Declarations, Handle};
use crate::multirx::driver::receiver::Loss;
use crate::multirx::px4_rc_input::FcFrame;
use crate::multirx::session::{MultirxSession, POSITION_MODE};
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "fault_device_reset",
    summary: "MultiRX resets in flight as a panic does: no RC loss, auto-loiter with neutral sticks while the receivers it switched off and on boot and bind, then the pilot is back in control",
    options: SessionOptions {
        loss: Loss::Failsafe,
    },
    plan,
};

/// PX4's COM_RC_LOSS_T default: a gap this long in the output is RC loss.
const PX4_RC_LOSS_MS: f64 = 500.0;

/// Longest wait for the boot line after the reset: it follows the first frame, and the
/// firmware repeats it every second.
const BOOT_LINE_AFTER_RESET: Duration = Duration::from_secs(3);

struct Handles {
    gap: Handle,
    rc_losses: Handle,
    first_frame: Handle,
    not_loiter: Handle,
    back: Handle,
}

fn plan(d: &mut Declarations, l: &ModeLimits) -> Script {
    let h = Handles {
        gap: d.declare(
            l.spec("reset_output_gap_ms", "ms")
                .describe(
                    "longest interval between frames at the flight controller across the reset \
                     (emulated device: the host starting the program again; board: the reset and \
                     the boot); limit: PX4's RC-loss timeout (COM_RC_LOSS_T, 0.5 s)",
                )
                .at_most(PX4_RC_LOSS_MS),
        ),
        rc_losses: d.declare(
            l.spec("reset_rc_losses", "")
                .describe("times PX4 would have declared RC loss from 1 s before the reset until the pilot was back")
                .equal_to(0.0),
        ),
        first_frame: d.declare(
            l.spec("reset_boot_to_first_frame_ms", "ms")
                .describe(
                    "the boot line after the reset (cause `software`): from the device's clock \
                     start to its first SBUS frame; limit: the project's boot target, a tenth of \
                     PX4's RC-loss timeout",
                )
                .at_most(FIRST_FRAME_MAX_MS),
        ),
        not_loiter: d.declare(
            l.spec("reset_frames_not_loiter", "frames")
                .describe(
                    "frames between the reset and the pilot's return that were not neutral \
                     sticks at auto-loiter with the pilot channel at 'none' (a reset must not \
                     replay a stale pilot or hand control to anyone unbound)",
                )
                .equal_to(0.0),
        ),
        back: d.declare(
            l.spec("reset_pilot_back_ms", "ms")
                // The receivers' boot and bind are theirs, not MultiRX's (the emulated
                // receivers take their configured boot time): recorded, no requirement.
                .describe(
                    "reset → the pilot in control again: receivers switched back on (20 ms \
                     apart), their boot and bind, and acquisition",
                ),
        ),
    };
    Box::new(move |s, ctx, _| run(s, ctx, h))
}

fn run(s: &MultirxSession, ctx: &mut PhaseContext, h: Handles) -> Result<()> {
    let fm = s.config.flight_mode_channel + 1;
    s.receiver(0).set_channels(&[(fm, POSITION_MODE)])?;
    s.fly(0)?;
    std::thread::sleep(SETTLE);
    ctx.log("pilot 1 in control in position mode; resetting MultiRX");

    let reset = s.reset_device()?;
    // Frames already on the line when the chip stopped are read just after it: the pilot
    // counts as back only after the restarted device's auto-loiter.
    let loiter = s.fc.wait_for(
        reset,
        Duration::from_secs(2),
        "auto-loiter with no pilot after the reset",
        |f| s.shows_loiter(f),
    )?;
    let back = s.fc.wait_for(
        loiter.at,
        s.acquire_timeout(),
        "pilot 1 in control again after the reset",
        |f| s.shows_pilot(f, 0),
    )?;
    let boot = s
        .boot_after(reset, ResetCause::Software, BOOT_LINE_AFTER_RESET)
        .with_context(|| {
            format!(
                "no boot line reporting a `software` reset within {BOOT_LINE_AFTER_RESET:?} of \
                 the reset (the device reset, or reports another cause)"
            )
        })?;

    let frames = s.fc.frames();
    // The gap: the longest interval from the last frame read before the reset to the
    // pilot's return.
    let before = frames.partition_point(|f| f.at <= reset).saturating_sub(1);
    let window: Vec<&FcFrame> = frames[before..]
        .iter()
        .take_while(|f| f.at <= back.at)
        .collect();
    let (gap_ms, resumed) = window
        .windows(2)
        .map(|w| (w[1].at.ms_since(w[0].at), w[1].at))
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .context("no frames at the flight controller around the reset")?;
    let not_loiter = window
        .iter()
        .filter(|f| f.at >= resumed && f.at < back.at)
        .filter(|f| !s.shows_loiter(f))
        .count();
    let losses = s
        .px4_replay(reset - Duration::from_secs(1), back.at)
        .rc_losses
        .len();
    // The session's own figures judge the restarted device, from its first frame.
    s.judge_from(resumed);

    ctx.record(h.gap, gap_ms);
    ctx.record(h.rc_losses, losses as f64);
    ctx.record(h.first_frame, boot.first_frame.as_secs_f64() * 1000.0);
    ctx.record(h.not_loiter, not_loiter as f64);
    ctx.record(h.back, back.at.ms_since(reset));
    ctx.log(format!(
        "reset: output resumed after {gap_ms:.1} ms (boot line: first frame {:.3} ms after the \
         clock started), pilot 1 back {:.0} ms after the reset",
        boot.first_frame.as_secs_f64() * 1000.0,
        back.at.ms_since(reset)
    ));
    Ok(())
}
