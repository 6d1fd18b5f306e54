//! Flashes a MultiRX board through a debug probe with probe-rs, used as a
//! library so a bench needs no separate tool install. Every write is read
//! back (`DownloadOptions::verify`; the default does not), and an image that
//! would land in the region a UF2 bootloader's BOOTPROT fuse protects is
//! refused before anything is erased, with what to do instead. Before that, the
//! chip's device id (DSU DID) must name an ATSAMD21G18A: probe-rs attaches to
//! any SAMD21 as the rig file's chip, and an E-package or a smaller part would
//! take the G18A image (pins it lacks, flash or RAM it lacks). Every probe step
//! runs under a time limit ([`run_steps`]), so a wedged probe or SWD line is an
//! error naming the probe and the step, never a rig that hangs.
//!
//! probe-rs is the `flash` feature (on by default): the emulated rig and CI need no probe
//! and skip its build (a third of the rig's compile time); a rig built without it says so
//! when asked to flash.

use std::path::Path;
use std::sync::mpsc;
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

    /// Resets the chip as a panic does (a system reset request: `PM.RCAUSE` reads SYST, the
    /// boot line `software`); returns the probe's name.
    #[cfg(feature = "flash")]
    pub fn reset(&self) -> Result<String> {
        session::reset(self)
    }

    /// Built without probe-rs: says so, and how to get it.
    #[cfg(not(feature = "flash"))]
    pub fn reset(&self) -> Result<String> {
        bail!(
            "cannot reset the board through probe {}: this rig was built without its `flash` \
             feature (probe-rs); build it with default features: cargo build --release -p harness",
            self.selector
        )
    }
}

/// A chip or probe that cannot be flashed safely.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FlashError {
    /// The chip's DSU DID names another part than the ATSAMD21G18A the image is built for.
    #[error(
        "probe {probe}: the chip's device id (DSU DID at {SAMD21_DSU_DID:#010x}) reads {did:#010x}, {found}; \
         the firmware is built for the ATSAMD21G18A only (DID processor 1, family 0, series 1, \
         device select {SAMD21G18A_DEVSEL:#04x}): refusing to flash"
    )]
    WrongChip {
        probe: String,
        did: u32,
        /// What the id decodes to, in words.
        found: String,
    },
    /// A probe step did not finish within its time limit.
    #[error(
        "probe {probe}: {step} did not finish within {limit:?} (probe or SWD wiring wedged? unplug and \
         replug the probe, check the board's power)"
    )]
    Timeout {
        probe: String,
        step: String,
        limit: Duration,
    },
    /// The thread driving the probe ended without a result (it panicked).
    #[error("probe {probe}: the probe thread ended during {step} without a result")]
    Lost { probe: String, step: String },
}

/// The SAMD21's Device Service Unit's device identification register (datasheet, DSU, DID).
pub const SAMD21_DSU_DID: u64 = 0x4100_2018;
/// DID.DEVSEL of the ATSAMD21G18A (datasheet, DSU, "Device selection").
pub const SAMD21G18A_DEVSEL: u8 = 0x05;

/// The fields of a SAMD DSU DID register.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceId {
    /// Bits 31:28; 1 = Cortex-M0+.
    pub processor: u8,
    /// Bits 27:23; 0 = SAM D.
    pub family: u8,
    /// Bits 21:16; 1 = SAMD21.
    pub series: u8,
    /// Bits 15:12.
    pub die: u8,
    /// Bits 11:8; 0 = A, 1 = B, ...
    pub revision: u8,
    /// Bits 7:0: which part of the series.
    pub devsel: u8,
}

impl DeviceId {
    pub fn decode(did: u32) -> DeviceId {
        DeviceId {
            processor: (did >> 28) as u8,
            family: ((did >> 23) & 0x1f) as u8,
            series: ((did >> 16) & 0x3f) as u8,
            die: ((did >> 12) & 0xf) as u8,
            revision: ((did >> 8) & 0xf) as u8,
            devsel: did as u8,
        }
    }

