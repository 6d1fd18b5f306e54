//! `[radios]`: the emulated radios a rig offers, by name, each checked against the radio
//! model at load. Device sections refer to them by name (or to a built-in preset).

use std::collections::BTreeMap;

use harness_radio::{Preset, RadioSetup};

use super::{Checker, RigFileError};

impl Checker<'_> {
    /// Checks `[radios]`: every preset resolves and every direction's settings are accepted
    /// by the model, so a bad radio fails at load, not mid-run.
    pub(crate) fn radios(
        &self,
        raw: BTreeMap<String, RadioSetup>,
    ) -> Result<BTreeMap<String, RadioSetup>, RigFileError> {
        for (name, setup) in &raw {
            if Preset::builtin(name).is_some() {
                return Err(self.invalid(
                    &["radios", name],
                    format!(
                        "\"{name}\" is a built-in preset's name; give this radio another name so \
                         the loss-free built-in stays reachable"
                    ),
                ));
            }
            setup
                .radio()
                .map_err(|e| self.invalid(&["radios", name], e.to_string()))?;
        }
        Ok(raw)
    }
}
