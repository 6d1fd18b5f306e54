//! MavLora's phases: the simulated reproductions (in-process, virtual clock) and the real-time
//! runs of the real binaries, each scenario one phase.

use std::sync::Arc;

use anyhow::Result;

use super::realtime::{self, SessionDefaults};
use super::rigfile::{MavloraSection, Suite};
use super::simulated::{self, Radios};
use super::sitl;
use super::{MAVLORA_BRIDGE, MAVLORA_ROUTER};
use crate::measurement::Declarations;
use crate::record::DeviceIdentity;
use crate::rigfile::RigFile;
use crate::runner::{Device, Phase, SideBySideGroup};

/// The simulated scenarios' radios, from the rig file's `[mavlora]`.
fn simulated_radios(section: &MavloraSection) -> Radios {
    let r = &section.radios;
    Radios {
        table_ii: r.table_ii.as_ref().map(|n| n.setup.clone()),
        // The radio dimension is the rig file's radio name: `lora-sf7-bursty` → `lora_sf7_bursty`.
        mission: r
            .mission
            .iter()
            .map(|n| (n.name.replace('-', "_"), n.setup.clone()))
            .collect(),
        c2: r.c2.setup.clone(),
        // Not a rig-file role yet: the radio of the project's command-latency target (SiK
        // 64k, 10 % loss each way).
        c2_target: Radios::paper_defaults().c2_target,
        sweep: r.sweep.iter().map(|n| n.setup.clone()).collect(),
        blind_drone: r.blind_drone.setup.clone(),
        duty: r.duty.setup.clone(),
        seed: section.seed,
    }
}

/// Real-time phases running at once: each is a session of four programs and a radio
/// thread on ptys of its own, mostly waiting on scripted seconds of flight. Four keep a
/// 2-core machine busy without starving the sessions' timers (their figures are latencies
/// of hundreds of ms against limits of seconds).
pub const REALTIME: SideBySideGroup = SideBySideGroup {
    name: "mavlora::realtime",
    width: 4,
};

/// MavLora as a rig file's `[mavlora]` describes it.
pub struct Mavlora {
    rig: Arc<RigFile>,
}

impl Mavlora {
    pub fn new(rig: Arc<RigFile>) -> Self {
        Mavlora { rig }
    }
}

impl Device for Mavlora {
    /// The phases of every suite the rig file asks for, the real-time ones side by side.
    fn phases(&self) -> Result<Vec<Phase>> {
        let mut phases = Vec::new();
        let Some(section) = &self.rig.devices.mavlora else {
            return Ok(phases);
        };
        if section.suites.contains(&Suite::Simulated) {
            let radios = Arc::new(simulated_radios(section));
            for scenario in simulated::scenarios() {
                let mut declared = Declarations::new();
                let script = (scenario.plan)(&mut declared, &radios);
                let name = format!("mavlora::simulated::{}", scenario.name);
                let radios = radios.clone();
                phases.push(Phase::measured(
                    name,
                    scenario.summary,
                    declared,
                    move |ctx| script(ctx, &radios),
                ));
            }
        }
        let mut realtime_scenarios = Vec::new();
        if section.suites.contains(&Suite::Realtime) {
            realtime_scenarios.extend(realtime::scenarios());
        }
        if section.suites.contains(&Suite::Soak) {
            realtime_scenarios.push(realtime::soak::SCENARIO);
        }
        let defaults = Arc::new(session_defaults(&self.rig, section));
        if !realtime_scenarios.is_empty() {
            for scenario in realtime_scenarios {
                let mut declared = Declarations::new();
                let script = (scenario.plan)(&mut declared);
                let name = format!("mavlora::realtime::{}", scenario.name);
                let defaults = defaults.clone();
                phases.push(
                    Phase::measured(name, scenario.summary, declared, move |ctx| {
                        script(ctx, &defaults)
                    })
                    .side_by_side(REALTIME),
                );
            }
        }
        if section.suites.contains(&Suite::Sitl) {
            phases.extend(sitl::phases(&section.sitl, &defaults));
        }
        if section.suites.contains(&Suite::Bench)
            && let Some(plan) = &section.bench
        {
            phases.extend(super::bench::phases(&Arc::new(plan.clone()), &defaults));
        }
        Ok(phases)
    }

    /// The bridge and router are programs of this build (the record's tool identity).
    fn identities(&self) -> Vec<DeviceIdentity> {
        Vec::new()
    }
}

/// What the real-time sessions start, from the rig file: its Python and fixtures, the
/// MavLora programs it names (else those next to the `rig` binary), its profiles and radios.
fn session_defaults(rig: &RigFile, section: &MavloraSection) -> SessionDefaults {
    SessionDefaults {
        python: rig.fixtures.python.clone(),
        fixtures_dir: rig.fixtures.dir.clone(),
        bridge_program: match &section.bridge {
            Some(p) => p.clone(),
            None => MAVLORA_BRIDGE.path(),
        },
        router_program: match &section.router {
            Some(p) => p.clone(),
            None => MAVLORA_ROUTER.path(),
        },
        profile_dir: section.profiles.clone(),
        lossy_radio: section.radios.realtime_lossy.setup.clone(),
        clean_radio: section.radios.realtime_ideal.setup.clone(),
        c2_radio: section.radios.realtime_c2.setup.clone(),
        soak_s: section.soak_s,
    }
}
