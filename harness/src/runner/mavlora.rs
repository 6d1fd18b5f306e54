//! MavLora trials: the simulated reproductions (in-process, virtual clock) and the real-time
//! runs of the real binaries, each scenario one phase.

use std::path::Path;
use std::sync::Arc;

use libtest_mimic::Trial;

use super::side_by_side::SideBySide;
use super::{Phases, phase_trial, run_phase};
use crate::driver::program::{MAVLORA_BRIDGE, MAVLORA_ROUTER};
use crate::measurement::Declarations;
use crate::rigfile::{MavloraSection, RigFile, Suite};
use crate::scenario::mavlora::realtime::{self, SessionDefaults};
use crate::scenario::mavlora::simulated::{self, Radios};

/// The simulated scenarios' radios, from the rig file's `[mavlora]`.
pub fn simulated_radios(section: &MavloraSection) -> Radios {
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
        // Not a rig-file role yet: issue 9's target radio (SiK 64k, 10 % loss each way).
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
pub const REALTIME_SIDE_BY_SIDE: usize = 4;

/// Adds the trials of every suite the rig file asks for, the real-time ones in the
/// side-by-side group `realtime`; returns the measurement names they may record (for the
/// `[limits]` check).
pub fn add_trials(
    rig: &Arc<RigFile>,
    phases: &Phases,
    out_dir: &Path,
    realtime: &Arc<SideBySide>,
    trials: &mut Vec<Trial>,
) -> Vec<String> {
    let Some(section) = &rig.mavlora else {
        return Vec::new();
    };
    let mut names = Vec::new();
    if section.suites.contains(&Suite::Simulated) {
        let radios = Arc::new(simulated_radios(section));
        for scenario in simulated::scenarios() {
            let mut declared = Declarations::new();
            let script = (scenario.plan)(&mut declared, &radios);
            names.extend(super::names(&declared));
            let name = format!("mavlora::simulated::{}", scenario.name);
            let (rig, out_dir, radios) = (rig.clone(), out_dir.to_path_buf(), radios.clone());
            trials.push(phase_trial(phases, name.clone(), move || {
                run_phase(&rig, &out_dir, &name, scenario.summary, declared, |ctx| {
                    script(ctx, &radios)
                })
            }));
        }
    }
    let mut realtime_scenarios = Vec::new();
    if section.suites.contains(&Suite::Realtime) {
        realtime_scenarios.extend(realtime::scenarios());
    }
    if section.suites.contains(&Suite::Soak) {
        realtime_scenarios.push(realtime::soak::SCENARIO);
    }
    if !realtime_scenarios.is_empty() {
        let defaults = Arc::new(session_defaults(rig, section));
        for scenario in realtime_scenarios {
            let mut declared = Declarations::new();
            let script = (scenario.plan)(&mut declared);
            names.extend(super::names(&declared));
            let name = format!("mavlora::realtime::{}", scenario.name);
            let (rig, out_dir, defaults) = (rig.clone(), out_dir.to_path_buf(), defaults.clone());
            let phase = name.clone();
            let body = realtime.add(name.clone(), move || {
                run_phase(&rig, &out_dir, &phase, scenario.summary, declared, |ctx| {
                    script(ctx, &defaults)
                })
            });
            trials.push(phase_trial(phases, name, body));
        }
    }
    names
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
