//! The whole parameter list as QGroundControl downloads it (PARAM_REQUEST_LIST, then
//! re-reads by index of what is missing), through compact MavLora from a real autopilot,
//! with a PARAM_SET sent while the list is in flight and checked on the truth connection.
//!
//! Limits (issue targets): all parameters at the ground, SiK ≤ 15 s clean and ≤ 30 s at
//! 10 % loss, LoRa SF7 ≤ 120 s; a PARAM_SET echoed within 1 s even while a list is in flight;
//! position ≥ 2 Hz throughout.

use std::time::Duration;

use anyhow::{Context, bail};

use super::telemetry::PositionHandles;
use super::{Flavour, Scenario, Script, Target, freshness, options, run};
use crate::mavlora::fixture::sitl::{GroundEvent, TruthEvent};
use crate::mavlora::session::SessionDefaults;
use crate::measurement::Declarations;

pub const SCENARIO: Scenario = Scenario {
    name: "params",
    summary: "All parameters as QGroundControl downloads them (SiK <= 15 s, <= 30 s at loss; \
              LoRa SF7 <= 120 s), a PARAM_SET echoed within 1 s while the list is in flight \
              and held by the vehicle, position >= 2 Hz meanwhile",
    plan,
    radios: |p| &p.params,
};

/// The ground station gives up on the list after this long.
const LIST_TIMEOUT_S: f64 = 150.0;

/// A harmless parameter to set, and the value: the return altitude (ArduPilot in cm, PX4 in m).
fn parameter(f: Flavour) -> (&'static str, f64) {
    match f {
        Flavour::ArduPilot => ("RTL_ALT", 2_500.0),
        Flavour::Px4 => ("RTL_RETURN_ALT", 45.0),
    }
}

/// The list's limit for this radio: `None` where the issue sets none.
fn list_limit(t: &Target) -> Option<f64> {
    match (t.preset().as_str(), t.lossy()) {
        ("sik-64k" | "sik-64k-ecc", false) => Some(15.0),
        ("sik-64k" | "sik-64k-ecc", true) => Some(30.0),
        ("lora-sf7", _) => Some(120.0),
        _ => None,
    }
}

fn plan(d: &mut Declarations, t: &Target) -> Script {
    let list = t
        .spec("params_s", "s")
        .describe("from PARAM_REQUEST_LIST to the last missing parameter at the ground station");
    let list = d.declare(match list_limit(t) {
        Some(max) => list.at_most(max),
        None => list,
    });
    let missing = d.declare(
        t.spec("params_missing", "")
            .describe("parameters the autopilot announced (param_count) that never arrived")
            .equal_to(0.0),
    );
    let rereads = d.declare(
        t.spec("params_rereads", "")
            .describe("PARAM_REQUEST_READs by index the ground station needed"),
    );
    let echo = d.declare(
        t.spec("param_set_echo_s", "s")
            .describe("PARAM_SET sent while the list was in flight to its PARAM_VALUE echo")
            .at_most(1.0),
    );
    let held = d.declare(
        t.spec("param_set_held", "")
            .describe("1 when the truth connection reads the value the ground station set")
            .equal_to(1.0),
    );
    let positions = PositionHandles::declare(d, t, false, 2.0);
    Box::new(move |ctx, defaults: &SessionDefaults, t: &Target| {
        let (name, value) = parameter(t.flavour());
        let args = vec![
            "--scenario".into(),
            "params".into(),
            "--param-timeout".into(),
            LIST_TIMEOUT_S.to_string(),
            "--set".into(),
            format!("{name}={value}"),
        ];
        let dir = ctx.dir.clone();
        let budget = Duration::from_secs_f64(LIST_TIMEOUT_S + 40.0);
        let mut o = options(defaults, t, &dir, args, budget);
        o.truth_after = vec![format!("param {name}")];
        let report = run(ctx, o)?;
        let done = report.ground_events().find_map(|e| match e {
            GroundEvent::Params {
                t,
                count,
                total,
                seconds,
                rereads: r,
            } => Some((*t, *count, *total, *seconds, *r)),
            _ => None,
        });
        let Some((end, count, total, seconds, r)) = done else {
            bail!("the ground station reported no parameter download");
        };
        ctx.record(missing, f64::from(total.saturating_sub(count)));
        ctx.record(rereads, f64::from(r));
        if count == total && total > 0 {
            ctx.record(list, seconds);
        } else {
            ctx.log(format!(
                "only {count} of {total} parameters after {seconds:.1} s"
            ));
        }
        let during = report.ground_events().find_map(|e| match e {
            GroundEvent::ParamSet {
                echo_s,
                during_list: true,
                ..
            } => Some(*echo_s),
            _ => None,
        });
        match during {
            Some(Some(s)) => ctx.record(echo, s),
            Some(None) => ctx.log(format!(
                "{name}: no echo of the PARAM_SET sent during the list"
            )),
            None => ctx.log("the ground station sent no PARAM_SET during the list"),
        }
        let truth = report.truth.iter().rev().find_map(|e| match e {
            TruthEvent::Param {
                name: n, value: v, ..
            } if n == name => Some(*v),
            _ => None,
        });
        let truth = truth.with_context(|| format!("the truth connection never read {name}"))?;
        ctx.log(format!("{name} on the vehicle: {truth} (set {value})"));
        ctx.record(held, f64::from(u8::from((truth - value).abs() < 1e-3)));
        // Position freshness while the list was in flight.
        let start = report.ground_events().find_map(|e| match e {
            GroundEvent::WindowStart { t } => Some(*t),
            _ => None,
        });
        let start = start.context("the ground station's window")?;
        let ground: Vec<_> = report
            .ground_events()
            .filter_map(|e| match e {
                GroundEvent::Position(p) => Some(*p),
                _ => None,
            })
            .collect();
        match freshness::judge(&ground, &report.clock(), start, end) {
            Some(f) => positions.record(ctx, &f),
            None => ctx.log("no position reached the ground while the list was in flight"),
        }
        Ok(())
    })
}

