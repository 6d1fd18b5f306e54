//! `[radios]` and `[mavlora]`: the emulated radios a rig offers and which of them each
//! MavLora scenario uses.
//!
//! ```toml
//! [radios.sik-bursty]                 # a name scenarios refer to
//! preset = "sik-64k"                  # built in: sik-64k, sik-64k-ecc, lora-sf7, dmd-dl1
//! # burst: Gilbert-Elliott stepped per ms: 10 % of the time in 250 ms fades
//! uplink = { seed = 2, burst = { p_good_to_bad = 0.000444, p_bad_to_good = 0.004 } }
//! downlink = { seed = 1, burst = { p_good_to_bad = 0.000444, p_bad_to_good = 0.004 }, duplicate = 0.01 }
//! # also per direction: packet_loss, bit_error_rate, reorder = { share, delay_ms },
//! # silences = [{ at_s, for_s, every_s }] (harness_radio::faults)
//!
//! [mavlora]
//! suites = ["simulated", "realtime"]  # virtual-clock full-length runs; real binaries over ptys
//!                                     # ("soak": opt-in, soak_minutes of real time)
//! seed = 1
//! soak_minutes = 10                   # length of the "soak" suite's run
//!
//! [mavlora.radios]                    # a [radios] name, or a built-in preset name (no loss)
//! mission = ["lora-bursty", "sik-bursty"]
//!
//! [mavlora.sitl]                      # the "sitl" suite: real autopilots behind the bridge
//! autopilots = ["arducopter", "px4"]  # [autopilots] names; each scenario runs with each
//! telemetry = ["sik-64k", "lora-sf7", "sik-bursty"]   # radios of each scenario
//! params = ["sik-64k", { radio = "lora-sf7", autopilots = ["px4"] }]  # an entry may name
//! params_cache = [{ radio = "sik-64k", autopilots = ["px4"] }]  # which of the autopilots
//! mission = ["sik-bursty"]            # fly it (default: all of them)
//! flight = ["sik-64k"]
//! table_ii = [{ radio = "sik-64k", autopilots = ["px4"] }]  # Table II's limit + filter row
//! ```

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::driver::autopilot::AutopilotSpec;
use crate::rigfile::{Checker, RigFileError};
use harness_radio::{Preset, RadioSetup};

/// Profiles folder used when the rig file names none, relative to the rig file.
pub const DEFAULT_PROFILES_DIR: &str = "../firmware/mavlora/profiles";

/// The real-time `soak` suite's length unless the rig file says.
pub const DEFAULT_SOAK_MINUTES: f64 = 10.0;

/// Which MavLora scenario family runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Suite {
    /// In-process engines and radio model under a virtual clock: the paper's full-length
    /// flights in seconds, deterministic for a seed.
    Simulated,
    /// The real `mavlora-bridge` and `mavlora-router`, pymavlink fixtures and the radio
    /// emulator over ptys, on the real clock: short runs.
    Realtime,
    /// The same, one long run on the real clock (`soak_minutes`): opt-in, never a default.
    Soak,
    /// The real programs behind real autopilots (ArduPilot, PX4 SITL: `[mavlora.sitl]`),
    /// judged against each autopilot's own truth connection.
    Sitl,
    /// The radios on an RF path with a programmable attenuator (`[mavlora.bench]`): real
    /// radios and attenuator on a bench, their emulated counterparts through the same
    /// drivers in CI.
    Bench,
}

impl Suite {
    /// Lower-case name, as in rig files and trial names.
    pub fn as_str(self) -> &'static str {
        match self {
            Suite::Simulated => "simulated",
            Suite::Realtime => "realtime",
            Suite::Soak => "soak",
            Suite::Sitl => "sitl",
            Suite::Bench => "bench",
        }
    }
}

/// A radio as scenarios get it: its rig-file name and its setup.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedRadio {
    /// The `[radios]` key, or the built-in preset name.
    pub name: String,
    pub setup: RadioSetup,
}

