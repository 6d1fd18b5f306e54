//! A mission upload through the bridge's relay over SiK with 10 % bursty
//! loss each way: the flight controller retries items every 250 ms (PX4
//! issue #11078), the relay must keep that off the radio and deliver every
//! item intact.

use anyhow::Result;

use super::{Scenario, Script, Unsigned, ensure_clean, run_session, spec};
use crate::mavlora::fixture::gcs::MissionItem;
use crate::mavlora::session::{GcsPlan, SessionDefaults};
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;

const SCENARIO_NAME: &str = "mission";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "40-item mission upload through bridge and router over SiK with 10 % bursty loss; items intact at the FC",
    plan,
};

const ITEMS: u32 = 40;

fn plan(d: &mut Declarations) -> Script {
    let upload_s = d.declare(
        spec("mission_upload_s", "s")
            .describe(format!(
                "{ITEMS} items, GCS MISSION_COUNT to MISSION_ACK (accepted) as the pymavlink GCS timed it; \
                 NaN when not accepted within 90 s"
            ))
            .at_most(60.0),
    );
    let intact = d.declare(
        spec("mission_items_intact", "")
            .describe(
                "1 when the FC fixture's stored mission equals what the GCS sent, item for item \
                 (seq, command, frame, x, y, z, autocontinue, param1), else 0",
            )
            .equal_to(1.0),
    );
    let unsigned = Unsigned::declare(d, SCENARIO_NAME);
    Box::new(move |ctx, defaults| run(ctx, defaults, upload_s, intact, unsigned))
}

fn run(
    ctx: &mut PhaseContext,
    d: &SessionDefaults,
    upload_time: Handle,
    items_intact: Handle,
    unsigned: Unsigned,
) -> Result<()> {
    let mut o = d.options("mission", &d.lossy_radio, &ctx.dir.join("mission"));
    o.gcs = GcsPlan {
        listen_s: 2.0,
        items: ITEMS,
        upload_timeout_s: 90.0,
        ..GcsPlan::default()
    };
    let report = run_session(ctx, o)?;
    let (gcs, fc) = (&report.gcs, &report.fc);
    let accepted = gcs.result == Some(0);
    let upload_s = gcs.upload_s.unwrap_or(f64::NAN);
    ctx.log(format!(
        "result {} after {upload_s:.2} s; GCS sent {} item messages; FC: {} item requests, {} duplicate items",
        gcs.result.map_or("none".into(), |r| r.to_string()),
        gcs.items_sent,
        fc.item_requests,
        fc.duplicate_items
    ));
    ctx.record(upload_time, if accepted { upload_s } else { f64::NAN });
    let (intact, why) = compare(&gcs.mission, &fc.mission);
    if let Some(why) = why {
        ctx.log(format!("mission differs: {why}"));
    }
    ctx.record(items_intact, if intact { 1.0 } else { 0.0 });
    unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)
}

/// Whether the FC holds exactly the mission the GCS sent; else the first difference.
pub fn compare(sent: &[MissionItem], got: &[MissionItem]) -> (bool, Option<String>) {
    if sent.is_empty() || sent.len() != got.len() {
        return (
            false,
            Some(format!(
                "{} items sent, {} at the FC",
                sent.len(),
                got.len()
            )),
        );
    }
    for (s, g) in sent.iter().zip(got) {
        let exact = [
            ("seq", i64::from(s.seq), i64::from(g.seq)),
            ("command", s.command.into(), g.command.into()),
            ("frame", s.frame.into(), g.frame.into()),
            ("x", s.x.into(), g.x.into()),
            ("y", s.y.into(), g.y.into()),
            ("autocontinue", s.autocontinue.into(), g.autocontinue.into()),
        ];
        for (key, a, b) in exact {
            if a != b {
                return (false, Some(format!("item {} {key}: {a} vs {b}", s.seq)));
            }
        }
        for (key, a, b) in [("z", s.z, g.z), ("param1", s.param1, g.param1)] {
            // float32 on the wire
            if (a - b).abs() > 1e-6 * a.abs().max(1.0) || a.is_nan() || b.is_nan() {
                return (false, Some(format!("item {} {key}: {a} vs {b}", s.seq)));
            }
        }
    }
    (true, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_changed_or_missing_item_is_not_intact() {
        let item = |seq: u16, x: i32| MissionItem {
            seq,
            command: 16,
            frame: 6,
            x,
            y: 2,
            z: 50.0,
            autocontinue: 1,
            param1: 0.0,
        };
        let sent = [item(0, 10), item(1, 11)];
        assert!(compare(&sent, &[item(0, 10), item(1, 11)]).0);
        let (intact, why) = compare(&sent, &[item(0, 10), item(1, 12)]);
        assert!(!intact && why.unwrap().contains("item 1 x"));
        assert!(!compare(&sent, &[item(0, 10)]).0);
        assert!(!compare(&[], &[]).0);
    }
}
