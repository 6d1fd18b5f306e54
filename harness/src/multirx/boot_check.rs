//! Running → identified: before a phase drives MultiRX, the device's boot
//! line must name the image and configuration the rig file does. A board
//! flashed by hand (or not flashed by this run, `flash = false`) or a stale
//! `multirx-emu` would otherwise be tested, and certified, in place of the
//! build the run claims.
//!
//! What is expected comes from the rig file's config for the mode (its
//! [`Config::identity_hash`]), this rig's own `multirx-core` (the build id
//! formula, [`build_id`], over the core version, the image kind, that hash
//! and the source) and the source: for a board, the commit and input files of
//! the firmware crate the rig file names, hashed now
//! ([`multirx_core::provenance`], the function the firmware's build script
//! uses), so a board still running an image of older firmware code fails;
//! for the emulated device, its input files as this rig's build script
//! hashed them when the rig was built (the same cargo build builds
//! `multirx-emu`), so a stale `multirx-emu` fails. A mismatch means a
//! different config or source.

use std::path::Path;
use std::time::Duration;

use multirx_core::BootReport;
use multirx_core::Config;
use multirx_core::boot::{CORE_VERSION, ImageKind, build_id};
use multirx_core::provenance::{SAMD21_INPUTS, Source};

/// The source id of the `multirx-emu` built with this rig, hashed by `build.rs`.
const EMULATOR_SOURCE_ID: &str = env!("MULTIRX_EMULATOR_SOURCE_ID");

/// How long after the device is up the rig waits for its boot line. The
/// firmware and the emulated device repeat it every second.
pub const BOOT_LINE_TIMEOUT: Duration = Duration::from_millis(2500);

/// The identity a device must report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Expected {
    pub kind: ImageKind,
    pub build_id: u64,
    pub config_hash: u64,
    /// Where the expected image is built from, for messages: `commit <c>, inputs <hash>`.
    pub source: String,
}

impl Expected {
    /// `kind` with `config`, built from the source `source_id` names.
    pub fn new(kind: ImageKind, config: &Config, source_id: u64, source: String) -> Self {
        let config_hash = config.identity_hash();
        Expected {
            kind,
            build_id: build_id(kind, config_hash, source_id),
            config_hash,
            source,
        }
    }

    /// The `multirx-emu` built with this rig, running `config`.
    pub fn emulated(config: &Config) -> Self {
        let source_id =
            u64::from_str_radix(EMULATOR_SOURCE_ID, 16).expect("build.rs writes 16 hex digits");
        Expected::new(
            ImageKind::Emulated,
            config,
            source_id,
            format!("source {EMULATOR_SOURCE_ID} as this rig was built"),
        )
    }

    /// The image the firmware crate at `firmware` builds with the config file at
    /// `config_path` (parsed: `config`), from the tree as it is now.
    pub fn board(config: &Config, firmware: &Path, config_path: &Path) -> std::io::Result<Self> {
        let source = Source::of(firmware, SAMD21_INPUTS, Some(config_path))?;
        Ok(Expected::new(
            ImageKind::Samd21,
            config,
            source.id(),
            format!(
                "commit {}, inputs {:016x} of {}",
                source.commit,
                source.inputs,
                firmware.display()
            ),
        ))
    }
}

/// A device that does not run what the rig file names.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BootCheckError {
    /// No boot line within [`BOOT_LINE_TIMEOUT`].
    #[error(
        "MultiRX sent no boot line on its status port within {timeout:?}: cannot tell which image it runs (expected build {:016x}, config {:016x} from {config})",
        expected.build_id,
        expected.config_hash
    )]
    NoBootLine {
        expected: Expected,
        config: String,
        timeout: Duration,
    },
    /// The boot line names another image or configuration.
    #[error(
        "MultiRX runs another image than the rig file names: device reports build {:016x} config {:016x} (reset {}), rig expects build {:016x} config {:016x} ({} image of multirx-core {CORE_VERSION}, {}, config {config}){}{}",
        seen.build_id,
        seen.config_hash,
        seen.reset.name(),
        expected.build_id,
        expected.config_hash,
        expected.kind.as_str(),
        expected.source,
        if seen.config_hash != expected.config_hash { "; config differs" } else { "" },
        if seen.build_id != expected.build_id {
            match expected.kind {
                ImageKind::Samd21 => "; build differs (an image of other source or config: flash this tree's, flash = true or `rig flash`)",
                ImageKind::Emulated => "; build differs (a multirx-emu of other source: build it with this rig)",
            }
        } else { "" }
    )]
    Mismatch {
        seen: BootReport,
        expected: Expected,
        config: String,
    },
}