/// `[mavlora]`, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct MavloraSection {
    /// Suites to run, in file order.
    pub suites: Vec<Suite>,
    /// Seed of every random draw the scenarios make (radio seeds are per radio).
    pub seed: u64,
    /// Length of the `soak` suite's run, seconds.
    pub soak_s: f64,
    /// `mavlora-bridge` to start; `None`: next to the `rig` binary.
    pub bridge: Option<PathBuf>,
    /// `mavlora-router` to start; `None`: next to the `rig` binary.
    pub router: Option<PathBuf>,
    /// Absolute folder of the bridge profiles (`px4-normal.toml`, ...).
    pub profiles: PathBuf,
    /// `[mavlora.radios]`: scenario role → radios, each resolved.
    pub radios: RadioRoles,
    /// `[mavlora.sitl]`: the autopilots and radios of the `sitl` suite.
    pub sitl: SitlPlan,
    /// `[mavlora.bench]`: the RF path of the `bench` suite; `None` when the file has none.
    pub bench: Option<super::bench::rigfile::BenchPlan>,
}

/// Which autopilots fly the `sitl` suite and over which radios each scenario runs.
#[derive(Debug, Clone, PartialEq)]
pub struct SitlPlan {
    /// `[autopilots]` entries, by rig-file name, in file order.
    pub autopilots: Vec<(String, AutopilotSpec)>,
    /// Steady telemetry: rates, bytes, position freshness.
    pub telemetry: Vec<SitlRun>,
    /// Parameter download as a ground station does it, with a PARAM_SET in flight.
    pub params: Vec<SitlRun>,
    /// A parameter download, then the same list asked for again (a reconnect): the router's
    /// cache.
    pub params_cache: Vec<SitlRun>,
    /// Mission, fence and rally upload and download.
    pub mission: Vec<SitlRun>,
    /// A whole flight: GUIDED, arm, takeoff, AUTO, RTL, landed.
    pub flight: Vec<SitlRun>,
    /// Table II's limiting + filtering row with the autopilot's own streams.
    pub table_ii: Vec<SitlRun>,
}

/// One radio a `sitl` scenario runs over, and which of the suite's autopilots fly it.
#[derive(Debug, Clone, PartialEq)]
pub struct SitlRun {
    pub radio: NamedRadio,
    /// `None`: every autopilot of `[mavlora.sitl] autopilots`.
    pub autopilots: Option<Vec<String>>,
}

impl SitlRun {
    /// Whether `autopilot` flies this run.
    pub fn flown_by(&self, autopilot: &str) -> bool {
        self.autopilots
            .as_ref()
            .is_none_or(|a| a.iter().any(|n| n == autopilot))
    }
}

