//! The RF path as resources: the two radios (the radio emulator, or two real radios' ports)
//! and the programmable attenuator between them, connected through its real driver in both
//! cases: in CI the attenuator is the emulated Mini-Circuits unit on 127.0.0.1, whose settings
//! step the radio emulator's path loss, so a bench differs from CI only in its rig file.

use std::sync::Arc;

use anyhow::{Context, Result};

use super::rigfile::{BenchPlan, RadioFirmware, RadioPath};
use crate::driver::attenuator::Attenuator;
use crate::driver::attenuator::config::AttenuatorConfig;
use crate::driver::attenuator::emulated::{EmulatedMiniCircuits, EmulatedSpec};
use crate::driver::attenuator::minicircuits::{MiniCircuits, Options, Transport};
use crate::driver::radio_emulator::{RadioEmulator, SikPersonality};
use crate::driver::sik::{SikClient, SikRecord, check_match};

/// Serial speed of the probe on the emulator's ptys (a pty ignores it).
const PTY_BAUD: u32 = 57_600;

/// The path, up and connected.
pub struct RfPath {
    /// The drone's radio's port: where the probe writes.
    pub air_port: String,
    /// The ground's radio's port: where the probe reads.
    pub ground_port: String,
    pub baud: u32,
    pub attenuator: Box<dyn Attenuator + Send>,
    /// The radio emulator, when it plays the radios.
    pub emulator: Option<Arc<RadioEmulator>>,
    /// Both SiK radios' firmware and settings, as read before the sweep.
    pub sik: Option<SikRecord>,
    /// The emulated attenuator unit, kept running while the path is.
    _unit: Option<EmulatedMiniCircuits>,
}

/// What the emulated parts are instead of the rig file's (tests: hostile counterparts).
#[derive(Default)]
pub struct Emulated {
    /// The attenuator unit, e.g. one that refuses a value or goes away mid-sweep.
    pub attenuator: Option<EmulatedSpec>,
    /// Each side's firmware, air then ground: SiK with other settings, or `None` for a
    /// radio that does not speak the AT command set.
    pub radios: Option<(Option<SikPersonality>, Option<SikPersonality>)>,
}

impl RfPath {
    /// Brings the path up as `plan` says.
    pub fn open(plan: &BenchPlan) -> Result<RfPath> {
        Self::open_with(plan, Emulated::default())
    }

    /// As [`RfPath::open`], with emulated parts other than the plan's.
    pub fn open_with(plan: &BenchPlan, parts: Emulated) -> Result<RfPath> {
        let mut path = Self::connect(plan, parts)?;
        if plan.firmware == RadioFirmware::Sik {
            path.sik = Some(read_sik(&path.ground_port, path.baud)?);
        }
        Ok(path)
    }

    fn connect(plan: &BenchPlan, parts: Emulated) -> Result<RfPath> {
        match (&plan.path, &plan.attenuator) {
            (RadioPath::Emulated(radio), AttenuatorConfig::Emulated(cfg)) => {
                let name = format!("bench-{}", radio.name);
                let model = radio
                    .setup
                    .radio()
                    .with_context(|| format!("radio \"{}\"", radio.name))?;
                let sides = parts.radios.or_else(|| {
                    (plan.firmware == RadioFirmware::Sik).then(|| {
                        (
                            Some(SikPersonality::default()),
                            Some(SikPersonality::default()),
                        )
                    })
                });
                let emulator = Arc::new(match sides {
                    None | Some((None, None)) => RadioEmulator::new(&name, model)?,
                    Some((air, ground)) => RadioEmulator::with_sik(&name, model, air, ground)?,
                });
                let spec = parts.attenuator.unwrap_or_else(|| cfg.spec());
                // The pads and the unit's setting make the path; before the first setting
                // the path is at the unit's start value.
                let fixed = plan.fixed_db;
                emulator.set_attenuation(fixed + spec.start_db)?;
                let path = emulator.clone();
                let unit = EmulatedMiniCircuits::start(
                    spec,
                    Box::new(move |db| {
                        if let Err(e) = path.set_attenuation(fixed + db) {
                            tracing::error!("emulated attenuator: {e:#}");
                        }
                    }),
                )
                .context("cannot start the emulated attenuator")?;
                let attenuator = MiniCircuits::connect(&Options {
                    host: unit.addr().ip().to_string(),
                    port: Some(unit.addr().port()),
                    transport: Transport::Telnet,
                    timeout: cfg.timeout(),
                    settle: cfg.settle(),
                    range_step: None,
                })?;
                Ok(RfPath {
                    air_port: emulator.air_path(),
                    ground_port: emulator.ground_path(),
                    baud: PTY_BAUD,
                    attenuator: Box::new(attenuator),
                    emulator: Some(emulator),
                    sik: None,
                    _unit: Some(unit),
                })
            }
            (
                RadioPath::SerialPair {
                    air_port,
                    ground_port,
                    baud,
                },
                AttenuatorConfig::Minicircuits(cfg),
            ) => {
                let options = cfg.options()?;
                let attenuator = MiniCircuits::connect(&options)?;
                Ok(RfPath {
                    air_port: air_port.display().to_string(),
                    ground_port: ground_port.display().to_string(),
                    baud: *baud,
                    attenuator: Box::new(attenuator),
                    emulator: None,
                    sik: None,
                    _unit: None,
                })
            }
            // The rig file's check refuses the mixed pairs.
            _ => anyhow::bail!(
                "an emulated attenuator goes with the emulated radio, a real one with real radios"
            ),
        }
    }
}

/// Reads both SiK radios through the ground radio's port (the drone's over the air, `RT`) and
/// checks that they agree on every setting a link needs: a pair the rig cannot read, or whose
/// ends disagree, is an error naming the port, not a sweep of a link that was never set up.
fn read_sik(ground_port: &str, baud: u32) -> Result<SikRecord> {
    let mut client = SikClient::open(ground_port, baud)?;
    let record = client
        .read_both()
        .with_context(|| format!("reading the SiK radios through {ground_port}"))?;
    check_match(&record)?;
    tracing::info!(
        port = ground_port,
        local = %record.local.banner,
        remote = %record.remote.banner,
        "SiK radios read and matched"
    );
    Ok(record)
}
