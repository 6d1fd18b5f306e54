//! MAVSDK itself as the ground station: `fixtures/mavsdk_gcs.py` (PyPI `mavsdk` 4.1.0, the
//! MAVSDK C++ library in its process) uploads plan after plan through the real router and
//! bridge over SiK with 10 % bursty loss each way, to the PX4-like fixture, with MAVSDK's own
//! timeouts and retries (0.5 s per step, every repeated request counted as a try, and 2.5 s
//! after its last item it gives up without telling the vehicle; see the router's
//! `mission::terminator`). Until this scenario that behaviour was only modelled
//! (`harness_sim::GcsMock::with_mavsdk_retry_counting`).
//!
//! Each upload is a plan of its own (shifted coordinates) and the flight-controller fixture
//! names every plan it accepts by its CRC, so MAVSDK's answer to each upload is checked
//! against what the vehicle took: they must never disagree. How many uploads succeed is
//! recorded without a limit: twenty uploads cannot show 99 %; the engine simulation
//! `mavsdk_uploads_at_ten_percent_bursty_loss_succeed_and_never_disagree` checks that on 100
//! seeds.

use anyhow::{Result, bail};

use super::{Scenario, Script, Unsigned, ensure_clean, run_session, spec};
use crate::mavlora::fixture::fc::FcEvent;
use crate::mavlora::fixture::gcs::GcsEvent;
use crate::mavlora::session::{Ground, MavsdkPlan, SessionDefaults};
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;
use crate::stats::Percentiles;

const SCENARIO_NAME: &str = "mavsdk_mission";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "MAVSDK 4.1 (the real library) uploads 20 plans of 30 items through bridge and router over SiK with 10 % bursty loss: its answer and the plan the autopilot took never disagree",
    plan,
};

const UPLOADS: u32 = 20;
const ITEMS: u32 = 30;

struct Measured {
    unsigned: Unsigned,
    disagreements: Handle,
    success_ratio: Handle,
    upload_p50_s: Handle,
    upload_max_s: Handle,
}

fn plan(d: &mut Declarations) -> Script {
    let m = Measured {
        unsigned: Unsigned::declare(d, SCENARIO_NAME),
        disagreements: d.declare(
            spec("mavsdk_mission_disagreements", "")
                .describe(format!(
                    "of {UPLOADS} MAVSDK uploads of {ITEMS} items: those MAVSDK called SUCCESS \
                     whose plan the autopilot fixture never accepted, those MAVSDK failed whose \
                     plan it accepted (then or later), plus plans it accepted that no upload sent \
                     (plans told apart by their CRC)"
                ))
                .equal_to(0.0),
        ),
        success_ratio: d.declare(spec("mavsdk_mission_success_ratio", "").describe(format!(
            "share of {UPLOADS} MAVSDK uploads it reported SUCCESS; recorded without a limit: \
             the 99 % target is checked on 100 seeds in the engine simulation \
             (harness::mavlora::simulated test \
             mavsdk_uploads_at_ten_percent_bursty_loss_succeed_and_never_disagree)"
        ))),
        upload_p50_s: d.declare(spec("mavsdk_mission_upload_p50_s", "s").describe(format!(
            "median of MAVSDK's upload_mission calls that succeeded (call to result, {ITEMS} \
             items); NaN when none did"
        ))),
        upload_max_s: d.declare(spec("mavsdk_mission_upload_max_s", "s").describe(format!(
            "slowest of MAVSDK's upload_mission calls that succeeded ({ITEMS} items)"
        ))),
    };
    Box::new(move |ctx, defaults| run(ctx, defaults, &m))
}

