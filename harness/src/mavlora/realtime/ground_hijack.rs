//! Someone on the ground side tries to fly the drone: an unauthenticated ground port would
//! let anyone who reaches it fly it. While the pilot's pymavlink ground station flies,
//! hostile senders (`mavlora_intruder.py`) aim ARM (forced), flight termination, mode and
//! parameter changes and a mission takeover at the router's ground port, with garbage and
//! partial frames between them. Two sessions side by side, one per way the router tells the
//! pilot from others:
//!
//! - `ground_hijack` (the default policy: `--allow 127.0.0.1`, system ids 255 and 245): another
//!   host (127.0.0.2, every 127.x is loopback on Linux) spoofing the ground's system id 255,
//!   and another program on the ground computer with system id 66;
//! - `ground_hijack_signed` (`--ground-key`, the pilot's station signs): programs on the
//!   ground computer spoofing id 255, one unsigned, one signing with a wrong key.
//!
//! Invariants: none of their frames crosses the radio, none of the vehicle's telemetry goes
//! to them, the router counts every frame it refused, and the pilot's commands sent under
//! attack are acked within SORA's TMPR with nothing lost, telemetry without a hole.

use std::time::Duration;

use anyhow::{Context, Result, bail};

use super::{CommandsAfter, Scenario, Script, Unsigned, ensure_clean, keep_evidence, spec};
use crate::clock::Mono;
use crate::driver::fixture::Fixture;
use crate::mavlora::fixture::fc::FcSummary;
use crate::mavlora::fixture::gcs::GcsEvent;
use crate::mavlora::fixture::intruder::{IntruderEvent, IntruderSummary};
use crate::mavlora::session::{GcsPlan, MavloraSession, SessionDefaults, SessionReport};
use crate::measurement::{Declarations, Handle};
use crate::runner::PhaseContext;

const SCENARIO_NAME: &str = "ground_hijack";

pub const SCENARIO: Scenario = Scenario {
    name: SCENARIO_NAME,
    summary: "Hostile ground senders (another host, another system id, unsigned, a wrong key) try to arm, terminate and take the mission over while the pilot flies: nothing of theirs crosses the radio, no telemetry reaches them, the pilot's commands are acked",
    plan,
};

/// Telemetry flows this long before the attack.
const BEFORE: Duration = Duration::from_secs(1);
/// How long the intruders send: past the pilot's command phase, which starts at
/// `LISTEN_S` after the ground station started.
const ATTACK: Duration = Duration::from_secs(11);
const LISTEN_S: f64 = 6.0;

/// The intruder's messages the pilot's ground station never sends in this scenario: one of
/// them at the autopilot is a hijack that crossed the radio.
const INTRUDER_ONLY: [&str; 4] = [
    "SET_MODE",
    "PARAM_SET",
    "MISSION_CLEAR_ALL",
    "MISSION_COUNT",
];
/// ...and its commands: ARM (400) and FLIGHTTERMINATION (185).
const INTRUDER_COMMANDS: [u32; 2] = [400, 185];
/// The system id the second sender of the unsigned session uses.
const FOREIGN_SYSID: u8 = 66;

/// One hostile sender: its label, source address, system id, and whether it signs (with
/// a key that is not the ground's).
struct Intruder {
    label: &'static str,
    source: &'static str,
    sysid: u8,
    wrong_key: bool,
}

/// The two sessions: (name, ground key on, intruders).
const SESSIONS: [(&str, bool, [Intruder; 2]); 2] = [
    (
        "ground_hijack",
        false,
        [
            Intruder {
                label: "intruder_other_host",
                source: "127.0.0.2",
                sysid: 255,
                wrong_key: false,
            },
            Intruder {
                label: "intruder_other_sysid",
                source: "127.0.0.1",
                sysid: FOREIGN_SYSID,
                wrong_key: false,
            },
        ],
    ),
    (
        "ground_hijack_signed",
        true,
        [
            Intruder {
                label: "intruder_unsigned",
                source: "127.0.0.1",
                sysid: 255,
                wrong_key: false,
            },
            Intruder {
                label: "intruder_wrong_key",
                source: "127.0.0.1",
                sysid: 255,
                wrong_key: true,
            },
        ],
    ),
];