    /// The part's name if it is a SAMD21 (datasheet, DSU, "Device selection"; the A
    /// parts), else what the fields say.
    pub fn describe(&self) -> String {
        const SAMD21: [(u8, &str); 12] = [
            (0x00, "ATSAMD21J18A"),
            (0x01, "ATSAMD21J17A"),
            (0x02, "ATSAMD21J16A"),
            (0x03, "ATSAMD21J15A"),
            (0x05, "ATSAMD21G18A"),
            (0x06, "ATSAMD21G17A"),
            (0x07, "ATSAMD21G16A"),
            (0x08, "ATSAMD21G15A"),
            (0x0a, "ATSAMD21E18A"),
            (0x0b, "ATSAMD21E17A"),
            (0x0c, "ATSAMD21E16A"),
            (0x0d, "ATSAMD21E15A"),
        ];
        let rev = char::from(b'A' + self.revision.min(25));
        if self.is_samd21() {
            match SAMD21.iter().find(|(d, _)| *d == self.devsel) {
                Some((_, name)) => format!("an {name} (revision {rev})"),
                None => format!(
                    "a SAMD21 with device select {:#04x} (revision {rev})",
                    self.devsel
                ),
            }
        } else {
            format!(
                "not a SAMD21 (processor {}, family {}, series {}, device select {:#04x})",
                self.processor, self.family, self.series, self.devsel
            )
        }
    }

    fn is_samd21(&self) -> bool {
        self.processor == 1 && self.family == 0 && self.series == 1
    }
}

/// Accepts `did` only if it names an ATSAMD21G18A (any die or revision); `probe`
/// names the probe in the error.
pub fn check_device_id(probe: &str, did: u32) -> Result<DeviceId, FlashError> {
    let id = DeviceId::decode(did);
    if id.is_samd21() && id.devsel == SAMD21G18A_DEVSEL {
        Ok(id)
    } else {
        Err(FlashError::WrongChip {
            probe: probe.to_owned(),
            did,
            found: id.describe(),
        })
    }
}

/// Time limits of the probe steps: generous next to what a healthy probe takes (attach and
/// register reads well under a second, a 32 KiB image written and read back in seconds), so
/// that only a wedged probe or line reaches them.
pub mod limits {
    use std::time::Duration;
    /// Listing, opening and attaching the probe.
    pub const ATTACH: Duration = Duration::from_secs(20);
    /// Reading one register or word.
    pub const READ: Duration = Duration::from_secs(5);
    /// Erasing, writing and reading back the image.
    pub const DOWNLOAD: Duration = Duration::from_secs(180);
    /// Restarting the chip.
    pub const RESET: Duration = Duration::from_secs(5);
}

/// What the probe thread tells [`run_steps`]: each step as it begins (its name and
/// limit), the probe's name once known.
#[derive(Debug)]
pub struct Steps {
    tx: mpsc::Sender<StepMsg>,
}

#[derive(Debug)]
enum StepMsg {
    Step(String, Duration),
    Probe(String),
}

impl Steps {
    /// A step begins and must end (the next step begins, or the work returns) within `limit`.
    pub fn step(&self, what: &str, limit: Duration) {
        let _ = self.tx.send(StepMsg::Step(what.to_owned(), limit));
    }

    /// The probe's own name, for the messages from now on.
    pub fn probe(&self, name: &str) {
        let _ = self.tx.send(StepMsg::Probe(name.to_owned()));
    }
}

