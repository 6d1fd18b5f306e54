//! Who a MultiRX device is, said on its status line once it has started: the
//! image's build id, the hash of the configuration compiled into it, why it
//! last reset and how long after start its first SBUS frame left. The rig
//! compares the first two with what its rig file names before any phase (a
//! board flashed by hand, or not at all, must still run the image and config
//! the run claims); the last two are what a bench looks at after a brown-out.
//!
//! Line format (after the usual `<micros>`, the time the line was written):
//! ```text
//! <micros> boot build <16 hex> config <16 hex> reset <cause> first-frame-us <n>
//! ```
//!
//! Both ids are FNV-1a 64 (a fixed, published function, so the firmware's
//! build script, the emulated device and the rig compute the same number
//! without sharing a hasher implementation): the config hash over the
//! configuration's canonical text ([`Config::write_rust_literal`], the form
//! compiled into the firmware), the build id over the core's version, the
//! image kind, the config hash and the image's source ([`source_id`]: the git
//! commit and a hash of the input files, computed by
//! `provenance::Source` with feature `std`). Without the source, an image
//! built from older firmware code with the same core version and config
//! would pass the rig's identity check.

use core::fmt;

use crate::config::Config;
use crate::time::{Duration, Instant};

/// This crate's version, part of every build id.
pub const CORE_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Which program a build id belongs to: the same core and config built for
/// the board and for the host are different images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ImageKind {
    /// The SAMD21 firmware (`firmware/multirx/samd21`).
    Samd21,
    /// The emulated device (`multirx-emu`).
    Emulated,
}

impl ImageKind {
    pub const fn as_str(self) -> &'static str {
        match self {
            ImageKind::Samd21 => "samd21",
            ImageKind::Emulated => "emulated",
        }
    }
}

/// FNV-1a, 64 bits (<http://www.isthe.com/chongo/tech/comp/fnv/>): not a
/// cryptographic hash; it names an image, it does not authenticate one.
#[derive(Debug, Clone, Copy)]
pub struct Fnv1a64(u64);

impl Fnv1a64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;

    pub const fn new() -> Self {
        Fnv1a64(Self::OFFSET)
    }

    pub const fn bytes(mut self, bytes: &[u8]) -> Self {
        let mut i = 0;
        while i < bytes.len() {
            self.0 = (self.0 ^ bytes[i] as u64).wrapping_mul(Self::PRIME);
            i += 1;
        }
        self
    }

    pub const fn finish(self) -> u64 {
        self.0
    }
}

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self::new()
    }
}

impl fmt::Write for Fnv1a64 {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        *self = self.bytes(s.as_bytes());
        Ok(())
    }
}

impl Config {
    /// FNV-1a 64 of this configuration's canonical text: equal for two
    /// files that parse to the same configuration (comments, order and
    /// defaults spelled out or not make no difference).
    pub fn identity_hash(&self) -> u64 {
        let mut hasher = Fnv1a64::new();
        // Writing into a hasher cannot fail.
        let _ = self.write_rust_literal(&mut hasher);
        hasher.finish()
    }
}

/// The source part of a build id: the commit (`unknown` outside a git tree)
/// and the hash of the image's input files.
pub const fn source_id(commit: &[u8], inputs_hash: u64) -> u64 {
    Fnv1a64::new()
        .bytes(b"source ")
        .bytes(commit)
        .bytes(b"\0")
        .bytes(&inputs_hash.to_le_bytes())
        .finish()
}

/// The build id of `kind` built from this core with a config hashing to
/// `config_hash`, from the source [`source_id`] names.
pub const fn build_id(kind: ImageKind, config_hash: u64, source_id: u64) -> u64 {
    Fnv1a64::new()
        .bytes(b"multirx-core ")
        .bytes(CORE_VERSION.as_bytes())
        .bytes(b"\0")
        .bytes(kind.as_str().as_bytes())
        .bytes(b"\0")
        .bytes(&config_hash.to_le_bytes())
        .bytes(&source_id.to_le_bytes())
        .finish()
}

/// Why the device last started.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ResetCause {
    /// Power was applied (power-on reset).
    PowerOn,
    /// The 3.3 V rail sagged below the BOD33 level.
    BrownOut,
    /// The core's 1.2 V regulator sagged (BOD12).
    BrownOutCore,
    /// The reset pin.
    External,
    /// The watchdog was not fed in time.
    Watchdog,
    /// A software reset: a panic (`panic-reset`) or a debugger.
    Software,
    /// A host process started (the emulated device).
    Host,
    /// No cause bit set (should not happen).
    Unknown,
}

impl ResetCause {
    pub const ALL: [ResetCause; 8] = [
        ResetCause::PowerOn,
        ResetCause::BrownOut,
        ResetCause::BrownOutCore,
        ResetCause::External,
        ResetCause::Watchdog,
        ResetCause::Software,
        ResetCause::Host,
        ResetCause::Unknown,
    ];

