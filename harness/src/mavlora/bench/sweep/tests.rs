//! The sweep against hostile counterparts: an attenuator that refuses a value or goes away
//! mid-sweep, SiK radios whose ends disagree, a radio that does not speak AT at all. Each
//! must be an error naming the device, and the points measured before it must be kept.

use std::time::Duration;

use super::*;
use crate::driver::attenuator::config::{AttenuatorConfig, EmulatedConfig};
use crate::driver::attenuator::emulated::{EmulatedSpec, Hostile};
use crate::driver::radio_emulator::SikPersonality;
use crate::mavlora::bench::rigfile::{RadioFirmware, RadioPath, SweepPlan};
use crate::mavlora::rigfile::NamedRadio;
use harness_radio::RadioSetup;
use harness_radio::sik::{Board, Param, Params};

/// SiK over the emulator, three 1 dB steps well inside the edge (no loss), quick.
fn plan(firmware: RadioFirmware) -> BenchPlan {
    BenchPlan {
        path: RadioPath::Emulated(Box::new(NamedRadio {
            name: "sik-64k".into(),
            setup: RadioSetup::builtin("sik-64k").unwrap(),
        })),
        firmware,
        fixed_db: 30.0,
        session_db: 60.0,
        attenuator: AttenuatorConfig::Emulated(EmulatedConfig::default()),
        sweep: SweepPlan {
            from_db: 60.0,
            to_db: 62.0,
            step_db: 1.0,
            messages: 100,
            hz: 200.0,
        },
    }
}

fn hostile(h: Hostile) -> Emulated {
    Emulated {
        attenuator: Some(EmulatedSpec {
            hostile: h,
            ..EmulatedSpec::default()
        }),
        radios: None,
    }
}

/// A SiK side with quick escapes (the driver's own guard stays SiK's 1 s).
fn sik(params: Option<Params>) -> Option<SikPersonality> {
    let p = SikPersonality::default().guard(Duration::from_millis(50));
    Some(match params {
        Some(params) => p.eeprom(params),
        None => p,
    })
}

#[test]
fn a_clean_sweep_measures_every_point_through_the_drivers() {
    let outcome = run_sweep(&plan(RadioFirmware::Transparent), Emulated::default()).unwrap();
    assert!(outcome.error.is_none(), "{:?}", outcome.error);
    let dbs: Vec<f64> = outcome.points.iter().map(|p| p.path_db).collect();
    assert_eq!(dbs, [60.0, 61.0, 62.0]);
    // The pads are the plan's: the unit was set to the rest.
    assert_eq!(outcome.points[0].attenuator_db, 30.0);
    for p in &outcome.points {
        assert_eq!((p.count.sent, p.count.received), (100, 100), "{p:?}");
    }
}

#[test]
fn a_unit_that_goes_away_mid_sweep_ends_it_naming_the_unit_and_keeps_the_points_done() {
    // Connecting asks three questions; each step is a set and a readback.
    let outcome = run_sweep(
        &plan(RadioFirmware::Transparent),
        hostile(Hostile::DisconnectAfter(3 + 2 * 2)),
    )
    .unwrap();
    let error = format!(
        "{:#}",
        outcome.error.expect("the sweep went on without its unit")
    );
    assert!(error.contains("EMULATED-0001"), "{error}");
    assert!(error.contains("step 3 of 3"), "{error}");
    assert_eq!(outcome.points.len(), 2);
    let csv = csv(&outcome.points);
    assert_eq!(csv.lines().count(), 1 + 2, "{csv}");
}

#[test]
fn a_refused_value_ends_the_sweep_with_the_units_answer() {
    let outcome = run_sweep(
        &plan(RadioFirmware::Transparent),
        hostile(Hostile::RefuseAbove(30.5)),
    )
    .unwrap();
    let error = format!("{:#}", outcome.error.expect("a refused value was taken"));
    assert!(
        error.contains("refused") && error.contains("RCDAT-6000-90"),
        "{error}"
    );
    assert_eq!(
        outcome.points.len(),
        1,
        "the one point before the refusal is kept"
    );
}

#[test]
fn sik_radios_that_disagree_are_refused_before_the_sweep_naming_the_setting() {
    let board = Board::hm_trp_915();
    let mut other = Params::defaults(&board);
    assert!(other.set(&board, Param::DutyCycle, 50));
    let parts = Emulated {
        attenuator: None,
        radios: Some((sik(Some(other)), sik(None))),
    };
    let error = match RfPath::open_with(&plan(RadioFirmware::Sik), parts) {
        Ok(_) => panic!("mismatched radios were swept"),
        Err(e) => format!("{e:#}"),
    };
    assert!(error.contains("DUTY_CYCLE"), "{error}");
    assert!(
        error.contains("/dev/pts/"),
        "the error names the port: {error}"
    );
}

#[test]
fn a_radio_that_does_not_answer_at_commands_is_an_error_naming_its_port() {
    let parts = Emulated {
        attenuator: None,
        radios: Some((None, None)),
    };
    let error = match RfPath::open_with(&plan(RadioFirmware::Sik), parts) {
        Ok(_) => panic!("a radio that never answered was taken for SiK"),
        Err(e) => format!("{e:#}"),
    };
    assert!(
        error.contains("/dev/pts/") && error.contains("no answer"),
        "{error}"
    );
}

#[test]
fn matched_sik_radios_are_recorded() {
    let parts = Emulated {
        attenuator: None,
        radios: Some((sik(None), sik(None))),
    };
    let path = RfPath::open_with(&plan(RadioFirmware::Sik), parts).unwrap();
    let record = path.sik.expect("no SiK record");
    assert!(record.local.banner.starts_with("SiK"), "{record:?}");
    assert_eq!(record.local.params.len(), 16);
    assert_eq!(record.remote.params.len(), 16);
}