/// Runs `work` (probe calls, which block without a timeout of their own) on its own
/// thread and returns its result, or [`FlashError::Timeout`] naming the probe and the
/// step if a step outlives its limit. A timed-out thread is left blocked in the probe
/// driver (it cannot be cancelled); the rig reports and ends rather than hang.
pub fn run_steps<T: Send + 'static>(
    probe: &str,
    work: impl FnOnce(&Steps) -> Result<T> + Send + 'static,
) -> Result<T> {
    let (tx, rx) = mpsc::channel();
    let (done_tx, done_rx) = mpsc::channel();
    let steps = Steps { tx };
    std::thread::Builder::new()
        .name("probe".into())
        .spawn(move || {
            let result = work(&steps);
            let _ = done_tx.send(result);
            drop(steps);
        })
        .context("cannot start the probe thread")?;
    let mut probe = probe.to_owned();
    let mut step = ("starting".to_owned(), limits::ATTACH);
    let mut deadline = std::time::Instant::now() + step.1;
    loop {
        while let Ok(msg) = rx.try_recv() {
            match msg {
                StepMsg::Step(what, limit) => {
                    step = (what, limit);
                    deadline = std::time::Instant::now() + limit;
                }
                StepMsg::Probe(name) => probe = name,
            }
        }
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        if left.is_zero() {
            return Err(FlashError::Timeout {
                probe,
                step: step.0,
                limit: step.1,
            }
            .into());
        }
        // Short waits, to see a new step's limit soon after it begins.
        match done_rx.recv_timeout(left.min(Duration::from_millis(20))) {
            Ok(result) => return result,
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                return Err(FlashError::Lost {
                    probe,
                    step: step.0,
                }
                .into());
            }
        }
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
    fn only_a_samd21g18a_passes_the_device_id_check() {
        // An Arduino Zero's SAMD21G18A, revision D.
        let id = check_device_id("J-Link 123", 0x1001_0305).unwrap();
        assert_eq!((id.series, id.revision, id.devsel), (1, 3, 0x05));
        // Another die or revision of the same part.
        check_device_id("p", 0x1001_1005).unwrap();
        for (did, part) in [
            (0x1001_030a, "ATSAMD21E18A"),
            (0x1001_0306, "ATSAMD21G17A"),
            (0x1001_0300, "ATSAMD21J18A"),
            (0x1000_0305, "not a SAMD21"),
            (0x6006_0305, "not a SAMD21"),
            (0x0000_0000, "not a SAMD21"),
            (0xffff_ffff, "not a SAMD21"),
        ] {
            let err = check_device_id("J-Link 123", did).unwrap_err().to_string();
            for part in [part, "J-Link 123", &format!("{did:#010x}"), "0x41002018"] {
                assert!(err.contains(part), "{part:?} missing: {err}");
            }
        }
    }

    #[test]
    fn a_probe_step_that_never_returns_is_a_timeout_naming_the_probe() {
        let started = std::time::Instant::now();
        let err = run_steps::<()>("ST-Link V2 (0483:3748)", |steps| {
            steps.step("opening", Duration::from_secs(5));
            steps.probe("stub probe 42");
            steps.step("reading the device id", Duration::from_millis(100));
            loop {
                std::thread::park();
            }
        })
        .unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("stub probe 42") && text.contains("reading the device id"),
            "{text}"
        );
        assert!(
            matches!(err.downcast_ref(), Some(FlashError::Timeout { .. })),
            "{err:?}"
        );
        assert!(
            started.elapsed() < Duration::from_secs(3),
            "{:?}",
            started.elapsed()
        );
    }

    #[test]
    fn probe_steps_within_their_limits_return_the_result() {
        let got = run_steps("p", |steps| {
            for _ in 0..3 {
                steps.step("a short step", Duration::from_millis(200));
                std::thread::sleep(Duration::from_millis(50));
            }
            Ok(7)
        })
        .unwrap();
        assert_eq!(got, 7);
        let err = run_steps::<()>("p", |_| bail!("attach failed")).unwrap_err();
        assert_eq!(err.to_string(), "attach failed");
        let err = run_steps::<()>("p", |_| panic!("boom")).unwrap_err();
        assert!(err.to_string().contains("ended during"), "{err}");
    }

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
