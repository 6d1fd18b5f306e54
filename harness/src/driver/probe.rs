//! Flashes a MultiRX board through a debug probe with probe-rs, used as a
//! library so a bench needs no separate tool install.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use probe_rs::Permissions;
use probe_rs::flashing::{ElfLoader, ElfOptions};
use probe_rs::probe::DebugProbeSelector;
use probe_rs::probe::list::Lister;

use crate::rigfile::ProbeSelector;

/// What was flashed, for the run record.
#[derive(Debug, Clone)]
pub struct Flashed {
    /// The probe used, as probe-rs names it.
    pub probe: String,
    pub duration: Duration,
}

/// A debug probe attached to one chip.
pub struct ProbeDriver {
    pub selector: ProbeSelector,
    pub chip: String,
}

impl ProbeDriver {
    /// Writes `elf` to the chip and restarts it.
    pub fn flash(&self, elf: &Path) -> Result<Flashed> {
        let started = Instant::now();
        let lister = Lister::new();
        let probes = lister.list_all();
        let probe = match &self.selector {
            ProbeSelector::Auto => match probes.as_slice() {
                [] => bail!(
                    "no debug probe found (is it plugged in, and may this user open it? see udev rules for probe-rs)"
                ),
                [one] => one
                    .open()
                    .with_context(|| format!("cannot open probe {}", one.identifier))?,
                many => bail!(
                    "{} debug probes found ({}); name one in [multirx.device] probe = \"VID:PID[:SERIAL]\"",
                    many.len(),
                    many.iter()
                        .map(|p| format!(
                            "{:04x}:{:04x} {}",
                            p.vendor_id, p.product_id, p.identifier
                        ))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            },
            selector => {
                let wanted: DebugProbeSelector = selector
                    .to_string()
                    .parse()
                    .with_context(|| format!("probe selector {selector}"))?;
                lister.open(wanted).with_context(|| {
                    format!(
                        "cannot open debug probe {selector} ({} probes attached)",
                        probes.len()
                    )
                })?
            }
        };
        let name = probe.get_name();
        let mut session = probe
            .attach(self.chip.as_str(), Permissions::default())
            .with_context(|| format!("probe {name} cannot attach to {}", self.chip))?;
        probe_rs::flashing::download_file(&mut session, elf, ElfLoader(ElfOptions::default()))
            .with_context(|| format!("flashing {} failed", elf.display()))?;
        session
            .core(0)
            .and_then(|mut core| core.reset())
            .context("cannot restart the chip after flashing")?;
        Ok(Flashed {
            probe: name,
            duration: started.elapsed(),
        })
    }
}
