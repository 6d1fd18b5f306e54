//! A 30-item plan uploaded through compact MavLora to a real autopilot and read back, as a
//! ground station does it; then the truth connection reads the plan the vehicle holds.
//!
//! Invariant (issue 21/22): the ground is told ACCEPTED only for the plan the vehicle holds,
//! item by item. An upload that fails is reported as failed, never as accepted.

use std::time::Duration;

use anyhow::bail;

use super::{Flavour, Scenario, Script, Target, options, run};
use crate::mavlora::fixture::sitl::{GroundEvent, PlanItem, TruthEvent};
use crate::mavlora::session::SessionDefaults;
use crate::measurement::Declarations;

pub const SCENARIO: Scenario = Scenario {
    name: "mission",
    summary: "A 30-item mission uploaded and downloaded by a pymavlink ground station: \
              ACCEPTED, the download equal, and the vehicle holding exactly that plan (truth \
              connection)",
    plan,
    radios: |p| &p.mission,
};

const ITEMS: u32 = 30;
const MISSION: u8 = 0;
/// MAV_MISSION_ACCEPTED.
const ACCEPTED: u8 = 0;

/// Whether two plans are the same item by item. ArduPilot keeps item 0 as the vehicle's
/// home and writes its own home there, so with `home_first` item 0 is compared by command
/// only.
pub fn same_plan(a: &[PlanItem], b: &[PlanItem], home_first: bool) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).enumerate().all(|(i, (x, y))| {
            if i == 0 && home_first {
                x.command == y.command
            } else {
                x.same_as(y)
            }
        })
}

fn plan(d: &mut Declarations, t: &Target) -> Script {
    let accepted = d.declare(
        t.spec("mission_accepted", "")
            .describe("1 when the ground station got MISSION_ACK ACCEPTED for its upload")
            .equal_to(1.0),
    );
    let upload_s = d.declare(
        t.spec("mission_upload_s", "s")
            .describe("MISSION_COUNT to the final MISSION_ACK at the ground station"),
    );
    let download_equal = d.declare(
        t.spec("mission_download_equal", "")
            .describe("1 when the plan downloaded through the link equals the one uploaded")
            .equal_to(1.0),
    );
    let false_accepted = d.declare(
        t.spec("plans_differing_from_accepted", "")
            .describe(
                "uploads the ground was told ACCEPTED whose plan the vehicle (truth connection) \
                 does not hold item by item",
            )
            .equal_to(0.0),
    );
    Box::new(move |ctx, defaults: &SessionDefaults, t: &Target| {
        let args = vec![
            "--scenario".into(),
            "mission".into(),
            "--items".into(),
            ITEMS.to_string(),
            "--download".into(),
        ];
        let dir = ctx.dir.clone();
        let mut o = options(defaults, t, &dir, args, Duration::from_secs(200));
        o.truth_after = vec![format!("mission {MISSION}")];
        let report = run(ctx, o)?;
        let upload = report.ground_events().find_map(|e| match e {
            GroundEvent::Upload {
                items,
                result,
                seconds,
                ..
            } => Some((items.clone(), *result, *seconds)),
            _ => None,
        });
        let Some((sent, result, seconds)) = upload else {
            bail!("the ground station reported no upload");
        };
        let home_first = t.flavour() == Flavour::ArduPilot;
        let ok = result == Some(ACCEPTED);
        ctx.record(accepted, f64::from(u8::from(ok)));
        ctx.record(upload_s, seconds);
        ctx.log(format!(
            "upload of {} items: ack {result:?} after {seconds:.2} s",
            sent.len()
        ));
        let down = report.ground_events().find_map(|e| match e {
            GroundEvent::Download { items, .. } => Some(items.clone()),
            _ => None,
        });
        if let Some(down) = down {
            let equal = down
                .as_deref()
                .is_some_and(|d| same_plan(d, &sent, home_first));
            ctx.record(download_equal, f64::from(u8::from(equal)));
        }
        let held = report.truth.iter().rev().find_map(|e| match e {
            TruthEvent::Mission {
                mission_type: MISSION,
                items,
                ..
            } => Some(items.clone()),
            _ => None,
        });
        let Some(held) = held else {
            bail!("the truth connection did not read the vehicle's mission");
        };
        ctx.log(format!("the vehicle holds {} items", held.len()));
        ctx.record(
            false_accepted,
            f64::from(u8::from(ok && !same_plan(&held, &sent, home_first))),
        );
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn item(seq: u16, frame: u8, command: u16, z: f32) -> PlanItem {
        PlanItem {
            seq,
            frame,
            command,
            x: -353_632_610 + i32::from(seq),
            y: 1_491_652_300,
            z,
            param1: 0.0,
            param2: 0.0,
            param3: 0.0,
            param4: 0.0,
            autocontinue: 1,
        }
    }

    #[test]
    fn a_plan_is_compared_as_a_vehicle_stores_it() {
        let sent = vec![
            item(0, 0, 16, 584.0),
            item(1, 6, 22, 20.0),
            item(2, 2, 20, 0.0),
        ];
        // ArduPilot: its own home at 0, the _INT frame as its twin, RTL in frame GLOBAL.
        let mut held = vec![
            item(0, 0, 16, 590.0),
            item(1, 3, 22, 20.004),
            item(2, 0, 20, 0.0),
        ];
        held[0].x += 55;
        assert!(same_plan(&held, &sent, true));
        assert!(!same_plan(&held, &sent, false), "PX4 has no home item");
        let mut moved = held.clone();
        moved[1].x += 1;
        assert!(!same_plan(&moved, &sent, true), "a waypoint moved by 1e-7°");
        let mut higher = held.clone();
        higher[1].z += 0.5;
        assert!(!same_plan(&higher, &sent, true));
        let mut terrain = held.clone();
        terrain[1].frame = 10;
        assert!(!same_plan(&terrain, &sent, true), "another altitude frame");
        assert!(!same_plan(&held[..2], &sent, true), "an item missing");
    }
}
