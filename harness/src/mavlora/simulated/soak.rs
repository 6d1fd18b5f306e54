//! An hour of flight on the virtual clock with the faults of the real-time phases, again
//! and again: the real bridge and router engines between the simulated PX4 and ground
//! station over SiK 64k with 10 % bursty loss each way, and
//!
//! - a 10 s radio silence both ways every 7 minutes (a hill, a radio browning out; the sim has
//!   no ports, so this is also what a replugged radio looks like to the engines);
//! - an autopilot reboot every 13 minutes;
//! - a 5 s flood of garbage into the router's ground side every 11 minutes (64 KiB every
//!   100 ms from the allowed ground station's address);
//! - a command every 10 s (the mix that tells executions apart) and a 30-item mission upload
//!   every 10 minutes, throughout.
//!
//! Invariants: memory flat (the heap's high-water mark at the end of the hour at most 5 %
//! above its high-water mark at minute 5, after every kind of fault has happened once,
//! counted over the world's footprint: the project's bound, so a leak shows within the
//! hour), every command the ground heard acked executed exactly once by the autopilot and
//! none executed twice (a command the ground gave up on during a silence may have run or
//! not: its outcome is unknown to the ground, as MAVLink's command protocol has it, and
//! both are counted), every upload the ground heard ACCEPTED held exactly by the autopilot,
//! the radio's byte counters balanced, and nothing stuck: telemetry still arriving at the
//! end.

use anyhow::{Context, Result, bail};
use harness_radio::{Direction, Silence};
use harness_sim::profiles::PX4_COMPACT_TOML;
use harness_sim::{CommandPlan, Flight, GcsMock, PX4_NORMAL, Px4Fc, Route, World, secs};
use mavlora::Instant;
use mavlora::dialect::MavMissionResult;
use timebase::Duration;

use super::c2_latency::Integrity;
use super::{Radios, Scenario, Script, mavlora_configs, spec};
use crate::heap::{self, HeapMeter};
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;

pub const SCENARIO: Scenario = Scenario {
    name: "soak",
    summary: "One hour of flight over SiK with bursty loss, a 10 s silence every 7 min, an autopilot reboot every 13 min, a ground-side flood every 11 min, commands and mission uploads throughout: memory flat, every command once, every accepted plan exact, nothing stuck",
    plan,
};

const HOUR_S: u64 = 3600;
/// The heap's reference point: the world's footprint once everything has run at least once.
const SETTLE_S: u64 = 300;
/// The high-water mark after the first 5 minutes grows at most this much: the project's bound
/// for a program that does not leak.
const GROWTH_LIMIT_PCT: f64 = 5.0;
/// SORA TMPR, medium robustness: telemetry older than this at the end is a stuck link.
const TMPR_S: f64 = 3.0;
/// Faults stop this long before the end, so the end shows a link that recovered.
const QUIET_END_S: u64 = 120;
const SILENCE_EVERY_S: u64 = 420;
const SILENCE_S: f64 = 10.0;
const REBOOT_EVERY_S: u64 = 780;
const FLOOD_EVERY_S: u64 = 660;
const FLOOD_S: u64 = 5;
const FLOOD_CHUNK: usize = 64 * 1024;
const MISSION_EVERY_S: u64 = 600;
const MISSION_ITEMS: u16 = 30;

struct Measured {
    growth: Handle,
    footprint: Handle,
    never_executed: Handle,
    given_up: Handle,
    twice: Handle,
    commands: Handle,
    mismatch: Handle,
    accepted: Handle,
    unbalanced: Handle,
    last_position: Handle,
}

fn plan(d: &mut Declarations, _: &Radios) -> Script {
    let m = Measured {
        growth: d.declare(
            spec("soak_heap_growth_pct", "%")
                .describe(
                    "the heap's high-water mark at the end of the hour above its high-water \
                     mark at minute 5 (by then every fault has happened once), as a share of \
                     the world's footprint at minute 5 (engines, radio model, simulated \
                     autopilot and ground station); limit 5 %, the project's bound for a program \
                     that does not leak",
                )
                .at_most(GROWTH_LIMIT_PCT),
        ),
        footprint: d.declare(spec("soak_heap_footprint_kib", "KiB").describe(
            "the world's heap high-water mark at minute 5, above what the process held \
             before the world was made",
        )),
        never_executed: d.declare(
            spec("soak_commands_acked_not_executed", "")
                .describe(
                    "commands the ground heard acked that the autopilot never executed (an \
                     ack that lies)",
                )
                .equal_to(0.0),
        ),
        given_up: d.declare(spec("soak_commands_given_up", "").describe(
            "commands the ground gave up on (5 copies 1.5 s apart without an ack: a 10 s \
             silence outlasts them); whether each ran is in the log",
        )),
        twice: d.declare(
            spec("soak_commands_executed_twice", "")
                .describe("commands the autopilot executed more than once")
                .equal_to(0.0),
        ),
        commands: d.declare(spec("soak_commands_sent", "").describe(
            "commands the ground sent over the hour (one every 10 s, 1.5 s retries, 5 copies)",
        )),
        mismatch: d.declare(
            spec("soak_mission_mismatch_on_accept", "")
                .describe(
                    "uploads the ground heard ACCEPTED while the autopilot did not hold exactly \
                     the plan sent",
                )
                .equal_to(0.0),
        ),
        accepted: d.declare(spec("soak_missions_accepted", "").describe(
            "uploads of 30 items (one every 10 minutes) that ended ACCEPTED at the ground",
        )),
        unbalanced: d.declare(
            spec("soak_radio_unbalanced_bytes", "B")
                .describe(
                    "bytes offered to the radio, both ways, not accounted for as dropped (full \
                     buffer), lost (air) or delivered (once) or still queued",
                )
                .equal_to(0.0),
        ),
        last_position: d.declare(
            spec("soak_last_position_age_s", "s")
                .describe(
                    "age of the last GLOBAL_POSITION_INT at the ground when the hour ends, two \
                     minutes after the last fault; limit: SORA TMPR medium (3 s)",
                )
                .at_most(TMPR_S),
        ),
    };
    Box::new(move |ctx, radios| run(ctx, radios, &m))
}

