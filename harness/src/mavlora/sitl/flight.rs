//! A whole flight through compact MavLora, as a pilot flies it with QGroundControl: a short
//! mission uploaded, GUIDED, arm, takeoff, AUTO through the mission, RTL, landed and
//! disarmed. Every command's ack latency at the ground, and each change of the vehicle's
//! mode and armed state (truth connection) seen at the ground, and how late.
//!
//! Limits (issue targets and SORA): every command acked (SORA's TMPR for medium robustness:
//! a command answered within 3 s), no command acked ACCEPTED without its effect on the truth
//! port, every mode and armed change at the ground within 0.5 s of the vehicle's.

use std::time::Duration;

use anyhow::bail;

use super::{Scenario, Script, Target, freshness, options, run};
use crate::mavlora::fixture::sitl::{GroundEvent, State, TruthEvent};
use crate::mavlora::session::SessionDefaults;
use crate::measurement::Declarations;
use crate::stats;

pub const SCENARIO: Scenario = Scenario {
    name: "flight",
    summary: "A whole flight (mission upload, GUIDED, arm, takeoff, AUTO, RTL, landed): every \
              command acked within 3 s, none ACCEPTED without its effect on the vehicle, each \
              mode and armed change at the ground within 0.5 s of the vehicle's",
    plan,
    radios: |p| &p.flight,
};

const ITEMS: u32 = 6;
const TAKEOFF_ALT_M: f64 = 10.0;
const FLIGHT_TIMEOUT_S: f64 = 300.0;

/// How late each of the vehicle's (mode, armed) changes showed at the ground: for each truth
/// change, the state it changed to and the first ground state equal to it after the truth
/// connection last saw the state before (the vehicle changed between then and `t`, and its
/// link to the bridge may report it first); `None` where the ground never showed it. The lag
/// counts from `t`, the first sight on the truth connection, and is at least 0.
pub fn state_lags(truth: &[State], ground: &[State]) -> Vec<(State, Option<f64>)> {
    truth
        .windows(2)
        .filter(|w| (w[0].custom_mode, w[0].armed) != (w[1].custom_mode, w[1].armed))
        .map(|w| {
            let change = w[1];
            // The last sight of the state before: the ground may show the change from then on.
            let earliest = change.since.unwrap_or(w[0].t).as_secs_f64();
            let lag = ground
                .iter()
                .find(|g| {
                    g.t.as_secs_f64() > earliest
                        && (g.custom_mode, g.armed) == (change.custom_mode, change.armed)
                })
                .map(|g| (g.t.as_secs_f64() - change.t.as_secs_f64()).max(0.0));
            (change, lag)
        })
        .collect()
}

/// How long, at most, the truth connection took to see a change: the time between its last
/// sight of the state before and its first of the new one (its HEARTBEAT period where the
/// autopilot streams nothing faster). The lags above are exact to within this.
pub fn truth_resolution(truth: &[State]) -> Option<f64> {
    truth
        .iter()
        .filter_map(|s| s.since.map(|since| s.t.as_secs_f64() - since.as_secs_f64()))
        .reduce(f64::max)
}

