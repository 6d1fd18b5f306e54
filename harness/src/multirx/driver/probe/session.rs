//! The probe-rs session behind [`ProbeDriver::flash`] and [`ProbeDriver::reset`]: find and
//! open the probe, attach, check the device id and BOOTPROT, download with read-back,
//! restart; each step under its time limit ([`run_steps`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use probe_rs::flashing::{DownloadOptions, ElfLoader, ElfOptions};
use probe_rs::probe::DebugProbeSelector;
use probe_rs::probe::list::Lister;
use probe_rs::{MemoryInterface, Permissions};

use super::{
    Flashed, ProbeDriver, SAMD21_DSU_DID, SAMD21_USER_ROW, Steps, check_bootprot, check_device_id,
    limits, lowest_load_address, run_steps,
};
use crate::multirx::rigfile::ProbeSelector;

/// See [`ProbeDriver::flash`].
pub(super) fn flash(driver: &ProbeDriver, elf: &Path) -> Result<Flashed> {
    let selector = driver.selector.clone();
    let chip = driver.chip.clone();
    let elf: PathBuf = elf.to_path_buf();
    let label = format!("{}", driver.selector);
    run_steps(&label, move |steps| {
        flash_steps(steps, &selector, &chip, &elf)
    })
}

/// See [`ProbeDriver::reset`].
pub(super) fn reset(driver: &ProbeDriver) -> Result<String> {
    let selector = driver.selector.clone();
    let chip = driver.chip.clone();
    let label = format!("{}", driver.selector);
    run_steps(&label, move |steps| {
        let (mut session, name) = attach(steps, &selector, &chip)?;
        steps.step("resetting the chip", limits::RESET);
        session
            .core(0)
            .and_then(|mut core| core.reset())
            .with_context(|| format!("probe {name}: cannot reset the chip"))?;
        Ok(name)
    })
}

/// Finds and opens the probe, and attaches to `chip`; returns the session and the probe's
/// name for messages.
fn attach(
    steps: &Steps,
    selector: &ProbeSelector,
    chip: &str,
) -> Result<(probe_rs::Session, String)> {
    steps.step("listing and opening the probe", limits::ATTACH);
    let lister = Lister::new();
    let probes = lister.list_all();
    let probe = match selector {
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
    let name = format!("{} ({selector})", probe.get_name());
    steps.probe(&name);
    steps.step(&format!("attaching to {chip}"), limits::ATTACH);
    let session = probe
        .attach(chip, Permissions::default())
        .with_context(|| format!("probe {name} cannot attach to {chip}"))?;
    Ok((session, name))
}

fn flash_steps(steps: &Steps, selector: &ProbeSelector, chip: &str, elf: &Path) -> Result<Flashed> {
    let started = Instant::now();
    let (mut session, name) = attach(steps, selector, chip)?;
    steps.step("reading the device id (DSU DID)", limits::READ);
    let did = session
        .core(0)
        .and_then(|mut core| core.read_word_32(SAMD21_DSU_DID))
        .with_context(|| format!("probe {name}: cannot read the chip's device id"))?;
    let id = check_device_id(&name, did)?;
    tracing::info!(probe = %name, did = format!("{did:#010x}"), chip = %id.describe(), "chip identified");
    steps.step("reading the NVM user row (BOOTPROT)", limits::READ);
    let user_row = session
        .core(0)
        .and_then(|mut core| core.read_word_32(SAMD21_USER_ROW))
        .with_context(|| format!("probe {name}: cannot read the chip's NVM user row (BOOTPROT)"))?;
    check_bootprot(elf, lowest_load_address(elf)?, user_row)?;
    steps.step(
        &format!("writing and verifying {}", elf.display()),
        limits::DOWNLOAD,
    );
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
            "flashing {} through {name} failed (written and read back: a verify error means the flash does not hold the image)",
            elf.display()
        )
    })?;
    steps.step("restarting the chip", limits::RESET);
    session
        .core(0)
        .and_then(|mut core| core.reset())
        .with_context(|| format!("probe {name}: cannot restart the chip after flashing"))?;
    Ok(Flashed {
        probe: name,
        duration: started.elapsed(),
    })
}