/// Checks `seen` (the device's boot line, if any) against `expected`;
/// `config` is the rig's config file, named in the error.
pub fn check(
    seen: Option<BootReport>,
    expected: &Expected,
    config: &Path,
) -> Result<BootReport, BootCheckError> {
    let config = config.display().to_string();
    let Some(seen) = seen else {
        return Err(BootCheckError::NoBootLine {
            expected: expected.clone(),
            config,
            timeout: BOOT_LINE_TIMEOUT,
        });
    };
    if seen.build_id == expected.build_id && seen.config_hash == expected.config_hash {
        Ok(seen)
    } else {
        Err(BootCheckError::Mismatch {
            seen,
            expected: expected.clone(),
            config,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use multirx_core::boot::ResetCause;
    use multirx_core::{Instant, Mode};

    fn boot(expected: &Expected) -> BootReport {
        BootReport {
            at: Instant::from_micros(30_000),
            build_id: expected.build_id,
            config_hash: expected.config_hash,
            reset: ResetCause::PowerOn,
            first_frame: multirx_core::Duration::from_micros(29_000),
        }
    }

    #[test]
    fn a_matching_boot_line_passes() {
        let expected = Expected::new(
            ImageKind::Samd21,
            &Config::new(Mode::Scan, 3),
            1,
            "commit abc".into(),
        );
        let seen = boot(&expected);
        assert_eq!(
            check(Some(seen), &expected, Path::new("scan.toml")),
            Ok(seen)
        );
    }

    #[test]
    fn a_stale_build_with_the_right_config_fails_naming_both_builds() {
        let expected = Expected::new(
            ImageKind::Samd21,
            &Config::new(Mode::Scan, 3),
            1,
            "commit abc".into(),
        );
        let seen = BootReport {
            build_id: 0x1111_2222_3333_4444,
            ..boot(&expected)
        };
        let err = check(Some(seen), &expected, Path::new("scan.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("device reports build 1111222233334444"),
            "{err}"
        );
        assert!(
            err.contains(&format!("rig expects build {:016x}", expected.build_id)),
            "{err}"
        );
        assert!(
            err.contains("build differs") && !err.contains("config differs"),
            "{err}"
        );
        assert!(
            err.contains("scan.toml") && err.contains("reset power-on"),
            "{err}"
        );
        assert!(err.contains("commit abc") && err.contains("flash"), "{err}");
    }

    #[test]
    fn a_board_image_of_older_firmware_source_fails_the_check() {
        // A copy of the firmware's inputs; the boot line of an image built from it.
        let dir = tempfile::tempdir().unwrap();
        let firmware = dir.path().join("firmware/multirx/samd21");
        std::fs::create_dir_all(firmware.join("src")).unwrap();
        std::fs::create_dir_all(dir.path().join("firmware/multirx/core/src")).unwrap();
        std::fs::write(firmware.join("src/main.rs"), "fn main() {}\n").unwrap();
        std::fs::write(dir.path().join("firmware/multirx/core/src/lib.rs"), "\n").unwrap();
        let config_path = dir.path().join("scan.toml");
        std::fs::write(&config_path, "mode = \"scan\"\n").unwrap();
        let config = Config::new(Mode::Scan, 3);
        let built = Expected::board(&config, &firmware, &config_path).unwrap();
        let flashed = boot(&built);
        assert!(check(Some(flashed), &built, &config_path).is_ok());
        assert!(built.source.contains("commit unknown"), "{}", built.source);

        // The core changes after the board was flashed; config and core version do not.
        std::fs::write(
            dir.path().join("firmware/multirx/core/src/lib.rs"),
            "// fixed\n",
        )
        .unwrap();
        let now = Expected::board(&config, &firmware, &config_path).unwrap();
        assert_eq!(now.config_hash, built.config_hash);
        let err = check(Some(flashed), &now, &config_path)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("build differs") && !err.contains("config differs"),
            "{err}"
        );
    }

    #[test]
    fn the_emulated_image_is_not_the_board_image() {
        let config = Config::new(Mode::Parallel, 2);
        let board = Expected::new(ImageKind::Samd21, &config, 1, String::new());
        let emulated = Expected::new(ImageKind::Emulated, &config, 1, String::new());
        assert!(check(Some(boot(&emulated)), &board, Path::new("p.toml")).is_err());
    }

    #[test]
    fn silence_is_a_failure_not_a_pass() {
        let expected = Expected::emulated(&Config::new(Mode::Parallel, 2));
        let err = check(None, &expected, Path::new("p.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("no boot line") && err.contains("p.toml"),
            "{err}"
        );
    }
}