fn plan(d: &mut Declarations, t: &Target) -> Script {
    let completed = d.declare(
        t.spec("flight_completed", "")
            .describe("1 when the flight reached every step: armed, airborne, mission done, landed")
            .equal_to(1.0),
    );
    let ack_p50 = d.declare(
        t.spec("command_ack_p50_s", "s")
            .describe("median of first send to COMMAND_ACK over the flight's commands"),
    );
    let ack_max = d.declare(
        t.spec("command_ack_max_s", "s")
            .describe("slowest first send to COMMAND_ACK (SORA TMPR, medium robustness: 3 s)")
            .at_most(3.0),
    );
    let unacked = d.declare(
        t.spec("commands_unacked", "")
            .describe("commands the ground station sent that were never acked")
            .equal_to(0.0),
    );
    let state_lag = d.declare(
        t.spec("state_lag_max_s", "s")
            .describe(
                "slowest (mode, armed) change of the vehicle (truth connection) to the same \
                 state at the ground station",
            )
            .at_most(0.5),
    );
    let resolution = d.declare(t.spec("truth_state_resolution_s", "s").describe(
        "longest time the truth connection took to see a (mode, armed) change (between its \
             last sight of the old state and its first of the new): the lags are exact to \
             within it",
    ));
    let states_missed = d.declare(
        t.spec("states_missed", "")
            .describe("(mode, armed) changes of the vehicle the ground station never showed")
            .equal_to(0.0),
    );
    Box::new(move |ctx, defaults: &SessionDefaults, t: &Target| {
        let args = vec![
            "--scenario".into(),
            "flight".into(),
            "--items".into(),
            ITEMS.to_string(),
            "--takeoff-alt".into(),
            TAKEOFF_ALT_M.to_string(),
            "--flight-timeout".into(),
            FLIGHT_TIMEOUT_S.to_string(),
        ];
        let dir = ctx.dir.clone();
        let budget = Duration::from_secs_f64(FLIGHT_TIMEOUT_S + 120.0);
        let report = run(ctx, options(defaults, t, &dir, args, budget))?;
        let steps: Vec<String> = report
            .ground_events()
            .filter_map(|e| match e {
                GroundEvent::Step { name, .. } => Some(name.clone()),
                _ => None,
            })
            .collect();
        ctx.log(format!("steps: {}", steps.join(", ")));
        ctx.record(completed, f64::from(u8::from(report.ground_summary.ok)));
        if !report.ground_summary.ok {
            // Shown with the failure: why the flight stopped, without opening the evidence.
            ctx.annotate(
                completed,
                &format!(
                    "steps reached: [{}]; the ground station: {}",
                    steps.join(", "),
                    report.ground_summary.failed
                ),
            );
        }
        let mut latencies = Vec::new();
        let mut lost = 0u32;
        for e in report.ground_events() {
            if let GroundEvent::Command {
                name,
                sent_t,
                ack_t,
                result,
                tries,
                ..
            } = e
            {
                ctx.log(format!(
                    "{name}: ack {result:?} after {} in {tries} tries",
                    ack_t.map_or("never".into(), |a| format!("{:.3} s", a - sent_t))
                ));
                match ack_t {
                    Some(a) => latencies.push(a - sent_t),
                    None => lost += 1,
                }
            }
        }
        if latencies.is_empty() {
            bail!("the ground station acked no command");
        }
        latencies.sort_by(f64::total_cmp);
        ctx.record(ack_p50, stats::quantile(&latencies, 0.5));
        ctx.record(ack_max, *latencies.last().expect("not empty"));
        ctx.record(unacked, f64::from(lost));
        let truth: Vec<State> = report
            .truth
            .iter()
            .filter_map(|e| match e {
                TruthEvent::State(s) => Some(*s),
                _ => None,
            })
            .collect();
        let ground: Vec<State> = report
            .ground_events()
            .filter_map(|e| match e {
                GroundEvent::State(s) => Some(*s),
                _ => None,
            })
            .collect();
        let lags = state_lags(&truth, &ground);
        for (change, _) in lags.iter().filter(|(_, lag)| lag.is_none()) {
            let until = truth.iter().find(|s| s.t > change.t).map_or_else(
                || "the end".to_string(),
                |next| {
                    format!(
                        "{:.3} s later",
                        next.t.as_secs_f64() - change.t.as_secs_f64()
                    )
                },
            );
            ctx.log(format!(
                "never at the ground: custom_mode {:#x} armed {} (the vehicle's at {:.3} s, \
                 until {until})",
                change.custom_mode,
                change.armed,
                change.t.as_secs_f64(),
            ));
        }
        let seen: Vec<f64> = lags.iter().filter_map(|(_, lag)| *lag).collect();
        ctx.log(format!(
            "{} mode/armed changes on the vehicle; at the ground after {:?} s",
            lags.len(),
            seen.iter()
                .map(|l| (l * 1000.0).round() / 1000.0)
                .collect::<Vec<_>>()
        ));
        ctx.record(
            states_missed,
            lags.iter().filter(|(_, lag)| lag.is_none()).count() as f64,
        );
        if let Some(max) = seen.iter().copied().reduce(f64::max) {
            ctx.record(state_lag, max);
        }
        if let Some(r) = truth_resolution(&truth) {
            ctx.record(resolution, r);
        }
        // The position age over the whole flight, for the report's figure.
        let positions: Vec<_> = report
            .ground_events()
            .filter_map(|e| match e {
                GroundEvent::Position(p) => Some(*p),
                _ => None,
            })
            .collect();
        if let (Some(first), Some(last)) = (positions.first(), positions.last())
            && let Some(f) = freshness::judge(&positions, &report.clock(), first.t, last.t)
        {
            freshness::attach_series(ctx, &f)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::Mono;

    fn s(t: f64, mode: u32, armed: bool) -> State {
        State {
            t: Mono::from_secs_f64(t),
            custom_mode: mode,
            base_mode: 0,
            armed,
            system_status: 3,
            since: None,
        }
    }

    fn seen_since(mut state: State, since: f64) -> State {
        state.since = Some(Mono::from_secs_f64(since));
        state
    }

    #[test]
    fn each_vehicle_change_is_matched_to_the_first_equal_ground_state_after_it() {
        let truth = [
            s(1.0, 0, false),
            s(2.0, 4, false),
            s(3.0, 4, true),
            s(9.0, 6, true),
        ];
        let ground = [s(1.3, 0, false), s(2.4, 4, false), s(3.2, 4, true)];
        let lags = state_lags(&truth, &ground);
        assert_eq!(lags.len(), 3);
        assert!((lags[0].1.unwrap() - 0.4).abs() < 1e-9);
        assert!((lags[1].1.unwrap() - 0.2).abs() < 1e-9);
        assert_eq!(lags[2].1, None, "RTL never shown at the ground");
        assert_eq!(lags[2].0.custom_mode, 6);
    }

    #[test]
    fn a_change_the_ground_shows_before_the_truth_sees_it_counts_when_after_the_old_state() {
        // PX4 heartbeats each of its links at 1 Hz, out of phase: the bridge's link may show
        // RTL 0.7 s before the truth link does (seen in the rig: reported as never shown).
        let truth = [
            s(1.0, 4, true),
            seen_since(s(10.0, 6, true), 9.0),
            seen_since(s(20.0, 6, false), 19.0),
        ];
        let ground = [s(1.2, 4, true), s(9.3, 6, true), s(18.5, 6, false)];
        let lags = state_lags(&truth, &ground);
        assert_eq!(lags[0].1, Some(0.0), "shown 0.7 s before the truth saw it");
        assert_eq!(
            lags[1].1, None,
            "disarmed at the ground before the vehicle last armed"
        );
        assert_eq!(truth_resolution(&truth), Some(1.0));
    }
}
