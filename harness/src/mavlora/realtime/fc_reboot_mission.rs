//! The flight controller reboots in the middle of a mission upload (a brown-out, a
//! watchdog): the mission must end intact or fail loudly, never silently wrong. The
//! pymavlink ground station uploads 40 items over SiK with 10 % bursty loss; when item 15
//! reaches it, the PX4-like fixture reboots (4 s silent, then back with a new sequence and
//! uptime, forgetting the upload it was being given).
//!
//! The invariant is the ground's: told ACCEPTED only when the autopilot holds exactly the
//! plan it sent, told an error otherwise, and never left without an answer. Whether it
//! ends accepted, and how long it took, are recorded without a limit (MavLora restarts the
//! wire leg from `MISSION_COUNT`, so it should end accepted, but a loud failure is safe).

use anyhow::{Result, bail};

use super::mission::compare;
use super::{Scenario, Script, Unsigned, ensure_clean, run_session, spec};
use crate::mavlora::session::{GcsPlan, SessionDefaults};
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;

const SCENARIO_NAME: &str = "fc_reboot_mission";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "The flight controller reboots when item 15 of a 40-item upload over lossy SiK reaches it: the ground is told ACCEPTED only with the exact plan at the autopilot, an error otherwise, never nothing",
    plan,
};

const ITEMS: u32 = 40;
/// The item whose arrival reboots the flight controller.
const REBOOT_AT_ITEM: u32 = 15;
/// `MISSION_ACCEPTED`.
const ACCEPTED: i64 = 0;

struct Measured {
    unsigned: Unsigned,
    wrong_accept: Handle,
    unanswered: Handle,
    accepted: Handle,
    upload_s: Handle,
}

fn plan(d: &mut Declarations) -> Script {
    let m = Measured {
        unsigned: Unsigned::declare(d, SCENARIO_NAME),
        wrong_accept: d.declare(
            spec("fc_reboot_mission_mismatch_on_accept", "")
                .describe(
                    "1 when the ground was told ACCEPTED but the autopilot does not hold exactly \
                     the plan it sent (seq, command, frame, x, y, z, autocontinue, param1)",
                )
                .equal_to(0.0),
        ),
        unanswered: d.declare(
            spec("fc_reboot_mission_unanswered", "")
                .describe(
                    "1 when the ground got no MISSION_ACK at all within its 60 s upload timeout: \
                     a failure nobody was told of",
                )
                .equal_to(0.0),
        ),
        accepted: d.declare(spec("fc_reboot_mission_accepted", "").describe(
            "1 when the upload ended ACCEPTED (MavLora restarts the wire leg after the reboot), \
                 0 when it ended with an error the ground was told of",
        )),
        upload_s: d.declare(spec("fc_reboot_mission_upload_s", "s").describe(format!(
            "{ITEMS} items, MISSION_COUNT to the final MISSION_ACK at the ground, across the \
                 reboot (4 s of silence)"
        ))),
    };
    Box::new(move |ctx, defaults| run(ctx, defaults, &m))
}

fn run(ctx: &mut PhaseContext, d: &SessionDefaults, m: &Measured) -> Result<()> {
    let mut o = d.options(SCENARIO_NAME, &d.lossy_radio, &ctx.dir.join(SCENARIO_NAME));
    o.gcs = GcsPlan {
        listen_s: 2.0,
        items: ITEMS,
        upload_timeout_s: 60.0,
        ..GcsPlan::default()
    };
    o.fc_reboot_at_item = Some(REBOOT_AT_ITEM);
    let report = run_session(ctx, o)?;
    let (gcs, fc) = (&report.gcs, &report.fc);
    if fc.reboots == 0 {
        bail!(
            "the flight controller fixture reports no reboot: item {REBOOT_AT_ITEM} never              reached it, the fault did not take"
        );
    }
    let (intact, why) = compare(&gcs.mission, &fc.mission);
    ctx.log(format!(
        "ground: result {} after {}; autopilot: {} accepted uploads, {} item requests, {} \
         duplicate items, its plan {}",
        gcs.result.map_or("none".into(), |r| r.to_string()),
        gcs.upload_s.map_or("-".into(), |s| format!("{s:.2} s")),
        fc.missions_accepted,
        fc.item_requests,
        fc.duplicate_items,
        why.as_deref().unwrap_or("equals the ground's")
    ));
    let accepted = gcs.result == Some(ACCEPTED);
    ctx.record(m.wrong_accept, f64::from(u8::from(accepted && !intact)));
    ctx.record(m.unanswered, f64::from(u8::from(gcs.result.is_none())));
    ctx.record(m.accepted, f64::from(u8::from(accepted)));
    ctx.record(m.upload_s, gcs.upload_s.unwrap_or(f64::NAN));
    m.unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)
}
