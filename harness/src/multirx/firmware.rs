//! Built → flashed: compiles the MultiRX firmware with a mode's config baked
//! in (as the paper did, but through the core's validation), checks the image
//! as CI does (`ci/check-firmware-elf.py`: no panic reachable from the UART
//! interrupts, a stack bound that fits, the reset handler's RAM
//! initialisation within what the boot line's `first-frame-us` may leave
//! out) and flashes it. An image CI would refuse is never flashed.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};
use object::{Object, ObjectSection, SectionFlags, SectionKind};

use super::rigfile::{BoardSetup, DeviceSetup, MultirxSection};
use crate::evidence::build::FirmwareCrate;
use crate::multirx::driver::probe::{Flashed, ProbeDriver};
use crate::record::sha256_file;

/// The SAMD21 firmware crate, built with a mode's config compiled in.
pub const CRATE: FirmwareCrate = FirmwareCrate {
    dir: "firmware/multirx/samd21",
    bin: "multirx-samd21",
    target: "thumbv6m-none-eabi",
    default_config: "multirx.toml",
    config_env: "MULTIRX_CONFIG",
    check: |repo, elf| check_elf(&repo.join(CHECKER), elf).map(drop),
};

/// The configs a reproducible build compiles into firmware images, labelled by mode. A board
/// rig's images carry its mode configs; an emulated rig's configs are for the host program
/// (6 receivers and an IFS do not fit the board's UARTs): none, so the crate's default.
pub fn build_configs(section: &MultirxSection) -> Vec<(String, PathBuf)> {
    if !matches!(section.device.setup, DeviceSetup::Board(_)) {
        return Vec::new();
    }
    section
        .device
        .configs
        .iter()
        .map(|(mode, loaded)| (mode.to_string(), loaded.path.clone()))
        .collect()
}

/// A firmware image built for one config.
#[derive(Debug, Clone)]
pub struct FirmwareImage {
    pub elf: PathBuf,
    pub sha256: String,
    /// Bytes the image takes in flash (allocated, loaded sections).
    pub flash_bytes: u64,
    /// Bytes of static RAM (.data and .bss); the stack takes the rest.
    pub ram_bytes: u64,
}

/// Builds the firmware crate at `firmware` with `config` compiled in.
pub fn build(firmware: &Path, config: &Path) -> Result<FirmwareImage> {
    let target_dir = firmware.join("target");
    let status = Command::new("cargo")
        .args(["build", "--release", "--locked", "--quiet"])
        .arg("--target-dir")
        .arg(&target_dir)
        .current_dir(firmware)
        .env("MULTIRX_CONFIG", config)
        .status()
        .with_context(|| format!("cannot run cargo in {}", firmware.display()))?;
    if !status.success() {
        bail!(
            "building the firmware in {} with MULTIRX_CONFIG={} failed ({status})",
            firmware.display(),
            config.display()
        );
    }
    let elf = target_dir.join("thumbv6m-none-eabi/release/multirx-samd21");
    let report = check_elf(&find_checker(firmware)?, &elf)?;
    tracing::info!(elf = %elf.display(), "{}", report.trim());
    let (flash_bytes, ram_bytes) = sizes(&elf)?;
    Ok(FirmwareImage {
        sha256: sha256_file(&elf)?,
        elf,
        flash_bytes,
        ram_bytes,
    })
}

/// The image checker, relative to the repository root.
pub const CHECKER: &str = "ci/check-firmware-elf.py";
/// The RAM the checker's stack bound must fit, as `ci/build-firmware.sh` passes it: the
/// ATSAMD21G18A's 32 KiB, less the static-data budget of 8 KiB.
const CHECKER_ARGS: [&str; 4] = ["--ram-bytes", "32768", "--ram-static", "8192"];

