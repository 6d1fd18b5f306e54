//! The RF path as resources: the two radios (the radio emulator, or two real radios' ports)
//! and the programmable attenuator between them, connected through its real driver in both
//! cases: in CI the attenuator is the emulated Mini-Circuits unit on 127.0.0.1, whose settings
//! step the radio emulator's path loss, so a bench differs from CI only in its rig file.

use std::sync::Arc;

use anyhow::{Context, Result};

use super::rigfile::{BenchPlan, RadioPath};
use crate::driver::attenuator::Attenuator;
use crate::driver::attenuator::config::AttenuatorConfig;
use crate::driver::attenuator::emulated::{EmulatedMiniCircuits, EmulatedSpec};
use crate::driver::attenuator::minicircuits::{MiniCircuits, Options, Transport};
use crate::driver::radio_emulator::RadioEmulator;

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
    /// The emulated attenuator unit, kept running while the path is.
    _unit: Option<EmulatedMiniCircuits>,
}

impl RfPath {
    /// Brings the path up as `plan` says; `hostile` makes an emulated attenuator misbehave
    /// (tests).
    pub fn open(plan: &BenchPlan, hostile: Option<EmulatedSpec>) -> Result<RfPath> {
        match (&plan.path, &plan.attenuator) {
            (RadioPath::Emulated(radio), AttenuatorConfig::Emulated(cfg)) => {
                let emulator = Arc::new(RadioEmulator::new(
                    &format!("bench-{}", radio.name),
                    radio
                        .setup
                        .radio()
                        .with_context(|| format!("radio \"{}\"", radio.name))?,
                )?);
                let spec = hostile.unwrap_or_else(|| cfg.spec());
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