struct Measured {
    unsigned: Unsigned,
    on_radio: Handle,
    to_intruders: Handle,
    refusals: Handle,
    sent: Handle,
    uncounted: Handle,
    gaps: Handle,
    commands: [CommandsAfter; 2],
}

fn plan(d: &mut Declarations) -> Script {
    let m = Measured {
        unsigned: Unsigned::declare(d, SCENARIO_NAME),
        on_radio: d.declare(
            spec("ground_hijack_frames_on_radio", "")
                .describe(
                    "intruders' frames that crossed the radio and reached the autopilot \
                     (their ARM, FLIGHTTERMINATION, SET_MODE, PARAM_SET, MISSION_CLEAR_ALL, \
                     MISSION_COUNT, anything from system 66), both sessions",
                )
                .equal_to(0.0),
        ),
        to_intruders: d.declare(
            spec("ground_hijack_datagrams_to_intruders", "")
                .describe(
                    "datagrams the router sent to an intruder's socket, its refusal notices \
                     aside: the vehicle's telemetry redirected to a stranger",
                )
                .equal_to(0.0),
        ),
        refusals: d.declare(spec("ground_hijack_refusal_notices", "").describe(
            "STATUSTEXTs the router sent an intruder to say it refused it (a program on an \
             allowed address with a system id not allowed is told why, at most once per reason \
             per 10 s; a stranger is told nothing)",
        )),
        sent: d.declare(spec("ground_hijack_intruder_frames_sent", "").describe(
            "well-formed frames the intruders sent to the router's ground port, both \
                 sessions (garbage and partial frames besides)",
        )),
        uncounted: d.declare(
            spec("ground_hijack_frames_not_counted", "")
                .describe(
                    "intruders' frames the router refused without counting them: sent minus \
                     the router's ground_rejected, per session, at least 0 (every refusal \
                     must show in its status line)",
                )
                .equal_to(0.0),
        ),
        gaps: d.declare(
            spec("ground_hijack_telemetry_gaps", "")
                .describe(
                    "holes of more than 2 s in the vehicle's telemetry at the pilot's ground \
                     station during the attack",
                )
                .equal_to(0.0),
        ),
        commands: [
            CommandsAfter::declare(d, "ground_hijack", "the attack began"),
            CommandsAfter::declare(d, "ground_hijack_signed", "the attack began"),
        ],
    };
    Box::new(move |ctx, defaults| run(ctx, defaults, &m))
}

