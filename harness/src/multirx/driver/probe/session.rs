//! The probe-rs session behind [`ProbeDriver::flash`]: find and open the probe, attach,
//! check BOOTPROT, download with read-back, restart.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use probe_rs::flashing::{DownloadOptions, ElfLoader, ElfOptions};
use probe_rs::probe::DebugProbeSelector;
use probe_rs::probe::list::Lister;
use probe_rs::{MemoryInterface, Permissions};

use super::{Flashed, ProbeDriver, SAMD21_USER_ROW, check_bootprot, lowest_load_address};
use crate::multirx::rigfile::ProbeSelector;

/// See [`ProbeDriver::flash`].
pub(super) fn flash(driver: &ProbeDriver, elf: &Path) -> Result<Flashed> {
    let started = Instant::now();
    let lister = Lister::new();
    let probes = lister.list_all();
    let probe = match &driver.selector {
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
                    .map(|p| format!("{:04x}:{:04x} {}", p.vendor_id, p.product_id, p.identifier))
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
        .attach(driver.chip.as_str(), Permissions::default())
        .with_context(|| format!("probe {name} cannot attach to {}", driver.chip))?;
    let user_row = session
        .core(0)
        .and_then(|mut core| core.read_word_32(SAMD21_USER_ROW))
        .context("cannot read the chip's NVM user row (BOOTPROT)")?;
    check_bootprot(elf, lowest_load_address(elf)?, user_row)?;
    let mut options = DownloadOptions::default();
    options.verify = true;
    probe_rs::flashing::download_file_with_options(
        &mut session,
        elf,
        ElfLoader(ElfOptions::default()),
        options,
    )
    .with_context(|| {
        format!(
            "flashing {} failed (written and read back: a verify error means the flash does not hold the image)",
            elf.display()
        )
    })?;
    session
        .core(0)
        .and_then(|mut core| core.reset())
        .context("cannot restart the chip after flashing")?;
    Ok(Flashed {
        probe: name,
        duration: started.elapsed(),
    })
}