/// What happens when, in whole seconds of the hour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Event {
    Sample,
    Reboot,
    FloodStart,
    FloodStop,
    Mission,
}

fn schedule() -> Vec<(u64, Event)> {
    let faults_until = HOUR_S - QUIET_END_S;
    let every = |first: u64, period: u64, until: u64| (first..until).step_by(period as usize);
    let mut events: Vec<(u64, Event)> = every(60, 60, HOUR_S + 1)
        .map(|t| (t, Event::Sample))
        .chain(every(180, REBOOT_EVERY_S, faults_until).map(|t| (t, Event::Reboot)))
        .chain(
            every(120, FLOOD_EVERY_S, faults_until)
                .flat_map(|t| [(t, Event::FloodStart), (t + FLOOD_S, Event::FloodStop)]),
        )
        .chain(every(60, MISSION_EVERY_S, faults_until).map(|t| (t, Event::Mission)))
        .collect();
    events.sort();
    events
}

fn run(ctx: &mut PhaseContext, radios: &Radios, m: &Measured) -> Result<()> {
    if !heap::installed() {
        bail!("the heap meter is not installed in this program: run the soak from `rig`");
    }
    let mut setup = radios
        .mission
        .iter()
        .find(|(key, _)| key.starts_with("sik"))
        .or(radios.mission.first())
        .map(|(_, s)| radios.seeded(s))
        .context("the rig file names no mission radio to soak on")?;
    // The radio model keeps every transmission of its duty-cycle window (by default the EU
    // 433 MHz rule's hour) to report the share: bookkeeping of the instrument, which would
    // grow for the whole first hour and hide the engines' own memory. The soak watches no
    // duty cycle, so the model keeps one minute.
    for link in [&mut setup.downlink, &mut setup.uplink] {
        link.duty.window_s = 60.0;
        link.duty.enforce = false;
    }
    let preset = setup.preset.resolve()?;
    let before_world = HeapMeter::mark();
    let fc =
        Px4Fc::new(PX4_NORMAL, Instant::ZERO, radios.seed).with_flight(Flight::Route(Route::PAPER));
    let mavlora = mavlora_configs(PX4_COMPACT_TOML, "px4-compact.toml", true, Some(&preset))?;
    let mut w = World::new(fc, Some(mavlora), Some(&setup))?;
    // Every fault once before minute 5 (silence at 4, reboot at 3, flood at 2, upload at 1),
    // so the high-water mark then has seen each.
    let silence = Silence {
        at_s: 240.0,
        for_s: SILENCE_S,
        every_s: Some(SILENCE_EVERY_S as f64),
    };
    let radio = w.radio_mut().context("the soak's world has no radio")?;
    for d in [Direction::Downlink, Direction::Uplink] {
        radio.link_mut(d).add_silence(silence)?;
    }
    w.gcs.start_commands(
        CommandPlan {
            period: Duration::from_secs(10),
            mix: true,
            ..CommandPlan::default()
        },
        w.now,
    );
    // The sim's records of every command are sized for the hour up front: they are the
    // instrument's, and must not count as the link's growth.
    let commands = (HOUR_S / 10) as usize + 1;
    w.gcs.reserve_command_records(commands);
    w.fc.reserve_executed(4 * commands);

    let mut flood_until: Option<Instant> = None;
    // (minute, KiB live, KiB high-water so far), for the log.
    let mut timeline = Vec::new();
    let junk: Vec<u8> = (0..FLOOD_CHUNK).map(|i| (i * 7 + i / 251) as u8).collect();
    let (mut settled, mut uploads, mut accepted, mut mismatch) = (None, 0u64, 0u64, 0u64);
    let (mut last_position, mut reboots, mut floods) = (None, 0u64, 0u64);
    let judge_upload = |w: &World, accepted: &mut u64, mismatch: &mut u64| {
        let Some((result, _)) = w.gcs.result else {
            return;
        };
        if result == MavMissionResult::MAV_MISSION_ACCEPTED {
            *accepted += 1;
            let sent = w
                .gcs
                .last_upload
                .as_ref()
                .map(|(_, items)| items.as_slice());
            if sent != Some(w.fc.mission()) {
                *mismatch += 1;
            }
        }
    };
    for (t, event) in schedule() {
        // A flood is chunks every 100 ms until it stops.
        while let Some(until) = flood_until {
            let next = w.now + Duration::from_millis(100);
            if next >= secs(t as f64) || next >= until {
                break;
            }
            w.run_until(next);
            if let Some(router) = w.router_mut() {
                router.handle_gcs_bytes(next, &junk);
            }
        }
        w.run_until(secs(t as f64));
        let now = w.now;
        match event {
            Event::Sample => {
                if let Some(&(at, _)) = w.gcs.positions.last() {
                    last_position = Some(at);
                }
                // The ground's record of every position is the sim's, not the engines':
                // kept to the last one, so it does not count as the link's growth.
                w.gcs.positions.clear();
                if t == SETTLE_S {
                    settled = Some(HeapMeter::peak());
                }
                timeline.push((t / 60, HeapMeter::live() / 1024, HeapMeter::peak() / 1024));
            }
            Event::Reboot => {
                w.fc.reboot(now);
                reboots += 1;
            }
            Event::FloodStart => {
                flood_until = Some(now + Duration::from_secs(FLOOD_S));
                floods += 1;
            }
            Event::FloodStop => flood_until = None,
            Event::Mission => {
                if uploads > 0 {
                    judge_upload(&w, &mut accepted, &mut mismatch);
                }
                w.gcs.upload(GcsMock::mission(MISSION_ITEMS), now);
                uploads += 1;
            }
        }
    }
    judge_upload(&w, &mut accepted, &mut mismatch);
    let peak = HeapMeter::peak();
    let settled = settled.context("the soak never reached minute 5")?;
    let footprint = settled.saturating_sub(before_world).max(1);
    let growth = 100.0 * peak.saturating_sub(settled) as f64 / footprint as f64;

    w.gcs.stop_commands();
    let stats = w.gcs.command_stats();
    let integrity = Integrity::of(&stats, w.fc.executed());
    let (runs, _) = Integrity::runs(&stats, w.fc.executed());
    let given_up_ran = stats
        .given_up
        .iter()
        .filter(|&&s| runs.get(s as usize).is_some_and(|&n| n > 0))
        .count();
    let acked_not_run = runs
        .iter()
        .enumerate()
        .filter(|&(serial, &n)| n == 0 && !stats.given_up.contains(&(serial as u64)))
        .count();
    let mut unbalanced = 0i64;
    for d in [Direction::Downlink, Direction::Uplink] {
        let link = w.radio().context("no radio")?.link(d);
        let s = link.stats();
        let accounted = s.bytes_dropped + s.bytes_lost + s.bytes_delivered - s.bytes_duplicated
            + link.queued_bytes() as u64;
        unbalanced += (s.bytes_offered as i64 - accounted as i64).abs();
    }
    let age = last_position.map_or(f64::INFINITY, |at: Instant| {
        w.now.saturating_duration_since(at).as_secs_f64()
    });
    ctx.log(format!(
        "an hour in {} steps: {reboots} reboots, {floods} floods, silences every {SILENCE_EVERY_S} s; \
         heap {} KiB before the world, high-water {} KiB at minute 5, {} KiB at the end",
        w.steps(),
        before_world / 1024,
        settled / 1024,
        peak / 1024
    ));
    ctx.log(format!(
        "commands: {} sent, {} acked, {} given up by the ground ({given_up_ran} of them ran \
         anyway, late); autopilot: {} never, {} twice, {} unknown; uploads: {uploads}, \
         {accepted} accepted, {mismatch} mismatched",
        stats.started,
        stats.acked,
        stats.failed,
        integrity.lost,
        integrity.executed_twice,
        integrity.unknown
    ));
    ctx.log(format!(
        "heap by minute (KiB live / high-water): {}",
        timeline
            .iter()
            .map(|(m, live, peak)| format!("{m}: {live}/{peak}"))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    if let Some(router) = w.router() {
        let s = router.stats();
        ctx.log(format!(
            "router: ground reader {:?}; mission {:?}",
            s.gcs_reader, s.mission
        ));
    }
    ctx.record(m.growth, growth);
    ctx.record(m.footprint, footprint as f64 / 1024.0);
    ctx.record(m.never_executed, acked_not_run as f64);
    ctx.record(m.given_up, stats.failed as f64);
    ctx.record(m.twice, integrity.executed_twice as f64);
    ctx.record(m.commands, stats.started as f64);
    ctx.record(m.mismatch, mismatch as f64);
    ctx.record(m.accepted, accepted as f64);
    ctx.record(m.unbalanced, unbalanced as f64);
    ctx.record(m.last_position, age);
    Ok(())
}
