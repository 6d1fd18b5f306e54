//! Short real-time MavLora scenarios: the real `mavlora-bridge` and
//! `mavlora-router` between a pymavlink PX4 and a pymavlink ground station (or MAVSDK),
//! over the radio emulator on pty pairs, on the wall clock
//! ([`MavloraSession`]). They check what the virtual-clock runs cannot: that
//! the programs, their serial and UDP IO and their timers meet the SLAs when
//! bytes take real time. Each scenario takes under ~50 s.
//!
//! - [`table_ii`]: radio bandwidth of compact telemetry and of limiting +
//!   filtering (paper Table II), loss-free SiK;
//! - [`ardupilot`]: an ArduPilot-like autopilot (MAVLink 1, stream requests ignored)
//!   through compact and limiting + filtering: budgets, position rate, commands;
//! - [`mission`]: a mission upload through the relay over SiK with bursty loss;
//! - [`mavsdk_mission`]: MAVSDK itself uploading plan after plan over the same radio: its
//!   answer and the plan the autopilot took never disagree;
//! - [`c2_latency`]: command-to-ack latency over SiK with bursty loss (SORA
//!   TMPR: < 3 s for medium robustness);
//! - [`radio_silence`]: 10 s of silence both ways, then telemetry and commands
//!   back within the same TMPR;
//! - [`fc_reboot_mission`]: the autopilot reboots mid-upload: ACCEPTED only with the
//!   exact plan, an error otherwise, never silence;
//! - [`outage`]: the bridge or the router killed and restarted, the drone's or the
//!   ground's radio unplugged and plugged in again: the same;
//! - [`ground_hijack`]: hostile senders on the ground side while the pilot flies:
//!   nothing of theirs on the radio, the pilot's commands acked.
//!
//! Not in [`scenarios`]: [`soak`], minutes of real time, run only when a rig file lists the
//! `soak` suite.

pub mod ardupilot;
pub mod c2_latency;
pub mod fc_reboot_mission;
pub mod ground_hijack;
pub mod mavsdk_mission;
pub mod mission;
pub mod outage;
pub mod radio_silence;
pub mod soak;
pub mod table_ii;

use anyhow::{Context, Result, bail};

use crate::mavlora::session::{MavloraSession, SessionOptions, SessionReport};
use crate::measurement::{Declarations, Dimension, Handle, PTY, Spec};
use crate::runner::PhaseContext;

pub use crate::mavlora::session::SessionDefaults;

/// One scenario: its measurements (with built-in limits) and its script.
pub struct Scenario {
    /// Short name, unique among the real-time scenarios: `table_ii`.
    pub name: &'static str,
    /// What it shows, for the report.
    pub summary: &'static str,
    /// Declares the measurements, with their built-in limits, and returns
    /// the script that records them.
    pub plan: fn(&mut Declarations) -> Script,
}

/// A scenario's script, holding the handles of the measurements it declared.
pub type Script = Box<dyn FnOnce(&mut PhaseContext, &SessionDefaults) -> Result<()> + Send>;

/// Every real-time scenario, in the order they run.
pub fn scenarios() -> Vec<Scenario> {
    vec![
        table_ii::SCENARIO,
        ardupilot::SCENARIO,
        mission::SCENARIO,
        mavsdk_mission::SCENARIO,
        c2_latency::SCENARIO,
        radio_silence::SCENARIO,
        outage::BRIDGE_CRASH,
        outage::ROUTER_CRASH,
        outage::AIR_REPLUG,
        outage::GROUND_REPLUG,
        fc_reboot_mission::SCENARIO,
        ground_hijack::SCENARIO,
    ]
}

/// A measurement of the MavLora programs over ptys (`mavlora.pty.<base>`).
pub fn spec(base: &str, unit: &str) -> Spec {
    Spec::new(base, unit)
        .dim(Dimension::Device, "mavlora")
        .dim(Dimension::Transport, PTY)
}

/// Runs one session to the end of its GCS plan and keeps its evidence: logs,
/// summaries, tlog, the radio's counters and the programs' status lines.
pub fn run_session(ctx: &mut PhaseContext, options: SessionOptions) -> Result<SessionReport> {
    Ok(run_sessions(ctx, vec![options])?.remove(0))
}

/// Runs sessions side by side (each on its own radio and ports), so
/// independent measurements share the wall time; reports in the given order.
pub fn run_sessions(
    ctx: &mut PhaseContext,
    options: Vec<SessionOptions>,
) -> Result<Vec<SessionReport>> {
    let mut sessions = Vec::new();
    for o in options {
        let session = MavloraSession::start(o)?;
        ctx.log(format!(
            "{}: telemetry at the GCS {:.0} ms after start",
            session.options.name,
            session.telemetry_at.ms_since(session.started)
        ));
        sessions.push(session);
    }
    let mut reports = Vec::new();
    for session in sessions {
        let label = session.options.name.clone();
        let report = session.finish()?;
        keep_evidence(ctx, &label, &report);
        reports.push(report);
    }
    Ok(reports)
}