fn run(ctx: &mut PhaseContext, d: &SessionDefaults, m: &Measured) -> Result<()> {
    let mut sessions = Vec::new();
    for (name, ground_key, _) in &SESSIONS {
        let mut o = d.options(name, &d.clean_radio, &ctx.dir.join(name));
        o.ground_key = *ground_key;
        o.gcs = GcsPlan {
            listen_s: LISTEN_S,
            commands: CommandsAfter::COMMANDS,
            ..GcsPlan::default()
        };
        sessions.push(MavloraSession::start(o)?);
    }
    let first = sessions.iter().map(|s| s.telemetry_at).max().expect("two");
    std::thread::sleep(BEFORE.saturating_sub(Mono::now().since(first)));
    let attack_start = Mono::now();
    let mut intruders: Vec<Vec<Fixture<IntruderEvent>>> = Vec::new();
    for (session, (_, _, who)) in sessions.iter().zip(&SESSIONS) {
        let mut started = Vec::new();
        for i in who {
            let key = i.wrong_key.then(random_key).transpose()?;
            started.push(session.start_intruder(
                i.label,
                i.source,
                i.sysid,
                key.as_deref(),
                ATTACK,
            )?);
        }
        intruders.push(started);
    }
    ctx.log(format!(
        "attack from {:.1} s after telemetry began, for {} s",
        attack_start.since(first).as_secs_f64(),
        ATTACK.as_secs()
    ));
    let attack_end = attack_start + ATTACK;

    let (mut on_radio, mut to_intruders, mut sent, mut uncounted, mut gaps) = (0, 0, 0, 0, 0);
    let mut refusals = 0;
    let mut reports = Vec::new();
    for ((session, started), (name, _, who)) in sessions.into_iter().zip(intruders).zip(&SESSIONS) {
        let mut summaries = Vec::new();
        for (fixture, i) in started.iter().zip(who) {
            let s: IntruderSummary = fixture
                .summary(ATTACK + Duration::from_secs(10))
                .with_context(|| format!("{name}: {} gave no summary", i.label))?;
            if s.frames_sent == 0 {
                bail!(
                    "{name}: {} sent nothing: the attack did not take place",
                    i.label
                );
            }
            ctx.log(format!(
                "{name}: {} ({} as system {}{}) sent {} frames {:?} and {} garbage datagrams, got {} datagrams back and {} refusal notices",
                i.label,
                i.source,
                i.sysid,
                if i.wrong_key { ", wrong key" } else { "" },
                s.frames_sent,
                s.by_type,
                s.garbage_sent,
                s.datagrams_received,
                s.refusals_received
            ));
            summaries.push(s);
        }
        let report = session.finish()?;
        keep_evidence(ctx, name, &report);
        for fixture in &started {
            ctx.attach(
                format!("{name}/{}", fixture.name()),
                fixture.log_path().to_path_buf(),
                "text/plain",
            );
        }
        let crossed = hijack_frames_at_autopilot(&report.fc);
        ctx.log(format!(
            "{name}: at the autopilot, of the intruders' kinds: {crossed}; received by type {:?}",
            report.fc.received
        ));
        on_radio += crossed;
        let name_sent: u64 = summaries.iter().map(|s| s.frames_sent).sum();
        to_intruders += summaries.iter().map(|s| s.datagrams_received).sum::<u64>();
        refusals += summaries.iter().map(|s| s.refusals_received).sum::<u64>();
        sent += name_sent;
        let rejected = report
            .router_status
            .as_ref()
            .context("the router wrote no status")?
            .counter("ground_rejected")?;
        ctx.log(format!(
            "{name}: router refused {rejected} ground inputs for {name_sent} intruder frames"
        ));
        uncounted += name_sent.saturating_sub(rejected as u64);
        gaps += telemetry_gaps(&report, attack_start, attack_end);
        reports.push(report);
    }
    ctx.record(m.on_radio, f64::from(on_radio));
    ctx.record(m.to_intruders, to_intruders as f64);
    ctx.record(m.refusals, refusals as f64);
    ctx.record(m.sent, sent as f64);
    ctx.record(m.uncounted, uncounted as f64);
    ctx.record(m.gaps, gaps as f64);
    for (c, r) in m.commands.iter().zip(&reports) {
        c.record(ctx, r)?;
    }
    m.unsigned
        .record(ctx, &reports.iter().collect::<Vec<_>>())?;
    reports.iter().try_for_each(|r| ensure_clean(ctx, r))
}

/// Frames at the autopilot that only an intruder sends here.
fn hijack_frames_at_autopilot(fc: &FcSummary) -> u32 {
    INTRUDER_ONLY.iter().map(|t| fc.received(t)).sum::<u32>()
        + INTRUDER_COMMANDS
            .iter()
            .map(|&c| fc.commands_received(c))
            .sum::<u32>()
        + fc.received_from_system(FOREIGN_SYSID)
}

/// Holes in the pilot's telemetry that overlap the attack.
fn telemetry_gaps(report: &SessionReport, from: Mono, to: Mono) -> u64 {
    report
        .gcs_events
        .iter()
        .filter(|l| {
            matches!(&l.event, GcsEvent::TelemetryGap { t, since, .. } if *t >= from && *since <= to)
        })
        .count() as u64
}

/// A fresh 32-byte key, hex: the wrong key, since the ground's is its own fresh one.
fn random_key() -> Result<String> {
    let mut bytes = [0u8; 32];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut bytes))
        .context("reading /dev/urandom")?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}
