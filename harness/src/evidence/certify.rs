//! `rig certify`: build → (flash, on board rigs, by the run) → the suite → the evidence folder.

use std::path::PathBuf;

use anyhow::Result;

use super::build::{BuildOptions, repo_root};
use crate::rigfile::{DeviceSetup, RigFile};

/// Build options for a rig file: one firmware image per mode config it names.
pub fn build_options(
    rig: Option<&RigFile>,
    out_dir: PathBuf,
    target_dir: PathBuf,
    host: bool,
) -> Result<BuildOptions> {
    let cwd = std::env::current_dir()?;
    let repo = repo_root(&cwd)?;
    // A board rig's images carry its mode configs; an emulated rig's configs are for the host
    // program (6 receivers and an IFS do not fit the board's UARTs): the crate's default then.
    let firmware_configs = rig
        .and_then(|r| r.multirx.as_ref())
        .filter(|m| matches!(m.device.setup, DeviceSetup::Board(_)))
        .map(|m| {
            m.device
                .configs
                .iter()
                .map(|(mode, loaded)| (mode.to_string(), loaded.path.clone()))
                .collect()
        })
        .unwrap_or_default();
    Ok(BuildOptions {
        out_dir: cwd.join(out_dir),
        target_dir: cwd.join(target_dir),
        repo,
        firmware_configs,
        host,
    })
}