pub(crate) fn keep_evidence(ctx: &mut PhaseContext, label: &str, report: &SessionReport) {
    for file in &report.files {
        let media = if file.extension().is_some_and(|e| e == "json") {
            "application/json"
        } else if file.extension().is_some_and(|e| e == "tlog") {
            "application/octet-stream"
        } else {
            "text/plain"
        };
        let stem = file.file_name().unwrap_or_default().to_string_lossy();
        ctx.attach(format!("{label}/{stem}"), file.clone(), media);
    }
    let (d, u) = (&report.downlink, &report.uplink);
    ctx.log(format!(
        "{label}: radio downlink {} B offered, {} on air, {} lost, {} dropped (buffer); uplink {} offered, {} on air, {} lost",
        d.bytes_offered, d.bytes_sent, d.bytes_lost, d.bytes_dropped, u.bytes_offered, u.bytes_sent, u.bytes_lost
    ));
    for (who, line) in [
        ("bridge", &report.bridge_status),
        ("router", &report.router_status),
    ] {
        if let Some(line) = line {
            ctx.log(format!("{label}: {who} {line}"));
        }
    }
}

/// `mavlora.pty.<scenario>.unsigned_frames_on_radio` (= 0): every radio leg of every phase is
/// signed (the paper's requirement D, link security), so neither program may put an unsigned
/// frame on the air.
pub struct Unsigned(Handle);

impl Unsigned {
    pub fn declare(d: &mut Declarations, scenario: &str) -> Unsigned {
        Unsigned(
            d.declare(
                spec("unsigned_frames_on_radio", "")
                    .dim(Dimension::Scenario, scenario)
                    .describe(
                        "frames the bridge and the router sent on the radio unsigned \
                         (radio_tx_unsigned of their status files), every session of the \
                         scenario",
                    )
                    .equal_to(0.0),
            ),
        )
    }

    /// Records the sum over `reports`' bridges and routers; a bridged session whose status
    /// line is missing cannot tell, and fails the phase.
    pub fn record(&self, ctx: &mut PhaseContext, reports: &[&SessionReport]) -> Result<()> {
        let mut total = 0.0;
        for r in reports {
            for status in [&r.bridge_status, &r.router_status].into_iter().flatten() {
                total += status.counter("radio_tx_unsigned")?;
            }
        }
        ctx.record(self.0, total);
        Ok(())
    }
}

/// The routers' "degraded" link announcements of a session (from their status files), each
/// logged into the phase; returns how many.
pub fn loss_alarms(ctx: &mut PhaseContext, report: &SessionReport) -> u32 {
    let mut alarms = 0;
    for n in report
        .link_notices
        .iter()
        .filter(|n| n.health == "degraded")
    {
        ctx.log(format!("router: link announcement {:?}", n.text));
        alarms += 1;
    }
    alarms
}

/// The `--link-quality-period` both ends get on the LoRa SF7 channel (683 B/s, signed), as
/// the simulated Table II paces it: a pty's budget would buy a report every second or two,
/// which the 50 B/s compact budget does not allow for.
pub fn lora_sf7_link_quality_period() -> f64 {
    /// LoRa SF7's channel rate, as the engines' default link monitoring assumes.
    const LORA_SF7_BYTES_PER_S: u32 = 683;
    mavlora::quality::LinkQualityConfig::for_budget(LORA_SF7_BYTES_PER_S, true)
        .period
        .as_secs_f64()
}

/// SORA TMPR, medium robustness: C2 latency under 3 s (the fault scenarios' bound).
pub const TMPR_S: f64 = 3.0;

/// Commands a fault scenario sends once the link is back, and how they fared:
/// `mavlora.pty.<prefix>_c2_latency_max_ms` (≤ TMPR) and `<prefix>_commands_lost` (= 0).
pub struct CommandsAfter {
    latency_max: Handle,
    lost: Handle,
    after: &'static str,
}

impl CommandsAfter {
    /// Commands the GCS sends after the fault.
    pub const COMMANDS: u32 = 5;

    /// `after`: what they follow, for the texts ("the silence", "the restart").
    pub fn declare(d: &mut Declarations, prefix: &str, after: &'static str) -> CommandsAfter {
        let n = Self::COMMANDS;
        CommandsAfter {
            latency_max: d.declare(
                spec(&format!("{prefix}_c2_latency_max_ms"), "ms")
                    .describe(format!(
                        "slowest of {n} commands sent after {after} (first send to its \
                         COMMAND_ACK); limit: SORA TMPR medium (3 s)"
                    ))
                    .at_most(TMPR_S * 1000.0),
            ),
            lost: d.declare(
                spec(&format!("{prefix}_commands_lost"), "")
                    .describe(format!(
                        "commands of {n} sent after {after} never acked after 5 sends"
                    ))
                    .equal_to(0.0),
            ),
            after,
        }
    }

    /// Records them from the GCS fixture's command phase.
    pub fn record(&self, ctx: &mut PhaseContext, report: &SessionReport) -> Result<()> {
        let c = report
            .gcs
            .commands
            .as_ref()
            .context("the GCS fixture ran no command phase")?;
        ctx.log(format!(
            "after {}: {} commands acked, {} lost, {} sends, latencies {:?} ms",
            self.after, c.acked, c.lost, c.sends, c.latency_ms
        ));
        ctx.record(self.latency_max, c.latency().max);
        ctx.record(self.lost, f64::from(c.lost));
        Ok(())
    }
}

/// Fails the phase when a program did not stop cleanly (status 0 on
/// SIGTERM, or the GCS's own status): called after the measurements are
/// recorded, so they are kept either way.
pub fn ensure_clean(ctx: &mut PhaseContext, report: &SessionReport) -> Result<()> {
    let bad: Vec<String> = report
        .exits
        .iter()
        .filter(|e| !e.clean())
        .map(|e| format!("{} ({:?}, see {})", e.name, e.status, e.log.display()))
        .collect();
    if bad.is_empty() {
        ctx.log("every program exited with status 0");
        Ok(())
    } else {
        bail!("did not exit cleanly: {}", bad.join("; "))
    }
}
