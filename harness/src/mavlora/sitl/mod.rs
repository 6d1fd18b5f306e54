//! The `sitl` suite: the real `mavlora-bridge` and `mavlora-router` behind real autopilots
//! (ArduPilot and PX4 software-in-the-loop builds, `[autopilots]` in the rig file), a
//! pymavlink ground station that behaves as QGroundControl does, and each autopilot's
//! second MAVLink connection as the judge ([`session`]).
//!
//! Scenarios, each run with every autopilot of `[mavlora.sitl]` over each of its radios:
//! - [`telemetry`]: steady telemetry: bytes each way, position rate and freshness;
//! - [`params`]: the whole parameter list as a ground station downloads it, with a
//!   PARAM_SET in flight, and the position rate meanwhile; and ([`params::CACHE`]) the list
//!   asked for again, as a reconnecting ground station does (the router's cache);
//! - [`mission`]: a 30-item plan uploaded and read back; the plan the vehicle holds must
//!   be the one the ground was told ACCEPTED;
//! - [`flight`]: GUIDED, arm, takeoff, AUTO through a mission, RTL, landed: every command
//!   acked once and done, and each state change at the ground soon after the vehicle's;
//! - [`table_ii`]: the paper's limiting + filtering row with the autopilot's own streams.
//!
//! An autopilot whose program is missing makes its phases `skipped` (never passed), with how
//! to get one.

pub mod flight;
pub mod freshness;
pub mod mission;
pub mod params;
pub mod session;
pub mod table_ii;
pub mod telemetry;

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Result;

use self::session::{SitlOptions, SitlReport, SitlSession};
use crate::driver::autopilot::AutopilotSpec;
use crate::mavlora::fixture::sitl::GroundEvent;
use crate::mavlora::rigfile::{NamedRadio, SitlRun};
use crate::mavlora::session::SessionDefaults;
use crate::measurement::{Declarations, Dimension, PTY, Spec};
use crate::record::{PhaseRecord, now_rfc3339};
use crate::runner::{Phase, PhaseContext, SideBySideGroup};

/// SITL phases running at once: each runs an autopilot simulation, the two MavLora
/// programs, the radio thread and two pymavlink fixtures, ~0.3 of a core in all at real time
/// (measured: 73 s of CPU over 254 s for the twelve phases three at a time); four keep a
/// 2-core machine under its limit and its timers on time.
pub const SITL: SideBySideGroup = SideBySideGroup {
    name: "mavlora::sitl",
    width: 4,
};

/// One scenario of the suite.
pub struct Scenario {
    pub name: &'static str,
    pub summary: &'static str,
    /// Declares its measurements for an autopilot and radio, and returns the script.
    pub plan: fn(&mut Declarations, &Target) -> Script,
    /// Which of `[mavlora.sitl]`'s radio lists it runs over.
    pub radios: fn(&crate::mavlora::rigfile::SitlPlan) -> &[SitlRun],
}

/// What one phase flies: an autopilot over a radio.
#[derive(Clone)]
pub struct Target {
    /// The autopilot's rig-file name.
    pub autopilot: String,
    pub spec: AutopilotSpec,
    pub radio: NamedRadio,
}

impl Target {
    /// Which autopilot software it is, for the scenario's choices (modes, parameters).
    pub fn flavour(&self) -> Flavour {
        match self.spec {
            AutopilotSpec::Px4Sitl(_) => Flavour::Px4,
            _ => Flavour::ArduPilot,
        }
    }

    /// The radio's preset (`sik-64k`, `lora-sf7`...).
    pub fn preset(&self) -> String {
        self.radio
            .setup
            .preset
            .resolve()
            .map(|p| p.name)
            .unwrap_or_default()
    }

    /// Whether the radio loses packets by design (bursty or independent loss).
    pub fn lossy(&self) -> bool {
        let lossy = |l: &harness_radio::LinkConfig| l.burst.is_some() || l.packet_loss > 0.0;
        lossy(&self.radio.setup.downlink) || lossy(&self.radio.setup.uplink)
    }

    /// The autopilot's rig-file name as a dimension value. The bare `px4` is the PX4-like
    /// fixture's, kept out of flat names, so a real one named `px4` goes by its kind
    /// (`px4_sitl`).
    pub fn autopilot_dimension(&self) -> String {
        let name = self.autopilot.replace('-', "_");
        if name == crate::measurement::PX4 {
            self.spec.kind().replace('-', "_")
        } else {
            name
        }
    }

    /// A measurement of this target: `mavlora.pty.<autopilot>.<radio>.compact.<base>`.
    pub fn spec(&self, base: &str, unit: &str) -> Spec {
        Spec::new(base, unit)
            .dim(Dimension::Device, "mavlora")
            .dim(Dimension::Transport, PTY)
            .dim(Dimension::Autopilot, self.autopilot_dimension())
            .dim(Dimension::Radio, self.radio.name.replace('-', "_"))
            .dim(Dimension::Variant, "compact")
    }
}

/// The autopilot software, where scenarios differ by it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flavour {
    ArduPilot,
    Px4,
}

/// A scenario's script for one target.
pub type Script =
    Box<dyn FnOnce(&mut PhaseContext, &SessionDefaults, &Target) -> Result<()> + Send>;

