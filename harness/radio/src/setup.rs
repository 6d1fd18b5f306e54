//! A radio as a rig file names it: a preset (built in by name, or written out
//! in full) and one [`LinkConfig`] per direction. Uplink is ground → drone,
//! downlink drone → ground; the drone's radio is side A of the [`Radio`].
//!
//! ```toml
//! [radios.sik_lossy]
//! preset = "sik-64k"             # sik-64k, sik-64k-ecc, lora-sf7, dmd-dl1
//! uplink = { seed = 2, burst = { p_good_to_bad = 0.02, p_bad_to_good = 0.18 } }
//! downlink = { seed = 1, burst = { p_good_to_bad = 0.02, p_bad_to_good = 0.18 } }
//! ```

use serde::{Deserialize, Serialize};

use super::error::ConfigError;
use super::link::LinkConfig;
use super::pair::Radio;
use super::preset::Preset;

/// The preset of a [`RadioSetup`]: a built-in name or a full table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PresetSpec {
    Named(String),
    Custom(Box<Preset>),
}

impl PresetSpec {
    /// The preset this names.
    pub fn resolve(&self) -> Result<Preset, ConfigError> {
        match self {
            PresetSpec::Custom(p) => {
                p.validate()?;
                Ok((**p).clone())
            }
            PresetSpec::Named(name) => {
                Preset::builtin(name).ok_or_else(|| ConfigError::UnknownPreset {
                    name: name.clone(),
                    builtin: Preset::BUILTIN.join(", "),
                })
            }
        }
    }
}

/// One radio of a rig file, before it is turned into a [`Radio`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadioSetup {
    pub preset: PresetSpec,
    /// Ground → drone.
    #[serde(default)]
    pub uplink: LinkConfig,
    /// Drone → ground.
    #[serde(default)]
    pub downlink: LinkConfig,
}

impl RadioSetup {
    /// A built-in preset with both directions at their defaults (no loss).
    pub fn builtin(name: &str) -> Result<RadioSetup, ConfigError> {
        let spec = PresetSpec::Named(name.to_string());
        spec.resolve()?;
        Ok(RadioSetup {
            preset: spec,
            uplink: LinkConfig::default(),
            downlink: LinkConfig::default(),
        })
    }

    /// The two engines, side A = drone (its sends are the downlink).
    pub fn radio(&self) -> Result<Radio, ConfigError> {
        let preset = self.preset.resolve()?;
        Radio::new(&preset, &self.uplink, &self.downlink)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_preset_with_asymmetric_directions() {
        let setup: RadioSetup = toml::from_str(
            r#"
            preset = "sik-64k"
            uplink = { seed = 2, burst = { p_good_to_bad = 0.02, p_bad_to_good = 0.18 } }
            downlink = { seed = 1 }
            "#,
        )
        .unwrap();
        assert_eq!(setup.preset.resolve().unwrap(), Preset::sik_64k());
        assert!(setup.uplink.burst.is_some() && setup.downlink.burst.is_none());
        setup.radio().unwrap();
    }

    #[test]
    fn unknown_preset_names_the_built_in_ones() {
        let err = RadioSetup::builtin("sik-128k").unwrap_err().to_string();
        assert!(
            err.contains("\"sik-128k\"") && err.contains("lora-sf7"),
            "{err}"
        );
    }

    #[test]
    fn every_built_in_name_resolves() {
        for name in Preset::BUILTIN {
            let preset = RadioSetup::builtin(name).unwrap().preset.resolve().unwrap();
            assert_eq!(&preset.name, name);
        }
    }
}
