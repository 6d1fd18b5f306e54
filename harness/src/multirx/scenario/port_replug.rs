//! The flying pilot's receiver wire is pulled out in flight and put back 1 s later (a
//! USB-serial adapter knocked loose). Its port hangs up under the device and its stable
//! name leads nowhere until a new one appears under it. MultiRX must treat the dead input
//! as that receiver's link loss (auto-loiter with neutral sticks within the silent-loss
//! bound, the flight controller never seeing RC loss: the session's `rc_losses`), reopen
//! the port by itself once it is back, and give the pilot control again.
//!
//! Emulated rigs only: a bench's adapters are real, and the rig cannot pull them out.

use std::time::Duration;

use anyhow::Result;

use super::{ModeLimits, Scenario, Script, SessionOptions};
use crate::clock::Mono;
use crate::measurement::{Declarations, Handle};
use crate::multirx::driver::receiver::Loss;
use crate::multirx::session::{MultirxSession, POSITION_MODE};
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "fault_receiver_replug",
    summary: "The flying pilot's receiver wire is unplugged in flight for 1 s and plugged back: auto-loiter with neutral sticks, no RC loss, the device reopens the port and the pilot is back in control",
    options: SessionOptions {
        loss: Loss::Failsafe,
    },
    plan,
};

/// How long the wire stays out.
const OUT: Duration = Duration::from_secs(1);
/// The longest the emulated device waits between two attempts to reopen an input that went
/// away (multirx-emu's backoff ceiling): the most a returning port can go unnoticed.
const REOPEN_MAX: Duration = Duration::from_secs(1);

/// Scan mode: a replugged receiver is back in control within one scan cycle plus this (the
/// reopen backoff, the receiver's boot and acquisition; issue 24's target).
const REPLUG_SCAN_MARGIN_MS: f64 = 2000.0;

struct Handles {
    entry: Handle,
    back: Handle,
}

fn plan(d: &mut Declarations, l: &ModeLimits) -> Script {
    let h = Handles {
        entry: d.declare(
            l.spec("port_replug_loiter_entry_ms", "ms")
                .describe(
                    "the flying pilot's receiver wire unplugged → flight-mode channel at \
                     auto-loiter, neutral sticks and pilot channel at 'none'; limit: the \
                     silent-loss bound of this mode (a dead port is a silent receiver)",
                )
                .at_most(l.handover_silent_ms),
        ),
        back: d.declare({
            let spec = l.spec("port_replug_recovery_ms", "ms").describe(
                "the wire plugged back → the pilot in control again: the device's reopen \
                 (backoff up to 1 s) and acquisition; scan mode: limit one scan cycle (every \
                 receiver's window) plus 2 s (issue 24)",
            );
            match l.scan_cycle_ms {
                Some(cycle) => spec.at_most(cycle + REPLUG_SCAN_MARGIN_MS),
                // Parallel: bounded by the script (the reopen backoff ceiling plus the
                // session's acquire timeout, else the phase fails); no requirement: recorded.
                None => spec,
            }
        }),
    };
    Box::new(move |s, ctx, _| run(s, ctx, h))
}

fn run(s: &MultirxSession, ctx: &mut PhaseContext, h: Handles) -> Result<()> {
    let fm = s.config.flight_mode_channel + 1;
    s.receiver(0).set_channels(&[(fm, POSITION_MODE)])?;
    s.fly(0)?;
    ctx.log("pilot 1 in control in position mode");
    let replug = std::thread::scope(|scope| {
        let unplugged = Mono::now();
        let replug = scope.spawn(|| s.replug_receiver(0, OUT));
        let loiter = s.fc.wait_for(
            unplugged,
            s.acquire_timeout(),
            "auto-loiter with no pilot",
            |f| s.shows_loiter(f),
        );
        let back = replug.join().expect("the replug thread panicked");
        (unplugged, loiter, back)
    });
    let (unplugged, loiter, back) = replug;
    let (loiter, back) = (loiter?, back?);
    ctx.record(h.entry, loiter.at.ms_since(unplugged));
    let again = s.fc.wait_for(
        back,
        s.acquire_timeout() + REOPEN_MAX,
        "pilot 1 in control again after the replug",
        |f| s.shows_pilot(f, 0),
    )?;
    ctx.record(h.back, again.at.ms_since(back));
    ctx.log(format!(
        "receiver 1's wire out for {OUT:?}: loiter after {:.0} ms, pilot 1 back {:.0} ms after it was plugged in",
        loiter.at.ms_since(unplugged),
        again.at.ms_since(back)
    ));
    Ok(())
}