/// Every scenario, in the order they run.
pub fn scenarios() -> Vec<Scenario> {
    // Longest first, so the shorter phases fill the other slots: the flights take ~125 s
    // each, PX4's parameters over LoRa SF7 ~115 s, Table II and telemetry ~53 s, the
    // reconnecting ground's parameters and the missions ~20 s (CI's times; in this order four lanes end after ~190 s by those times,
    // against ~230 s with the parameters after the telemetry).
    vec![
        flight::SCENARIO,
        params::SCENARIO,
        table_ii::SCENARIO,
        telemetry::SCENARIO,
        params::CACHE,
        mission::SCENARIO,
    ]
}

/// The suite's phases for `[mavlora.sitl]`, side by side.
pub fn phases(
    plan: &crate::mavlora::rigfile::SitlPlan,
    defaults: &Arc<SessionDefaults>,
) -> Vec<Phase> {
    let mut phases = Vec::new();
    for scenario in scenarios() {
        for (autopilot, spec) in &plan.autopilots {
            for run in (scenario.radios)(plan) {
                if !run.flown_by(autopilot) {
                    continue;
                }
                let radio = &run.radio;
                let target = Target {
                    autopilot: autopilot.clone(),
                    spec: spec.clone(),
                    radio: radio.clone(),
                };
                let name = format!(
                    "mavlora::sitl::{}::{}::{}",
                    scenario.name, autopilot, radio.name
                );
                let mut declared = Declarations::new();
                let script = (scenario.plan)(&mut declared, &target);
                let phase = match spec.available() {
                    Ok(()) => {
                        let defaults = defaults.clone();
                        Phase::measured(name, scenario.summary, declared, move |ctx| {
                            script(ctx, &defaults, &target)
                        })
                    }
                    Err(missing) => {
                        let why = format!("not run: {missing}");
                        Phase::custom(name.clone(), declared, move |_, declared| {
                            PhaseRecord::skipped(
                                name,
                                now_rfc3339(),
                                declared.into_measurements(),
                                why,
                            )
                        })
                    }
                };
                phases.push(phase.side_by_side(SITL));
            }
        }
    }
    phases
}

/// Session options for `target`, logging into `dir`: the compact profile of its autopilot.
pub fn options(
    defaults: &SessionDefaults,
    target: &Target,
    dir: &Path,
    ground_args: Vec<String>,
    budget: Duration,
) -> SitlOptions {
    let mut link = defaults.options(&target.autopilot, &target.radio.setup, dir);
    link.bridge_profile = defaults.profile_dir.join(match target.flavour() {
        Flavour::Px4 => "px4-compact.toml",
        Flavour::ArduPilot => "ardupilot-compact.toml",
    });
    link.compact = true;
    link.fc_baud = Some(target.spec.fc_baud());
    SitlOptions {
        link,
        autopilot: (target.autopilot.clone(), target.spec.clone()),
        ground_args,
        budget,
        truth_after: Vec::new(),
    }
}

/// Runs one session to the end of the ground station's scenario and keeps its evidence;
/// records the autopilot's version in the log.
pub fn run(ctx: &mut PhaseContext, options: SitlOptions) -> Result<SitlReport> {
    let name = options.autopilot.0.clone();
    let session = SitlSession::start(options)?;
    ctx.log(format!(
        "{name}: vehicle heartbeat at the ground station {:.1} s after the autopilot started",
        crate::clock::Mono::now()
            .since(session.started)
            .as_secs_f64()
    ));
    let files = session.files();
    match session.finish() {
        Ok(report) => {
            keep_evidence(ctx, &name, &report);
            Ok(report)
        }
        Err(e) => {
            // What there is, so the reader sees why (a dead SITL's last words among it).
            for file in files.into_iter().filter(|f| f.exists()) {
                let stem = file.file_name().unwrap_or_default().to_string_lossy();
                ctx.attach(format!("{name}/{stem}"), file.clone(), "text/plain");
            }
            Err(e)
        }
    }
}

/// Attaches the session's files and logs what the autopilot is and how the ground station
/// fared.
pub fn keep_evidence(ctx: &mut PhaseContext, label: &str, report: &SitlReport) {
    for file in &report.files {
        let stem = file.file_name().unwrap_or_default().to_string_lossy();
        ctx.attach(format!("{label}/{stem}"), file.clone(), "text/plain");
    }
    match report.version() {
        Some((v, hash)) => ctx.log(format!("{label}: autopilot version {v} ({hash})")),
        None => ctx.log(format!("{label}: the autopilot sent no AUTOPILOT_VERSION")),
    }
    let s = &report.ground_summary;
    ctx.log(format!(
        "{label}: ground station {} (exit {:?}){}",
        if s.ok { "succeeded" } else { "failed" },
        report.ground_exit,
        if s.failed.is_empty() {
            String::new()
        } else {
            format!(": {}", s.failed)
        }
    ));
    for e in report.ground_events() {
        if let GroundEvent::Statustext { text, .. } = e {
            ctx.log(format!("{label}: STATUSTEXT at the ground: {text}"));
        }
    }
    let (d, u) = (&report.downlink, &report.uplink);
    ctx.log(format!(
        "{label}: radio downlink {} B on air, {} lost, {} dropped; uplink {} on air, {} lost",
        d.bytes_sent, d.bytes_lost, d.bytes_dropped, u.bytes_sent, u.bytes_lost
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