    pub const fn name(self) -> &'static str {
        match self {
            ResetCause::PowerOn => "power-on",
            ResetCause::BrownOut => "brown-out",
            ResetCause::BrownOutCore => "brown-out-core",
            ResetCause::External => "external",
            ResetCause::Watchdog => "watchdog",
            ResetCause::Software => "software",
            ResetCause::Host => "host",
            ResetCause::Unknown => "unknown",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == name)
    }

    /// The SAMD21's `PM.RCAUSE` register: one bit per cause (POR 0, BOD12 1,
    /// BOD33 2, EXT 4, WDT 5, SYST 6; datasheet §16.8.14). A power-on may set
    /// the brown-out bits as the rail rises, so power-on wins over them; the
    /// others are exclusive.
    pub const fn from_samd21_rcause(bits: u8) -> Self {
        if bits & 1 << 0 != 0 {
            ResetCause::PowerOn
        } else if bits & 1 << 2 != 0 {
            ResetCause::BrownOut
        } else if bits & 1 << 1 != 0 {
            ResetCause::BrownOutCore
        } else if bits & 1 << 5 != 0 {
            ResetCause::Watchdog
        } else if bits & 1 << 6 != 0 {
            ResetCause::Software
        } else if bits & 1 << 4 != 0 {
            ResetCause::External
        } else {
            ResetCause::Unknown
        }
    }
}

/// How long a tap of the reset button leaves the UF2 bootloader reachable.
///
/// The Arduino/Adafruit UF2 bootloader waits 500 ms for a second tap after
/// every reset but a power-on, unless the application left its quick-boot
/// value in the last RAM word; the firmware behind it writes that value so a
/// watchdog, panic or brown-out reset restarts the frames at once. Written
/// at every start, it would also make every tap of the button a quick boot,
/// and the bootloader's drive could never be opened. So after a reset-pin
/// reset (a person at the bench) the firmware writes it only this long after
/// start: three taps within it open the drive (the first starts the firmware
/// at once, the second finds no quick-boot value, the third lands in the
/// bootloader's 500 ms wait).
pub const UF2_TAP_WINDOW: Duration = Duration::from_millis(1000);

/// How long after start the firmware behind a UF2 bootloader waits before it
/// writes the quick-boot value, by the cause of this start: at once, except
/// after a reset-pin reset ([`UF2_TAP_WINDOW`]).
pub const fn uf2_quick_boot_after(cause: ResetCause) -> Duration {
    match cause {
        ResetCause::External => UF2_TAP_WINDOW,
        _ => Duration::ZERO,
    }
}

/// The boot line: what the device is and how its start went.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BootReport {
    /// When the line was written (the device's clock, as every status line).
    pub at: Instant,
    /// [`build_id`] of the running image.
    pub build_id: u64,
    /// [`Config::identity_hash`] of the configuration it runs.
    pub config_hash: u64,
    pub reset: ResetCause,
    /// From the device's clock start to its first SBUS frame to the flight
    /// controller (queued for its UART; the frame's start bit follows within
    /// a loop pass).
    ///
    /// On the SAMD21 the clock is the 1 MHz timer, started at the end of the
    /// board's set-up, so the figure leaves out what comes before it, about
    /// 0.5 ms by estimate from the datasheet (not measured): the reset
    /// handler's RAM initialisation at the 1 MHz reset clock (56 µs with
    /// 24 bytes of `.bss`; computed from the image and bounded at 500 µs by
    /// `ci/check-firmware-elf.py`), the watchdog's two register
    /// synchronisations at 32,768 Hz (at most 2 × 186 µs), and the GCLK,
    /// BOD33, DFLL and SERCOM set-up (each synchronisation at most 6 periods
    /// of its clock: tens of µs). Also left out: the supply's rise and the
    /// chip's power-on start-up before its reset handler runs. The emulated
    /// device counts from its process start.
    pub first_frame: Duration,
}

impl fmt::Display for BootReport {
    /// One status line, without its newline.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} boot build {:016x} config {:016x} reset {} first-frame-us {}",
            self.at.as_micros(),
            self.build_id,
            self.config_hash,
            self.reset.name(),
            self.first_frame.as_micros()
        )
    }
}

/// A line that is not a boot line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "not a MultiRX boot line (expected `<micros> boot build <hex> config <hex> reset <cause> first-frame-us <n>`)"
)]
pub struct BootLineError;

impl BootReport {
    /// Parses one boot line (surrounding whitespace ignored).
    pub fn parse_line(line: &str) -> Result<BootReport, BootLineError> {
        let mut words = line.split_ascii_whitespace();
        let mut next = || words.next().ok_or(BootLineError);
        let at = next()?.parse().map_err(|_| BootLineError)?;
        let mut keyword = |name: &str| match next() {
            Ok(w) if w == name => Ok(()),
            _ => Err(BootLineError),
        };
        keyword("boot")?;
        keyword("build")?;
        let mut next = || words.next().ok_or(BootLineError);
        let build_id = hex64(next()?)?;
        (next()? == "config").then_some(()).ok_or(BootLineError)?;
        let config_hash = hex64(next()?)?;
        (next()? == "reset").then_some(()).ok_or(BootLineError)?;
        let reset = ResetCause::from_name(next()?).ok_or(BootLineError)?;
        (next()? == "first-frame-us")
            .then_some(())
            .ok_or(BootLineError)?;
        let first = next()?.parse().map_err(|_| BootLineError)?;
        if next().is_ok() {
            return Err(BootLineError);
        }
        Ok(BootReport {
            at: Instant::from_micros(at),
            build_id,
            config_hash,
            reset,
            first_frame: Duration::from_micros(first),
        })
    }
}

