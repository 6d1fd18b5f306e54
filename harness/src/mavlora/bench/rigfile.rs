//! `[mavlora.bench]`: the RF path of the `bench` suite — the two radios, the programmable
//! attenuator between their antenna ports, the fixed pads — and the sweep stepped through it.
//!
//! ```toml
//! [mavlora.bench]
//! radio = "sik-64k"            # the radio emulator plays both radios (a [radios] name or a
//!                              # built-in preset), or two real radios on two ports:
//! # air_port = "/dev/serial/by-id/usb-FTDI_..._A-if00-port0"   # the drone's radio
//! # ground_port = "/dev/serial/by-id/usb-FTDI_..._B-if00-port0" # the ground's radio
//! # baud = 57600               # both radios' serial speed (SiK: SERIAL_SPEED)
//! radio_firmware = "sik"       # "sik": the rig reads both radios' AT settings (the ground's
//!                              # port, the drone's over the air), records them and checks the
//!                              # ends agree; "transparent" (default): it only sends through
//! fixed_db = 0.0               # fixed pads in the path besides the attenuator, dB
//! attenuator = { kind = "emulated" }  # or { kind = "minicircuits", address = "192.168.1.10" }
//! session_db = 78.0           # the bench session's total path attenuation (default: 6 dB
//!                              # inside the emulated preset's edge; required for real radios)
//! # The sweep: total path attenuation (fixed + programmable) from..to in steps; at each step
//! # `messages` HEARTBEATs at `hz` go into the drone's radio and are counted at the ground's.
//! sweep = { from_db = 80.0, to_db = 88.0, step_db = 1.0, messages = 100, hz = 50.0 }
//! ```
//!
//! An emulated attenuator steps the radio emulator's path loss, so it goes with `radio`; a
//! real one with real radios. The sweep's points must be ones the attenuator can set once
//! the fixed pads are taken off (checked when it is connected: its range comes from it).

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::Deserialize;

use super::super::rigfile::NamedRadio;
use crate::driver::attenuator::config::AttenuatorConfig;
use crate::rigfile::{Checker, RigFileError};
use harness_radio::{Preset, RadioSetup};

/// Fewest messages a step sends: the nominal bound is 1 % lost, which must be a whole message
/// at least.
pub const MIN_MESSAGES: u32 = 100;
/// Fastest send rate: a HEARTBEAT is 21 bytes; 200 a second is 4.2 kB/s, within a 64 kbit/s
/// SiK's air rate with room for its framing, and past that a step measures the radio's
/// buffer rather than the path.
pub const MAX_HZ: f64 = 200.0;

/// The checked `[mavlora.bench]`.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchPlan {
    pub path: RadioPath,
    pub firmware: RadioFirmware,
    /// Fixed attenuation in the path besides the programmable attenuator, dB.
    pub fixed_db: f64,
    pub attenuator: AttenuatorConfig,
    pub sweep: SweepPlan,
    /// Total path attenuation the bench session runs at, dB.
    pub session_db: f64,
}

/// What the radios at the two ends run, as far as the rig talks to them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RadioFirmware {
    /// Transparent serial radios: the rig only sends through them.
    #[default]
    Transparent,
    /// SiK (mRo, Holybro, RFD900): the rig reads, records and checks both radios' settings
    /// over the AT command set; the emulator plays SiK on both sides.
    Sik,
}

/// The radios at the two ends of the RF path.
#[derive(Debug, Clone, PartialEq)]
pub enum RadioPath {
    /// The radio emulator plays both radios.
    Emulated(Box<NamedRadio>),
    /// Two real radios: the rig writes into the drone's, reads the ground's.
    SerialPair {
        air_port: PathBuf,
        ground_port: PathBuf,
        baud: u32,
    },
}

impl RadioPath {
    /// The radio's name for measurements and logs: the emulated radio's name, or `serial`.
    pub fn label(&self) -> String {
        match self {
            RadioPath::Emulated(n) => n.name.clone(),
            RadioPath::SerialPair { .. } => "serial".into(),
        }
    }

    /// The preset the path is: the emulated radio's; `None` for real radios.
    pub fn preset(&self) -> Option<Preset> {
        match self {
            RadioPath::Emulated(n) => n.setup.preset.resolve().ok(),
            RadioPath::SerialPair { .. } => None,
        }
    }
}