/// [`CHECKER`] in the repository holding the firmware crate at `firmware`.
pub fn find_checker(firmware: &Path) -> Result<PathBuf> {
    let start = firmware
        .canonicalize()
        .with_context(|| format!("cannot find the firmware crate {}", firmware.display()))?;
    start
        .ancestors()
        .map(|dir| dir.join(CHECKER))
        .find(|p| p.is_file())
        .with_context(|| {
            format!(
                "no {CHECKER} in any folder above {}: the image cannot be checked before flashing",
                start.display()
            )
        })
}

/// Runs `checker` on `elf` as CI does; its report on success, its own message as the
/// error otherwise.
pub fn check_elf(checker: &Path, elf: &Path) -> Result<String> {
    let out = Command::new("python3")
        .arg(checker)
        .arg(elf)
        .args(CHECKER_ARGS)
        .output()
        .with_context(|| format!("cannot run python3 {}", checker.display()))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        bail!(
            "{} refuses {} ({}): {}{}",
            checker.display(),
            elf.display(),
            out.status,
            stderr.trim(),
            if stdout.trim().is_empty() {
                String::new()
            } else {
                format!("\n{}", stdout.trim())
            }
        );
    }
    Ok(stdout.into_owned())
}

/// Flash and static-RAM use of an ELF image, from its section headers.
pub fn sizes(elf: &Path) -> Result<(u64, u64)> {
    let data = std::fs::read(elf).with_context(|| format!("cannot read {}", elf.display()))?;
    let file = object::File::parse(&*data)
        .with_context(|| format!("{} is not an ELF file", elf.display()))?;
    let (mut flash, mut ram) = (0, 0);
    for section in file.sections() {
        let SectionFlags::Elf { sh_flags } = section.flags() else {
            continue;
        };
        if sh_flags & u64::from(object::elf::SHF_ALLOC) == 0 {
            continue;
        }
        match section.kind() {
            SectionKind::UninitializedData => ram += section.size(),
            SectionKind::Data => {
                // Initialised data lives in flash and is copied to RAM at start.
                ram += section.size();
                flash += section.size();
            }
            _ => flash += section.size(),
        }
    }
    Ok((flash, ram))
}

/// Flashes `image` as the board's setup says.
pub fn flash(board: &BoardSetup, image: &FirmwareImage) -> Result<Flashed> {
    ProbeDriver {
        selector: board.probe.clone(),
        chip: board.chip.clone(),
    }
    .flash(&image.elf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_of_a_host_binary_are_plausible() {
        // Any ELF will do to check the section walk; the test binary itself is one.
        let exe = std::env::current_exe().unwrap();
        let (flash, ram) = sizes(&exe).unwrap();
        assert!(flash > 10_000, "{flash}");
        assert!(ram > 0 && ram < flash, "{ram}");
    }

    fn checker() -> PathBuf {
        find_checker(Path::new(env!("CARGO_MANIFEST_DIR"))).unwrap()
    }

    #[test]
    fn the_build_step_refuses_an_image_the_checker_refuses_with_its_message() {
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("multirx-samd21");
        std::fs::write(&bad, b"not an elf").unwrap();
        let err = check_elf(&checker(), &bad).unwrap_err().to_string();
        assert!(
            err.contains("check-firmware-elf.py refuses")
                && err.contains("not a little-endian ELF32 file")
                && err.contains(&bad.display().to_string()),
            "{err}"
        );
    }

    #[test]
    fn the_checker_is_found_from_the_firmware_crate() {
        let firmware = Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware/multirx/samd21");
        assert_eq!(
            find_checker(&firmware).unwrap(),
            checker(),
            "one checker for the rig and CI"
        );
        let dir = tempfile::tempdir().unwrap();
        let err = find_checker(dir.path()).unwrap_err().to_string();
        assert!(err.contains("no ci/check-firmware-elf.py"), "{err}");
    }

    #[test]
    fn not_an_elf_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.bin");
        std::fs::write(&path, b"not an elf").unwrap();
        let err = sizes(&path).unwrap_err().to_string();
        assert!(err.contains("is not an ELF file"), "{err}");
    }
}