/// Exactly 16 hex digits, as written.
fn hex64(word: &str) -> Result<u64, BootLineError> {
    if word.len() != 16 {
        return Err(BootLineError);
    }
    u64::from_str_radix(word, 16).map_err(|_| BootLineError)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Mode;

    fn report() -> BootReport {
        BootReport {
            at: Instant::from_micros(12_345),
            build_id: 0x0123_4567_89ab_cdef,
            config_hash: 0xfedc_ba98_7654_3210,
            reset: ResetCause::BrownOut,
            first_frame: Duration::from_micros(9_876),
        }
    }

    #[test]
    fn boot_lines_round_trip() {
        for reset in ResetCause::ALL {
            let r = BootReport { reset, ..report() };
            let line = r.to_string();
            assert_eq!(BootReport::parse_line(&line), Ok(r), "{line}");
        }
        assert_eq!(
            report().to_string(),
            "12345 boot build 0123456789abcdef config fedcba9876543210 reset brown-out first-frame-us 9876"
        );
    }

    #[test]
    fn garbage_boot_lines_are_refused() {
        let good = report().to_string();
        for line in [
            "",
            "12 boot",
            "12 power 1 on",
            &good.replace("0123456789abcdef", "123456789abcdef"),
            &good.replace("0123456789abcdef", "0123456789abcdeg"),
            &good.replace("brown-out", "brownout"),
            &good.replace(" config", " cfg"),
            &format!("{good} extra"),
            &good.replace("9876", "-1"),
        ] {
            assert_eq!(BootReport::parse_line(line), Err(BootLineError), "{line}");
        }
    }

    #[test]
    fn fnv1a_matches_the_published_test_vectors() {
        // From the FNV reference test suite (test_fnv.c, FNV1a_64).
        assert_eq!(Fnv1a64::new().finish(), 0xcbf29ce484222325);
        assert_eq!(Fnv1a64::new().bytes(b"a").finish(), 0xaf63dc4c8601ec8c);
        assert_eq!(Fnv1a64::new().bytes(b"foobar").finish(), 0x85944171f73967e8);
    }

    #[test]
    fn config_hash_follows_the_configuration_not_its_spelling() {
        let a = Config::new(Mode::Parallel, 2);
        let mut b = a.clone();
        assert_eq!(a.identity_hash(), b.identity_hash());
        b.acquire_frames += 1;
        assert_ne!(a.identity_hash(), b.identity_hash());
        assert_ne!(
            Config::new(Mode::Scan, 2).identity_hash(),
            a.identity_hash()
        );
    }

    #[test]
    fn build_id_names_the_image_kind_the_config_and_the_source() {
        let h = Config::new(Mode::Parallel, 2).identity_hash();
        let s = source_id(b"unknown", 1);
        assert_ne!(
            build_id(ImageKind::Samd21, h, s),
            build_id(ImageKind::Emulated, h, s)
        );
        assert_ne!(
            build_id(ImageKind::Samd21, h, s),
            build_id(ImageKind::Samd21, h ^ 1, s)
        );
        assert_ne!(
            build_id(ImageKind::Samd21, h, s),
            build_id(ImageKind::Samd21, h, source_id(b"unknown", 2))
        );
        assert_ne!(s, source_id(b"0123abc", 1));
    }

    #[test]
    fn only_a_reset_pin_start_delays_the_uf2_quick_boot() {
        for cause in ResetCause::ALL {
            let after = uf2_quick_boot_after(cause);
            if cause == ResetCause::External {
                // Longer than the bootloader's own 500 ms tap wait, so a person can tap thrice.
                assert!(after > Duration::from_millis(500), "{after:?}");
            } else {
                // Watchdog, panic, brown-out: the next reset must not wait 500 ms.
                assert_eq!(after, Duration::ZERO, "{cause:?}");
            }
        }
    }

    #[test]
    fn rcause_bits_name_the_cause() {
        assert_eq!(ResetCause::from_samd21_rcause(0x01), ResetCause::PowerOn);
        // A power-on also sets the brown-out bits while the rail rises.
        assert_eq!(ResetCause::from_samd21_rcause(0x07), ResetCause::PowerOn);
        assert_eq!(ResetCause::from_samd21_rcause(0x04), ResetCause::BrownOut);
        assert_eq!(
            ResetCause::from_samd21_rcause(0x02),
            ResetCause::BrownOutCore
        );
        assert_eq!(ResetCause::from_samd21_rcause(0x10), ResetCause::External);
        assert_eq!(ResetCause::from_samd21_rcause(0x20), ResetCause::Watchdog);
        assert_eq!(ResetCause::from_samd21_rcause(0x40), ResetCause::Software);
        assert_eq!(ResetCause::from_samd21_rcause(0x00), ResetCause::Unknown);
    }
}