fn run(ctx: &mut PhaseContext, d: &SessionDefaults, m: &Measured) -> Result<()> {
    let mut o = d.options(SCENARIO_NAME, &d.lossy_radio, &ctx.dir.join(SCENARIO_NAME));
    o.ground = Ground::Mavsdk(MavsdkPlan {
        uploads: UPLOADS,
        items: ITEMS,
        pause_s: 1.0,
        settle_s: 5.0,
    });
    let report = run_session(ctx, o)?;
    let uploads: Vec<Upload> = report
        .gcs_events
        .iter()
        .filter_map(|l| match &l.event {
            GcsEvent::Upload {
                n,
                ok,
                result,
                seconds,
                count,
                crc,
                ..
            } => Some(Upload {
                n: *n,
                ok: *ok,
                result: result.clone(),
                seconds: *seconds,
                plan: (*count, *crc),
            }),
            _ => None,
        })
        .collect();
    let taken: Vec<(u32, u32)> = report
        .fc_events
        .iter()
        .filter_map(|l| match l.event {
            FcEvent::Mission { count, crc } => Some((count, crc)),
            _ => None,
        })
        .collect();
    for u in &uploads {
        ctx.log(format!(
            "upload {}: MAVSDK {} after {:.2} s; the autopilot {}",
            u.n,
            u.result,
            u.seconds,
            if taken.contains(&u.plan) {
                "took its plan"
            } else {
                "did not take its plan"
            }
        ));
    }
    let verdict = judge(&uploads, &taken);
    for why in &verdict.disagreements {
        ctx.log(format!("disagreement: {why}"));
    }
    let succeeded: Vec<f64> = uploads.iter().filter(|u| u.ok).map(|u| u.seconds).collect();
    let times = Percentiles::of(&succeeded);
    ctx.log(format!(
        "{} of {} uploads succeeded; the autopilot accepted {} plans; {} item requests, {} \
         duplicate items",
        succeeded.len(),
        uploads.len(),
        taken.len(),
        report.fc.item_requests,
        report.fc.duplicate_items
    ));
    ctx.record(m.disagreements, verdict.disagreements.len() as f64);
    ctx.record(m.success_ratio, succeeded.len() as f64 / f64::from(UPLOADS));
    ctx.record(m.upload_p50_s, times.p50);
    ctx.record(m.upload_max_s, times.max);
    m.unsigned.record(ctx, &[&report])?;
    ensure_clean(ctx, &report)?;
    if uploads.len() != UPLOADS as usize {
        bail!(
            "MAVSDK reported {} of {UPLOADS} uploads; see gcs.log",
            uploads.len()
        );
    }
    Ok(())
}

/// One upload as MAVSDK reported it.
#[derive(Debug, Clone, PartialEq)]
struct Upload {
    n: u32,
    ok: bool,
    result: String,
    seconds: f64,
    /// (items, CRC) of the plan it sent.
    plan: (u32, u32),
}

/// Where the ground's word and the vehicle's plan part.
#[derive(Debug, Default)]
struct Verdict {
    disagreements: Vec<String>,
}

/// Each upload's result against the plans the vehicle accepted (`taken`, (items, CRC) each,
/// in order): SUCCESS for a plan never taken, a failure for a plan taken (at any time: a plan
/// that lands after MAVSDK gave up is the silent disagreement), and any plan taken that no
/// upload sent.
fn judge(uploads: &[Upload], taken: &[(u32, u32)]) -> Verdict {
    let mut v = Verdict::default();
    for u in uploads {
        let took = taken.contains(&u.plan);
        if u.ok && !took {
            v.disagreements.push(format!(
                "upload {}: MAVSDK SUCCESS, but the autopilot never took its plan",
                u.n
            ));
        } else if !u.ok && took {
            v.disagreements.push(format!(
                "upload {}: MAVSDK {}, but the autopilot took its plan",
                u.n, u.result
            ));
        }
    }
    for plan in taken {
        if !uploads.iter().any(|u| u.plan == *plan) {
            v.disagreements.push(format!(
                "the autopilot took a plan of {} items (crc {}) that no upload sent",
                plan.0, plan.1
            ));
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    fn upload(n: u32, ok: bool) -> Upload {
        Upload {
            n,
            ok,
            result: if ok { "SUCCESS" } else { "TIMEOUT" }.into(),
            seconds: 1.0,
            plan: (30, 100 + n),
        }
    }

    #[test]
    fn a_result_disagrees_when_the_vehicle_did_otherwise() {
        let uploads = [upload(0, true), upload(1, false), upload(2, false)];
        // 0 taken as said; 1 failed and not taken: agreement; 2 failed but taken later.
        let v = judge(&uploads, &[(30, 100), (30, 102)]);
        assert_eq!(v.disagreements.len(), 1, "{:?}", v.disagreements);
        assert!(v.disagreements[0].contains("upload 2: MAVSDK TIMEOUT"));
        // SUCCESS for a plan never taken, and a plan nobody sent.
        let v = judge(&uploads[..1], &[(30, 999)]);
        assert_eq!(v.disagreements.len(), 2, "{:?}", v.disagreements);
        assert!(v.disagreements[1].contains("no upload sent"));
        assert!(judge(&[upload(0, false)], &[]).disagreements.is_empty());
    }
}