/// A reconnecting ground station's list: the router answers it from its cache once the
/// vehicle's `_HASH_CHECK` says the parameters are unchanged (PX4; ArduPilot has no such
/// hash, so its second list crosses the radio again and is measured without a limit).
pub const CACHE: Scenario = Scenario {
    name: "params_cache",
    summary: "The whole parameter list asked for again after a first download, as a \
              reconnecting ground station does: PX4 <= 5 s on any radio (the router's cache, \
              checked with PX4's _HASH_CHECK); ArduPilot measured (no hash: over the radio)",
    plan: plan_cache,
    radios: |p| &p.params_cache,
};

/// The second list's limit (issue target): PX4's, whatever the radio; none for ArduPilot.
fn again_limit(f: Flavour) -> Option<f64> {
    match f {
        Flavour::Px4 => Some(5.0),
        Flavour::ArduPilot => None,
    }
}

fn plan_cache(d: &mut Declarations, t: &Target) -> Script {
    let first = d.declare(
        t.spec("params_cache_first_s", "s")
            .describe("the first download, from PARAM_REQUEST_LIST to the last parameter"),
    );
    let again = t
        .spec("params_again_s", "s")
        .describe("the list asked for again 5 s after the first download: to its last parameter");
    let again = d.declare(match again_limit(t.flavour()) {
        Some(max) => again.at_most(max),
        None => again,
    });
    let missing = d.declare(
        t.spec("params_again_missing", "")
            .describe("parameters of the second list that never arrived")
            .equal_to(0.0),
    );
    Box::new(move |ctx, defaults: &SessionDefaults, t: &Target| {
        let args = vec![
            "--scenario".into(),
            "params".into(),
            "--param-timeout".into(),
            LIST_TIMEOUT_S.to_string(),
            "--relist".into(),
        ];
        let dir = ctx.dir.clone();
        let budget = Duration::from_secs_f64(2.0 * LIST_TIMEOUT_S + 40.0);
        let o = options(defaults, t, &dir, args, budget);
        let report = run(ctx, o)?;
        let done = report.ground_events().find_map(|e| match e {
            GroundEvent::Params {
                count,
                total,
                seconds,
                ..
            } => Some((*count, *total, *seconds)),
            _ => None,
        });
        let Some((count, total, seconds)) = done else {
            bail!("the ground station reported no parameter download");
        };
        if count == total && total > 0 {
            ctx.record(first, seconds);
        }
        let done = report.ground_events().find_map(|e| match e {
            GroundEvent::ParamsAgain {
                count,
                total,
                seconds,
                rereads,
                ..
            } => Some((*count, *total, *seconds, *rereads)),
            _ => None,
        });
        let Some((count, total, seconds, rereads)) = done else {
            bail!("the ground station reported no second download");
        };
        ctx.record(missing, f64::from(total.saturating_sub(count)));
        ctx.log(format!(
            "second list: {count} of {total} in {seconds:.2} s, {rereads} read by index"
        ));
        if count == total && total > 0 {
            ctx.record(again, seconds);
        }
        Ok(())
    })
}
