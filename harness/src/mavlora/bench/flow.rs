//! `mavlora::bench::flow_control`: the radio's real throughput at half its nominal rate, and
//! the bridge and router budgeted for the nominal one, as an operator configures them for a
//! 64 kbit/s SiK: the rig turns ECC on in both radios through the SiK driver (`ATS5=1` /
//! `RTS5=1`, `AT&W`, `ATZ`: Golay coding halves what each packet carries), then runs the
//! real programs over the path with PX4's USB stream profile behind the bridge and a profile
//! that passes every message (several times what the radio carries). The programs pace themselves by the radio's `RADIO_STATUS` `txbuf`
//! (`mavlora::schedule::TxbufPacer`); the radio must drop nothing and carry at least 75 % of
//! its real throughput (mLRS aims at 75-85 % link use). ECC goes back off at the end.

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};

use super::path::RfPath;
use super::rigfile::{BenchPlan, RadioFirmware, RadioPath};
use crate::driver::sik::{SikClient, Which};
use crate::mavlora::realtime::{ensure_clean, keep_evidence};
use crate::mavlora::session::{
    FcProfile, GcsPlan, MavloraSession, RadioPath as SessionRadio, SessionDefaults,
};
use crate::measurement::{Declarations, Dimension, Handle, Spec};
use crate::runner::{Phase, PhaseContext};
use harness_radio::sik::Param;
use harness_radio::{Direction, Preset};

pub const NAME: &str = "flow_control";
pub const SUMMARY: &str = "SiK with ECC on (half the nominal throughput), the programs budgeted for the nominal rate: paced by the radio's txbuf, nothing dropped by the radio and >= 75 % of its real throughput used";

/// Settling before the measured window (the pacer takes a report a second).
const RAMP: Duration = Duration::from_secs(8);
/// The measured window.
const WINDOW: Duration = Duration::from_secs(20);

struct Measured {
    dropped: Handle,
    used: Handle,
}

fn spec(base: &str, unit: &str) -> Spec {
    Spec::new(base, unit)
        .dim(Dimension::Device, "mavlora")
        .dim(Dimension::Transport, "bench")
        .dim(Dimension::Radio, "sik_64k_ecc")
}

fn declare(d: &mut Declarations) -> Measured {
    Measured {
        dropped: d.declare(
            spec("radio_bytes_dropped", "B")
                .describe(
                    "bytes the drone's radio dropped from a full buffer, downlink, from the \
                     programs' start to the end of the window",
                )
                .equal_to(0.0),
        ),
        used: d.declare(
            spec("throughput_used_pct", "%")
                .describe(format!(
                    "downlink bytes the radio delivered per second over {} s, against one \
                     direction's capacity of SiK 64k with ECC (full packets in its TDM share)",
                    WINDOW.as_secs()
                ))
                .at_least(75.0),
        ),
    }
}

fn set_ecc(ground_port: &str, baud: u32, on: bool) -> Result<()> {
    {
        let mut sik = SikClient::open(ground_port, baud)?;
        sik.enter_command_mode()?;
        sik.set_both(Param::Ecc, u32::from(on))?;
        sik.write_and_reboot()?;
    }
    // Both came back with it, or the link never will.
    let mut sik = SikClient::open(ground_port, baud)?;
    sik.enter_command_mode()?;
    for which in [Which::Local, Which::Remote] {
        let ecc = sik.get(which, Param::Ecc)?;
        if ecc != u32::from(on) {
            bail!("{ground_port}: ECC reads {ecc} on the {which:?} radio after the reboot");
        }
    }
    sik.leave_command_mode()?;
    Ok(())
}

fn run(
    ctx: &mut PhaseContext,
    plan: &BenchPlan,
    defaults: &SessionDefaults,
    m: &Measured,
) -> Result<()> {
    let RadioPath::Emulated(radio) = &plan.path else {
        bail!(
            "a bench session over real radios is not supported yet: run the attenuation sweep \
             on them, and sessions on the emulated path"
        );
    };
    if plan.firmware != RadioFirmware::Sik {
        bail!("flow control needs radios that report their buffer: radio_firmware = \"sik\"");
    }
    let mut path = RfPath::open(plan)?;
    set_ecc(&path.ground_port, path.baud, true).context("turning ECC on in both radios")?;
    path.attenuator
        .set_db(plan.session_db - plan.fixed_db)
        .context("setting the session's attenuation")?;
    let emulator = path
        .emulator
        .clone()
        .context("the emulated path has no emulator")?;
    let nominal = Preset::sik_64k();
    let real = harness_sim::direction_capacity(&Preset::sik_64k_ecc());
    let mut o = defaults.options("bench_flow", &radio.setup, &ctx.dir.join("bench_flow"));
    // What an operator gives a 64 kbit/s SiK: its nominal budget, not the ECC one.
    o.rate = harness_sim::scheduler_for(Some(&nominal)).rate_bytes_per_s;
    o.radio_path = Some(SessionRadio(emulator.clone()));
    o.fc_profile = FcProfile::Config;
    o.compact = false;
    // Everything the autopilot streams goes to the radio: PX4's USB rates are several times
    // what the radio carries, so only the pacing keeps the radio's buffer from overflowing.
    let pass_all = ctx.dir.join("pass-all.toml");
    std::fs::create_dir_all(&ctx.dir)?;
    std::fs::write(
        &pass_all,
        "# Bench flow control: every message to the radio, at the autopilot's rate.\n\
         [defaults]\nradio = \"pass\"\n",
    )
    .with_context(|| format!("writing {}", pass_all.display()))?;
    o.bridge_profile = pass_all;
    o.gcs = GcsPlan {
        listen_s: (RAMP + WINDOW).as_secs_f64() + 5.0,
        commands: 0,
        ..GcsPlan::default()
    };
    ctx.log(format!(
        "programs budgeted at {} B/s (SiK 64k); the radio carries {real:.0} B/s with ECC",
        o.rate
    ));
    let session = MavloraSession::start(o)?;
    std::thread::sleep(RAMP);
    let before = emulator.stats(Direction::Downlink);
    std::thread::sleep(WINDOW);
    let after = emulator.stats(Direction::Downlink);
    let report = session.finish()?;
    keep_evidence(ctx, "bench_flow", &report);
    let rate = (after.bytes_delivered - before.bytes_delivered) as f64 / WINDOW.as_secs_f64();
    ctx.log(format!(
        "downlink: {rate:.0} B/s delivered in the window; {} B offered and {} B dropped \
         since the start, {} B of them before the window",
        after.bytes_offered, after.bytes_dropped, before.bytes_dropped
    ));
    ctx.record(m.dropped, after.bytes_dropped as f64);
    ctx.record(m.used, 100.0 * rate / real);
    set_ecc(&path.ground_port, path.baud, false).context("turning ECC off again")?;
    ensure_clean(ctx, &report)
}

/// The phase for `plan`.
pub fn phase(plan: Arc<BenchPlan>, defaults: Arc<SessionDefaults>) -> Phase {
    let mut declared = Declarations::new();
    let measured = declare(&mut declared);
    Phase::measured(
        format!("mavlora::bench::{NAME}"),
        SUMMARY,
        declared,
        move |ctx| run(ctx, &plan, &defaults, &measured),
    )
}