/// Which radio each scenario uses. Defaults follow the paper's radios and loss, and the
/// project's targets where the paper gives none (SiK 64k for command latency).
#[derive(Debug, Clone, PartialEq)]
pub struct RadioRoles {
    /// Table II's carrier for the bridge variants; `None`: an ideal wire, as the paper
    /// measured (the `wired` variant always runs on one).
    pub table_ii: Option<NamedRadio>,
    /// Mission upload over slow lossy links.
    pub mission: Vec<NamedRadio>,
    /// Command-to-ack latency.
    pub c2: NamedRadio,
    /// Attenuation sweep, one per preset.
    pub sweep: Vec<NamedRadio>,
    /// Loss on the uplink only.
    pub blind_drone: NamedRadio,
    /// Airtime share of the compact profile.
    pub duty: NamedRadio,
    /// Real-time runs that measure bandwidth: loss-free.
    pub realtime_ideal: NamedRadio,
    /// Real-time mission run: lossy.
    pub realtime_lossy: NamedRadio,
    /// Real-time command run: lossy.
    pub realtime_c2: NamedRadio,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawMavlora {
    pub suites: Option<Vec<Suite>>,
    pub seed: Option<u64>,
    pub soak_minutes: Option<f64>,
    pub bridge: Option<String>,
    pub router: Option<String>,
    pub profiles: Option<PathBuf>,
    #[serde(default)]
    pub radios: RawRoles,
    #[serde(default)]
    pub sitl: RawSitl,
    pub bench: Option<super::bench::rigfile::RawBench>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSitl {
    pub autopilots: Option<Vec<String>>,
    pub telemetry: Option<Vec<RawSitlRun>>,
    pub params: Option<Vec<RawSitlRun>>,
    pub params_cache: Option<Vec<RawSitlRun>>,
    pub mission: Option<Vec<RawSitlRun>>,
    pub flight: Option<Vec<RawSitlRun>>,
    pub table_ii: Option<Vec<RawSitlRun>>,
}

/// A radio's name, or `{ radio = "...", autopilots = [...] }`.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub(crate) enum RawSitlRun {
    Radio(String),
    Only(RawSitlOnly),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSitlOnly {
    radio: String,
    autopilots: Vec<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRoles {
    pub table_ii: Option<String>,
    pub mission: Option<Vec<String>>,
    pub c2: Option<String>,
    pub sweep: Option<Vec<String>>,
    pub blind_drone: Option<String>,
    pub duty: Option<String>,
    pub realtime_ideal: Option<String>,
    pub realtime_lossy: Option<String>,
    pub realtime_c2: Option<String>,
}

impl Checker<'_> {
    pub(crate) fn mavlora(
        &self,
        raw: RawMavlora,
        radios: &BTreeMap<String, RadioSetup>,
        autopilots: &BTreeMap<String, AutopilotSpec>,
    ) -> Result<MavloraSection, RigFileError> {
        let suites = match raw.suites {
            None => vec![Suite::Simulated, Suite::Realtime],
            Some(s) if s.is_empty() => {
                return Err(self.invalid(
                    &["mavlora", "suites"],
                    "empty; list \"simulated\", \"realtime\", \"sitl\", \"bench\" and/or \
                     \"soak\", or remove [mavlora]",
                ));
            }
            Some(s) => {
                for (i, x) in s.iter().enumerate() {
                    if s[..i].contains(x) {
                        return Err(self.invalid(
                            &["mavlora", "suites"],
                            format!("\"{}\" is listed twice", x.as_str()),
                        ));
                    }
                }
                s
            }
        };
        let program = |key: &str, p: Option<String>| -> Result<Option<PathBuf>, RigFileError> {
            match p.as_deref() {
                Some("") => Err(self.invalid(
                    &["mavlora", key],
                    format!(
                        "empty; omit it to use {} next to the rig binary",
                        key_program(key)
                    ),
                )),
                p => Ok(p.map(|p| self.resolve_program(p))),
            }
        };
        let soak_minutes = raw.soak_minutes.unwrap_or(DEFAULT_SOAK_MINUTES);
        if !(1.0..=1440.0).contains(&soak_minutes) {
            return Err(self.invalid(
                &["mavlora", "soak_minutes"],
                format!("{soak_minutes} is out of range 1..=1440 (minutes)"),
            ));
        }
        let bridge = program("bridge", raw.bridge)?;
        let router = program("router", raw.router)?;
        let profiles = self.resolve(
            raw.profiles
                .as_deref()
                .unwrap_or(Path::new(DEFAULT_PROFILES_DIR)),
        );

        let sitl = self.sitl_plan(raw.sitl, radios, autopilots, suites.contains(&Suite::Sitl))?;
        let bench = match raw.bench {
            Some(b) => Some(self.bench_plan(b, radios, |at, name, radios| {
                self.radio_at(at, name, radios)
            })?),
            None if suites.contains(&Suite::Bench) => {
                return Err(self.invalid(
                    &["mavlora", "bench"],
                    "the \"bench\" suite is listed but [mavlora.bench] is missing: name the \
                     radios and the attenuator (see rigs/bench-radios.example.toml)",
                ));
            }
            None => None,
        };
        let r = raw.radios;
        let one = |key: &str, given: Option<String>, default: &str| {
            self.named_radio(key, given.as_deref().unwrap_or(default), radios)
        };
        let many = |key: &str, given: Option<Vec<String>>, default: &[&str]| {
            let names: Vec<String> =
                given.unwrap_or_else(|| default.iter().map(|s| s.to_string()).collect());
            if names.is_empty() {
                return Err(self.invalid(
                    &["mavlora", "radios", key],
                    "empty; list one radio at least",
                ));
            }
            names
                .iter()
                .map(|n| self.named_radio(key, n, radios))
                .collect::<Result<Vec<_>, _>>()
        };
        let roles = RadioRoles {
            table_ii: r
                .table_ii
                .map(|n| self.named_radio("table_ii", &n, radios))
                .transpose()?,
            mission: many("mission", r.mission, &["lora-sf7", "sik-64k"])?,
            c2: one("c2", r.c2, "sik-64k")?,
            sweep: many("sweep", r.sweep, &["sik-64k", "lora-sf7", "dmd-dl1"])?,
            blind_drone: one("blind_drone", r.blind_drone, "sik-64k")?,
            duty: one("duty", r.duty, "lora-sf7")?,
            realtime_ideal: one("realtime_ideal", r.realtime_ideal, "sik-64k")?,
            realtime_lossy: one("realtime_lossy", r.realtime_lossy, "sik-64k")?,
            realtime_c2: one("realtime_c2", r.realtime_c2, "sik-64k")?,
        };
        Ok(MavloraSection {
            suites,
            seed: raw.seed.unwrap_or(1),
            soak_s: soak_minutes * 60.0,
            bridge,
            router,
            profiles,
            radios: roles,
            sitl,
            bench,
        })
    }

    /// `[mavlora.sitl]`: every autopilot named is defined; radios as the other roles. With
    /// the `sitl` suite listed, at least one autopilot.
    fn sitl_plan(
        &self,
        raw: RawSitl,
        radios: &BTreeMap<String, RadioSetup>,
        autopilots: &BTreeMap<String, AutopilotSpec>,
        listed: bool,
    ) -> Result<SitlPlan, RigFileError> {
        let names = raw.autopilots.unwrap_or_default();
        if listed && names.is_empty() {
            return Err(self.invalid(
                &["mavlora", "sitl", "autopilots"],
                "the \"sitl\" suite is listed but names no autopilot; list [autopilots] \
                 names here, e.g. autopilots = [\"arducopter\"]",
            ));
        }
        let mut chosen = Vec::new();
        for (i, name) in names.iter().enumerate() {
            if names[..i].contains(name) {
                return Err(self.invalid(
                    &["mavlora", "sitl", "autopilots"],
                    format!("\"{name}\" is listed twice"),
                ));
            }
            let Some(spec) = autopilots.get(name) else {
                let known: Vec<&str> = autopilots.keys().map(String::as_str).collect();
                return Err(self.invalid(
                    &["mavlora", "sitl", "autopilots"],
                    format!(
                        "no autopilot named \"{name}\"; define [autopilots.{name}]{}",
                        if known.is_empty() {
                            String::new()
                        } else {
                            format!(" or use one of: {}", known.join(", "))
                        }
                    ),
                ));
            };
            chosen.push((name.clone(), spec.clone()));
        }
        let many = |key: &str, given: Option<Vec<RawSitlRun>>| {
            let given = given.unwrap_or_else(|| vec![RawSitlRun::Radio("sik-64k".into())]);
            given
                .into_iter()
                .map(|run| {
                    let at = ["mavlora", "sitl", key];
                    let (radio, only) = match run {
                        RawSitlRun::Radio(r) => (r, None),
                        RawSitlRun::Only(o) => (o.radio, Some(o.autopilots)),
                    };
                    if let Some(stranger) = only.iter().flatten().find(|a| !names.contains(a)) {
                        return Err(self.invalid(
                            &at,
                            format!(
                                "\"{stranger}\" (in the entry of radio \"{radio}\") is not one \
                                 of the suite's autopilots: {}",
                                names.join(", ")
                            ),
                        ));
                    }
                    Ok(SitlRun {
                        radio: self.radio_at(&at, &radio, radios)?,
                        autopilots: only,
                    })
                })
                .collect::<Result<Vec<_>, _>>()
        };
        Ok(SitlPlan {
            autopilots: chosen,
            telemetry: many("telemetry", raw.telemetry)?,
            params: many("params", raw.params)?,
            params_cache: many("params_cache", raw.params_cache)?,
            mission: many("mission", raw.mission)?,
            flight: many("flight", raw.flight)?,
            table_ii: many("table_ii", raw.table_ii)?,
        })
    }

    fn named_radio(
        &self,
        key: &str,
        name: &str,
        radios: &BTreeMap<String, RadioSetup>,
    ) -> Result<NamedRadio, RigFileError> {
        self.radio_at(&["mavlora", "radios", key], name, radios)
    }

    fn radio_at(
        &self,
        at: &[&str],
        name: &str,
        radios: &BTreeMap<String, RadioSetup>,
    ) -> Result<NamedRadio, RigFileError> {
        let setup = radios
            .get(name)
            .cloned()
            .or_else(|| RadioSetup::builtin(name).ok());
        match setup {
            Some(setup) => Ok(NamedRadio {
                name: name.to_owned(),
                setup,
            }),
            None => {
                let mut known: Vec<&str> = radios.keys().map(String::as_str).collect();
                known.extend(Preset::BUILTIN);
                Err(self.invalid(
                    at,
                    format!(
                        "no radio named \"{name}\"; define [radios.{name}] or use one of: {}",
                        known.join(", ")
                    ),
                ))
            }
        }
    }
}

fn key_program(key: &str) -> &'static str {
    match key {
        "bridge" => "mavlora-bridge",
        _ => "mavlora-router",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rigfile::RigFile;

    const GOOD: &str = r#"[rig]
name = "t"

[radios.sik-bursty]
preset = "sik-64k"
uplink = { seed = 2, burst = { p_good_to_bad = 0.037, p_bad_to_good = 0.333 } }
downlink = { seed = 1, burst = { p_good_to_bad = 0.037, p_bad_to_good = 0.333 }, silences = [{ at_s = 5.0, for_s = 1.0 }] }

[mavlora]
seed = 7

[mavlora.radios]
mission = ["lora-sf7", "sik-bursty"]
c2 = "sik-bursty"
"#;

    fn load(text: &str) -> Result<RigFile, RigFileError> {
        RigFile::from_str(text, "/r/rigs/t.toml")
    }

    #[test]
    fn roles_resolve_to_defined_and_built_in_radios() {
        let rig = load(GOOD).unwrap();
        let m = rig.devices.mavlora.unwrap();
        assert_eq!(m.suites, vec![Suite::Simulated, Suite::Realtime]);
        assert_eq!(m.seed, 7);
        assert_eq!(m.profiles, PathBuf::from("/r/firmware/mavlora/profiles"));
        let names: Vec<_> = m.radios.mission.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(names, ["lora-sf7", "sik-bursty"]);
        assert!(m.radios.c2.setup.uplink.burst.is_some());
        // a role left out takes its default, loss-free
        assert_eq!(m.radios.duty.name, "lora-sf7");
        assert!(m.radios.duty.setup.downlink.burst.is_none());
        assert_eq!(m.radios.sweep.len(), 3);
    }

    #[test]
    fn the_soak_runs_only_when_listed_and_its_length_is_checked() {
        assert_eq!(load(GOOD).unwrap().devices.mavlora.unwrap().soak_s, 600.0);
        let text = GOOD.replace(
            "seed = 7",
            "seed = 7\nsuites = [\"soak\"]\nsoak_minutes = 2.5",
        );
        let m = load(&text).unwrap().devices.mavlora.unwrap();
        assert_eq!((m.suites, m.soak_s), (vec![Suite::Soak], 150.0));
        let text = GOOD.replace("seed = 7", "seed = 7\nsoak_minutes = 0");
        let err = load(&text).unwrap_err().to_string();
        assert!(
            err.contains("mavlora.soak_minutes") && err.contains("1..=1440"),
            "{err}"
        );
    }

    #[test]
    fn an_unknown_radio_is_named_with_its_line_and_the_known_ones() {
        let text = GOOD.replace("c2 = \"sik-bursty\"", "c2 = \"sik-burst\"");
        let err = load(&text).unwrap_err().to_string();
        assert!(err.starts_with("/r/rigs/t.toml:14:"), "{err}");
        assert!(err.contains("mavlora.radios.c2"), "{err}");
        assert!(
            err.contains("\"sik-burst\"") && err.contains("sik-bursty, sik-64k"),
            "{err}"
        );
    }

    #[test]
    fn a_radio_the_model_refuses_fails_at_load() {
        let text = GOOD.replace(
            "p_bad_to_good = 0.333 } }\ndownlink",
            "p_bad_to_good = 3.0 } }\ndownlink",
        );
        let err = load(&text).unwrap_err().to_string();
        assert!(err.contains("radios.sik-bursty"), "{err}");
        assert!(err.contains("out of range"), "{err}");
        let text = GOOD.replace("preset = \"sik-64k\"", "preset = \"sik-128k\"");
        let err = load(&text).unwrap_err().to_string();
        assert!(err.contains("unknown radio preset \"sik-128k\""), "{err}");
    }

    #[test]
    fn faults_the_model_refuses_fail_at_load_naming_the_radio() {
        let good = load(GOOD).unwrap();
        let m = good.devices.mavlora.unwrap();
        assert_eq!(m.radios.c2.setup.downlink.silences[0].for_s, 1.0);
        for (from, to) in [
            ("for_s = 1.0 }", "for_s = 0.0 }"),
            ("for_s = 1.0 }", "for_s = 1.0, every_s = 0.5 }"),
            ("silences = [", "duplicate = 1.5, silences = ["),
            ("silences = [", "bit_error_rate = -1.0, silences = ["),
            (
                "silences = [",
                "reorder = { share = 0.1, delay_ms = -5.0 }, silences = [",
            ),
        ] {
            let err = load(&GOOD.replace(from, to)).unwrap_err().to_string();
            assert!(err.contains("radios.sik-bursty"), "{to}: {err}");
            assert!(err.contains("out of range"), "{to}: {err}");
        }
        let err = load(&GOOD.replace("for_s = 1.0 }", "for_s = 1.0, every = 3.0 }"))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("/r/rigs/t.toml:7:") && err.contains("every"),
            "{err}"
        );
    }

    #[test]
    fn a_typo_in_a_direction_is_a_syntax_error_naming_the_key() {
        let text = GOOD.replace("uplink = { seed = 2,", "uplink = { sed = 2,");
        let err = load(&text).unwrap_err().to_string();
        assert!(err.contains("sed"), "{err}");
        assert!(err.starts_with("/r/rigs/t.toml:6:"), "{err}");
    }

    #[test]
    fn suites_empty_or_twice_are_refused() {
        let text = GOOD.replace("seed = 7", "suites = []");
        assert!(
            load(&text)
                .unwrap_err()
                .to_string()
                .contains("mavlora.suites: empty")
        );
        let text = GOOD.replace("seed = 7", "suites = [\"realtime\", \"realtime\"]");
        assert!(
            load(&text)
                .unwrap_err()
                .to_string()
                .contains("listed twice")
        );
    }

    #[test]
    fn the_sitl_suite_names_defined_autopilots() {
        let with = |sitl: &str| {
            format!(
                "{GOOD}\n[autopilots.copter]\nkind = \"ardupilot-sitl\"\nprogram = \
                 \"../sitl/arducopter\"\nfc_mavlink = 1\n\n[mavlora.sitl]\n{sitl}\n"
            )
            .replace("seed = 7", "seed = 7\nsuites = [\"sitl\"]")
        };
        let m = load(&with(
            "autopilots = [\"copter\"]\nmission = [\"sik-bursty\"]",
        ))
        .unwrap()
        .devices
        .mavlora
        .unwrap();
        assert_eq!(m.suites, vec![Suite::Sitl]);
        let (name, spec) = &m.sitl.autopilots[0];
        assert_eq!(name, "copter");
        let AutopilotSpec::ArdupilotSitl(a) = spec else {
            panic!("{spec:?}")
        };
        assert_eq!(a.program, PathBuf::from("/r/sitl/arducopter"));
        assert_eq!((a.fc_mavlink, a.fc_baud), (1, 57_600));
        assert_eq!(m.sitl.mission[0].radio.name, "sik-bursty");
        assert_eq!(m.sitl.telemetry[0].radio.name, "sik-64k");
        assert!(m.sitl.mission[0].flown_by("copter"));

        // an entry may say which autopilots fly it; only the suite's
        let m = load(&with(
            "autopilots = [\"copter\"]\nparams = [\"sik-64k\", { radio = \"sik-bursty\", \
             autopilots = [\"copter\"] }]",
        ))
        .unwrap()
        .devices
        .mavlora
        .unwrap();
        let runs: Vec<_> = m
            .sitl
            .params
            .iter()
            .map(|r| (r.radio.name.as_str(), r.autopilots.clone()))
            .collect();
        assert_eq!(
            runs,
            [
                ("sik-64k", None),
                ("sik-bursty", Some(vec!["copter".to_string()]))
            ]
        );
        assert!(!m.sitl.params[1].flown_by("px4") && m.sitl.params[1].flown_by("copter"));
        let err = load(&with(
            "autopilots = [\"copter\"]\nparams = [{ radio = \"sik-64k\", autopilots = [\"px4\"] }]",
        ))
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("mavlora.sitl.params")
                && err.contains("\"px4\"")
                && err.contains("copter"),
            "{err}"
        );

        let err = load(&with("autopilots = [\"coptr\"]"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("mavlora.sitl.autopilots")
                && err.contains("\"coptr\"")
                && err.contains("copter"),
            "{err}"
        );
        let err = load(&with("")).unwrap_err().to_string();
        assert!(err.contains("names no autopilot"), "{err}");
        let err = load(&with("autopilots = [\"copter\"]\nflight = [\"sik\"]"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("mavlora.sitl.flight"), "{err}");
        let err =
            load(&with("autopilots = [\"copter\"]").replace("fc_mavlink = 1", "fc_mavlink = 3"))
                .unwrap_err()
                .to_string();
        assert!(err.contains("autopilots.copter.fc_mavlink"), "{err}");
        let err =
            load(&with("autopilots = [\"copter\"]").replace("fc_mavlink = 1", "fc_mavlnk = 1"))
                .unwrap_err()
                .to_string();
        assert!(err.contains("fc_mavlnk"), "{err}");
    }

    #[test]
    fn a_radio_may_not_shadow_a_built_in_preset() {
        let text = GOOD.replace("[radios.sik-bursty]", "[radios.sik-64k]");
        let err = load(&text).unwrap_err().to_string();
        assert!(err.contains("built-in preset's name"), "{err}");
    }
}