/// The attenuation sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepPlan {
    pub from_db: f64,
    pub to_db: f64,
    pub step_db: f64,
    pub messages: u32,
    pub hz: f64,
}

impl SweepPlan {
    /// The total path attenuations, dB, from `from_db` up to `to_db` inclusive.
    pub fn points(&self) -> Vec<f64> {
        let n = ((self.to_db - self.from_db) / self.step_db + 1e-9).floor() as usize;
        (0..=n)
            .map(|i| self.from_db + i as f64 * self.step_db)
            .collect()
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawBench {
    radio: Option<String>,
    air_port: Option<PathBuf>,
    ground_port: Option<PathBuf>,
    baud: Option<u32>,
    radio_firmware: Option<RadioFirmware>,
    fixed_db: Option<f64>,
    session_db: Option<f64>,
    attenuator: Option<AttenuatorConfig>,
    sweep: Option<RawSweep>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSweep {
    from_db: f64,
    to_db: f64,
    step_db: Option<f64>,
    messages: Option<u32>,
    hz: Option<f64>,
}

impl Checker<'_> {
    /// Checks `[mavlora.bench]`; `resolve_radio` resolves a radio name as every other role.
    pub(crate) fn bench_plan(
        &self,
        raw: RawBench,
        radios: &BTreeMap<String, RadioSetup>,
        resolve_radio: impl Fn(
            &[&str],
            &str,
            &BTreeMap<String, RadioSetup>,
        ) -> Result<NamedRadio, RigFileError>,
    ) -> Result<BenchPlan, RigFileError> {
        let at = |key: &'static str| ["mavlora", "bench", key];
        let path = match (raw.radio, raw.air_port, raw.ground_port) {
            (Some(name), None, None) => {
                if raw.baud.is_some() {
                    return Err(self.invalid(
                        &at("baud"),
                        "the emulated radio has no serial speed; baud goes with air_port and \
                         ground_port",
                    ));
                }
                RadioPath::Emulated(Box::new(resolve_radio(&at("radio"), &name, radios)?))
            }
            (None, Some(air), Some(ground)) => {
                let baud = raw.baud.unwrap_or(57_600);
                if baud == 0 {
                    return Err(self.invalid(&at("baud"), "0 is not a serial speed"));
                }
                let (air, ground) = (self.resolve(&air), self.resolve(&ground));
                if air == ground {
                    return Err(self.invalid(
                        &at("ground_port"),
                        format!(
                            "{} is also the air_port: each radio needs its own port",
                            ground.display()
                        ),
                    ));
                }
                RadioPath::SerialPair {
                    air_port: air,
                    ground_port: ground,
                    baud,
                }
            }
            (Some(_), _, _) => {
                return Err(self.invalid(
                    &at("radio"),
                    "give either radio (emulated) or air_port and ground_port (real radios), \
                     not both",
                ));
            }
            (None, None, None) => {
                return Err(self.invalid(
                    &at("radio"),
                    "missing: name the emulated radio (radio = \"sik-64k\") or the two real \
                     radios' ports (air_port, ground_port)",
                ));
            }
            (None, _, _) => {
                return Err(self.invalid(
                    &at("air_port"),
                    "real radios need both air_port (the drone's) and ground_port (the ground's)",
                ));
            }
        };
        let fixed_db = raw.fixed_db.unwrap_or(0.0);
        if !(0.0..=200.0).contains(&fixed_db) {
            return Err(self.invalid(
                &at("fixed_db"),
                format!("{fixed_db} is out of range 0..=200 (dB)"),
            ));
        }
        let Some(attenuator) = raw.attenuator else {
            return Err(self.invalid(
                &at("attenuator"),
                "missing: the bench suite steps a programmable attenuator, e.g. \
                 attenuator = { kind = \"emulated\" } with the emulated radio, or \
                 { kind = \"minicircuits\", address = \"192.168.1.10\" }",
            ));
        };
        match (&path, &attenuator) {
            (RadioPath::Emulated(_), AttenuatorConfig::Minicircuits(_)) => {
                return Err(self.invalid(
                    &at("attenuator"),
                    "a real attenuator cannot attenuate the emulated radio; use \
                     { kind = \"emulated\" }, or real radios (air_port, ground_port)",
                ));
            }
            (RadioPath::SerialPair { .. }, AttenuatorConfig::Emulated(_)) => {
                return Err(self.invalid(
                    &at("attenuator"),
                    "the emulated attenuator steps only the radio emulator; real radios need a \
                     real attenuator (kind = \"minicircuits\")",
                ));
            }
            _ => {}
        }
        if let AttenuatorConfig::Minicircuits(m) = &attenuator {
            m.options()
                .map_err(|e| self.invalid(&at("attenuator"), e.to_string()))?;
        }
        let sweep = match raw.sweep {
            Some(s) => s,
            None => {
                // Around the emulated preset's edge, as the simulated sweep; real radios must
                // say where theirs is.
                let Some(edge) = path.preset().map(|p| p.nominal_edge_db().round()) else {
                    return Err(self.invalid(
                        &at("sweep"),
                        "missing: with real radios give the sweep, e.g. sweep = { from_db = \
                         70.0, to_db = 100.0 } (total path attenuation, pads included)",
                    ));
                };
                RawSweep {
                    from_db: edge - 4.0,
                    to_db: edge + 4.0,
                    step_db: None,
                    messages: None,
                    hz: None,
                }
            }
        };
        let sweep = SweepPlan {
            from_db: sweep.from_db,
            to_db: sweep.to_db,
            step_db: sweep.step_db.unwrap_or(1.0),
            messages: sweep.messages.unwrap_or(MIN_MESSAGES),
            hz: sweep.hz.unwrap_or(50.0),
        };
        let bad = |m: String| Err(self.invalid(&at("sweep"), m));
        if !(sweep.from_db.is_finite() && sweep.to_db.is_finite()) || sweep.from_db > sweep.to_db {
            return bad(format!(
                "from_db {} must not be above to_db {}",
                sweep.from_db, sweep.to_db
            ));
        }
        if sweep.from_db < fixed_db {
            return bad(format!(
                "from_db {} is below the fixed pads' {fixed_db} dB: the path cannot attenuate less",
                sweep.from_db
            ));
        }
        if sweep.step_db.is_nan() || sweep.step_db <= 0.0 {
            return bad(format!("step_db {} must be above 0", sweep.step_db));
        }
        if sweep.points().len() > 500 {
            return bad(format!(
                "{} points; a sweep of more than 500 is a typo in step_db",
                sweep.points().len()
            ));
        }
        if sweep.messages < MIN_MESSAGES {
            return bad(format!(
                "messages {} is below {MIN_MESSAGES}: 1 % lost must be a whole message",
                sweep.messages
            ));
        }
        if !(sweep.hz > 0.0 && sweep.hz <= MAX_HZ) {
            return bad(format!("hz {} is out of range (0, {MAX_HZ}]", sweep.hz));
        }
        let session_db = match (raw.session_db, path.preset()) {
            (Some(db), _) => db,
            // Inside the edge by a margin a real link is flown with.
            (None, Some(preset)) => preset.nominal_edge_db().round() - 6.0,
            (None, None) => {
                return Err(self.invalid(
                    &at("session_db"),
                    "missing: with real radios say at which total path attenuation the bench \
                     session runs, e.g. session_db = 78.0",
                ));
            }
        };
        if !(session_db.is_finite() && session_db >= fixed_db) {
            return Err(self.invalid(
                &at("session_db"),
                format!("{session_db} dB is below the fixed pads' {fixed_db} dB"),
            ));
        }
        Ok(BenchPlan {
            session_db,
            path,
            firmware: raw.radio_firmware.unwrap_or_default(),
            fixed_db,
            attenuator,
            sweep,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mavlora::rigfile::Suite;
    use crate::rigfile::RigFile;

    fn load(bench: &str) -> Result<BenchPlan, String> {
        let text = format!(
            "[rig]\nname = \"t\"\n\n[mavlora]\nsuites = [\"bench\"]\n\n[mavlora.bench]\n{bench}\n"
        );
        RigFile::from_str(&text, "/r/rigs/t.toml")
            .map(|rig| rig.devices.mavlora.unwrap().bench.unwrap())
            .map_err(|e| e.to_string())
    }

    #[test]
    fn an_emulated_path_sweeps_around_its_presets_edge_by_default() {
        let plan = load("radio = \"sik-64k\"\nattenuator = { kind = \"emulated\" }").unwrap();
        assert_eq!(plan.firmware, RadioFirmware::Transparent);
        let edge = Preset::sik_64k().nominal_edge_db().round();
        assert_eq!(plan.sweep.points().first(), Some(&(edge - 4.0)));
        assert_eq!(plan.sweep.points().len(), 9);
        assert_eq!(plan.sweep.messages, MIN_MESSAGES);
    }

    #[test]
    fn checked_in_examples_load() {
        let rigs = concat!(env!("CARGO_MANIFEST_DIR"), "/../rigs");
        let bench = RigFile::load(format!("{rigs}/bench-radios.example.toml")).unwrap();
        let m = bench.devices.mavlora.unwrap();
        assert_eq!(m.suites, [Suite::Bench]);
        let plan = m.bench.unwrap();
        assert!(matches!(
            plan.path,
            RadioPath::SerialPair { baud: 57_600, .. }
        ));
        assert_eq!((plan.firmware, plan.fixed_db), (RadioFirmware::Sik, 60.0));
        assert!(matches!(plan.attenuator, AttenuatorConfig::Minicircuits(_)));
        assert_eq!(plan.sweep.points().len(), 31);
        let ci = RigFile::load(format!("{rigs}/emulated.toml")).unwrap();
        let m = ci.devices.mavlora.unwrap();
        assert!(m.suites.contains(&Suite::Bench));
        assert_eq!(m.bench.unwrap().firmware, RadioFirmware::Sik);
    }

    #[test]
    fn the_suite_listed_without_its_section_is_refused() {
        let e = RigFile::from_str(
            "[rig]\nname = \"t\"\n[mavlora]\nsuites = [\"bench\"]\n",
            "/r/rigs/t.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("mavlora.bench") && e.contains("missing"), "{e}");
    }

    #[test]
    fn mixed_or_missing_parts_are_refused_naming_the_key() {
        for (bench, key, words) in [
            (
                "radio = \"sik-64k\"\nattenuator = { kind = \"minicircuits\", address = \"10.0.0.2\" }",
                "mavlora.bench.attenuator",
                "cannot attenuate the emulated radio",
            ),
            (
                "air_port = \"/dev/ttyUSB0\"\nground_port = \"/dev/ttyUSB1\"\nattenuator = { kind = \"emulated\" }\nsweep = { from_db = 70.0, to_db = 90.0 }",
                "mavlora.bench.attenuator",
                "real radios need a real attenuator",
            ),
            (
                "radio = \"sik-64k\"\nair_port = \"/dev/ttyUSB0\"\nattenuator = { kind = \"emulated\" }",
                "mavlora.bench.radio",
                "not both",
            ),
            (
                "air_port = \"/dev/ttyUSB0\"\nattenuator = { kind = \"minicircuits\", address = \"10.0.0.2\" }",
                "mavlora.bench.air_port",
                "both air_port",
            ),
            (
                "air_port = \"/dev/ttyUSB0\"\nground_port = \"/dev/ttyUSB1\"\nattenuator = { kind = \"minicircuits\", address = \"10.0.0.2\" }",
                "mavlora.bench.sweep",
                "with real radios give the sweep",
            ),
            (
                "radio = \"sik-64k\"\nattenuator = { kind = \"emulated\" }\nsweep = { from_db = 80.0, to_db = 90.0, messages = 10 }",
                "mavlora.bench.sweep",
                "1 % lost must be a whole message",
            ),
            (
                "radio = \"sik-64k\"\nfixed_db = 60.0\nattenuator = { kind = \"emulated\" }\nsweep = { from_db = 50.0, to_db = 90.0 }",
                "mavlora.bench.sweep",
                "below the fixed pads",
            ),
            ("radio = \"sik-64k\"", "mavlora.bench.attenuator", "missing"),
            (
                "radio = \"sik-128k\"\nattenuator = { kind = \"emulated\" }",
                "mavlora.bench.radio",
                "sik-128k",
            ),
        ] {
            let e = load(bench).unwrap_err();
            assert!(e.contains(key) && e.contains(words), "{bench}:\n{e}");
        }
    }
}
