//! Running → identified: before a phase drives MultiRX, the device's boot
//! line must name the image and configuration the rig file does. A board
//! flashed by hand (or not flashed by this run, `flash = false`) or a stale
//! `multirx-emu` would otherwise be tested, and certified, in place of the
//! build the run claims.
//!
//! What is expected comes from the rig file's config for the mode (its
//! [`Config::identity_hash`]) and this rig's own `multirx-core` (the build id
//! formula, [`build_id`], over the core version, the image kind and that
//! hash): the same function the firmware's build script and the emulated
//! device use, so a mismatch means a different config or a different core.

use std::path::Path;
use std::time::Duration;

use multirx_core::BootReport;
use multirx_core::Config;
use multirx_core::boot::{CORE_VERSION, ImageKind, build_id};

/// How long after the device is up the rig waits for its boot line. The
/// firmware and the emulated device repeat it every second.
pub const BOOT_LINE_TIMEOUT: Duration = Duration::from_millis(2500);

/// The identity a device must report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Expected {
    pub kind: ImageKind,
    pub build_id: u64,
    pub config_hash: u64,
}

impl Expected {
    pub fn new(kind: ImageKind, config: &Config) -> Self {
        let config_hash = config.identity_hash();
        Expected {
            kind,
            build_id: build_id(kind, config_hash),
            config_hash,
        }
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
        "MultiRX runs another image than the rig file names: device reports build {:016x} config {:016x} (reset {}), rig expects build {:016x} config {:016x} ({} image of multirx-core {CORE_VERSION}, config {config}){}{}",
        seen.build_id,
        seen.config_hash,
        seen.reset.name(),
        expected.build_id,
        expected.config_hash,
        expected.kind.as_str(),
        if seen.config_hash != expected.config_hash { "; config differs" } else { "" },
        if seen.build_id != expected.build_id { "; build differs" } else { "" }
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
        let expected = Expected::new(ImageKind::Samd21, &Config::new(Mode::Scan, 3));
        let seen = boot(&expected);
        assert_eq!(
            check(Some(seen), &expected, Path::new("scan.toml")),
            Ok(seen)
        );
    }

    #[test]
    fn a_stale_build_with_the_right_config_fails_naming_both_builds() {
        let expected = Expected::new(ImageKind::Samd21, &Config::new(Mode::Scan, 3));
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
    }

    #[test]
    fn the_emulated_image_is_not_the_board_image() {
        let config = Config::new(Mode::Parallel, 2);
        let board = Expected::new(ImageKind::Samd21, &config);
        let emulated = Expected::new(ImageKind::Emulated, &config);
        assert!(check(Some(boot(&emulated)), &board, Path::new("p.toml")).is_err());
    }

    #[test]
    fn silence_is_a_failure_not_a_pass() {
        let expected = Expected::new(ImageKind::Emulated, &Config::new(Mode::Parallel, 2));
        let err = check(None, &expected, Path::new("p.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("no boot line") && err.contains("p.toml"),
            "{err}"
        );
    }
}
