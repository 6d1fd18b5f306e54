//! Flashes a MultiRX board through a debug probe with probe-rs, used as a
//! library so a bench needs no separate tool install. Every write is read
//! back (`DownloadOptions::verify`; the default does not), and an image that
//! would land in the region a UF2 bootloader's BOOTPROT fuse protects is
//! refused before anything is erased, with what to do instead.
//!
//! probe-rs is the `flash` feature (on by default): the emulated rig and CI need no probe
//! and skip its build (a third of the rig's compile time); a rig built without it says so
//! when asked to flash.

use std::path::Path;
use std::time::Duration;

use anyhow::{Context, Result, bail};

use crate::multirx::rigfile::ProbeSelector;

#[cfg(feature = "flash")]
mod session;

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
    /// Writes `elf` to the chip, reads it back and restarts the chip.
    #[cfg(feature = "flash")]
    pub fn flash(&self, elf: &Path) -> Result<Flashed> {
        session::flash(self, elf)
    }

    /// Built without probe-rs: says so, and how to get it.
    #[cfg(not(feature = "flash"))]
    pub fn flash(&self, elf: &Path) -> Result<Flashed> {
        bail!(
            "cannot flash {}: this rig was built without its `flash` feature (probe-rs); \
             build it with default features: cargo build --release -p harness",
            elf.display()
        )
    }
}

/// The SAMD21's NVM user row; BOOTPROT is bits 2:0 of its first word.
#[cfg(feature = "flash")]
const SAMD21_USER_ROW: u64 = 0x0080_4000;

/// Bytes at the start of flash that BOOTPROT protects from erase and write
/// (SAM D21 datasheet, NVMCTRL, "Boot loader size"): 0b111 none, then 512 B
/// doubling down to 0b000 = 32 KiB. UF2 bootloaders set 8 KiB (0b010).
pub fn bootprot_protected_bytes(user_row_word0: u32) -> u32 {
    match user_row_word0 & 0b111 {
        0b111 => 0,
        n => 512 << (6 - n),
    }
}

/// Refuses an image that starts inside the BOOTPROT region, naming both and
/// the two ways out, rather than letting the flash algorithm fail with a
/// bare NVM lock error halfway through.
pub fn check_bootprot(elf: &Path, lowest: u64, user_row_word0: u32) -> Result<()> {
    let protected = bootprot_protected_bytes(user_row_word0);
    if lowest < u64::from(protected) {
        bail!(
            "{} starts at {lowest:#x}, inside the first {} KiB that the chip's BOOTPROT fuse protects \
             (user row BOOTPROT = {:#05b}: a UF2 bootloader is installed). Build the bootloader layout \
             (cargo build --release --features uf2, application at 0x2000), or to replace the bootloader \
             clear BOOTPROT (user row bits 2:0 = 0b111) first",
            elf.display(),
            protected / 1024,
            user_row_word0 & 0b111
        );
    }
    Ok(())
}

/// The lowest address an ELF image writes: its loadable segments' physical
/// (load) addresses, where `.data`'s initial values sit in flash too.
pub fn lowest_load_address(elf: &Path) -> Result<u64> {
    use object::elf::PT_LOAD;
    use object::read::elf::{ElfFile32, ProgramHeader};
    let data = std::fs::read(elf).with_context(|| format!("cannot read {}", elf.display()))?;
    let lowest = match ElfFile32::<object::Endianness>::parse(&*data) {
        Ok(file) => {
            let endian = file.endian();
            file.elf_program_headers()
                .iter()
                .filter(|h| h.p_type(endian) == PT_LOAD && h.p_filesz(endian) > 0)
                .map(|h| u64::from(h.p_paddr(endian)))
                .min()
        }
        Err(_) => {
            use object::{Object, ObjectSegment};
            let file = object::File::parse(&*data)
                .with_context(|| format!("{} is not an ELF file", elf.display()))?;
            file.segments()
                .filter(|s| s.file_range().1 > 0)
                .map(|s| s.address())
                .min()
        }
    };
    lowest.with_context(|| format!("{} has nothing to flash", elf.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bootprot_sizes_follow_the_datasheet_table() {
        let sizes: Vec<u32> = (0..8).map(bootprot_protected_bytes).collect();
        assert_eq!(
            sizes,
            [32768, 16384, 8192, 4096, 2048, 1024, 512, 0],
            "BOOTPROT 0b000..0b111"
        );
        // Only bits 2:0 count; the rest of the word is other fuses.
        assert_eq!(bootprot_protected_bytes(0xd8e0_c7fa), 8192);
    }

    #[test]
    fn a_bare_image_over_a_uf2_bootloader_is_refused_naming_the_way_out() {
        let elf = Path::new("multirx-samd21");
        let err = check_bootprot(elf, 0x0, 0xffff_fffa)
            .unwrap_err()
            .to_string();
        for part in [
            "starts at 0x0",
            "first 8 KiB",
            "BOOTPROT = 0b010",
            "--features uf2",
            "0b111",
        ] {
            assert!(err.contains(part), "{part:?} missing: {err}");
        }
        // The uf2 layout (0x2000) fits behind it; no bootloader, anything goes.
        check_bootprot(elf, 0x2000, 0xffff_fffa).unwrap();
        check_bootprot(elf, 0x0, 0xffff_ffff).unwrap();
    }

    #[test]
    fn lowest_load_address_of_the_firmware_layouts() {
        // Any ELF with loadable data will do here; the firmware's own layouts
        // are checked in ci/build-firmware.sh.
        let exe = std::env::current_exe().unwrap();
        assert!(lowest_load_address(&exe).is_ok());
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("x");
        std::fs::write(&bad, b"nope").unwrap();
        assert!(lowest_load_address(&bad).is_err());
    }
}
