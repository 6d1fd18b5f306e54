//! Brings up a MavLora link for one real-time scenario, on the real clock:
//!
//! ```text
//! FC fixture (pty) ─ mavlora-bridge ─ RadioEmulator ─ mavlora-router ─UDP─ GCS fixture
//!   mavlora_fc.py                      side A │ side B                      mavlora_gcs.py
//! ```
//!
//! The ground station is `mavlora_gcs.py` on its plan, or MAVSDK itself ([`Ground::Mavsdk`],
//! `mavsdk_gcs.py`, behind the router only), which speaks the same event lines.
//!
//! [`Variant::Transparent`] is the paper's "no companion computer" case: the
//! flight controller's serial port straight on the drone radio and the ground
//! station straight on the ground radio's serial port. No router either: the
//! router is half of MavLora (it thins ground heartbeats and drops premature
//! mission retransmissions), so keeping it would not be the naive link.
//!
//! The GCS fixture runs a plan ([`GcsPlan`]: telemetry window, commands,
//! mission) and exits; its JSON event lines are read as they come (by the
//! fixture driver, [`crate::driver::fixture`]), and each carries the radio's
//! counters at the moment it was read, so a rate taken from the radio and one
//! taken from the GCS cover the same window.
//! [`MavloraSession::finish`] stops everything with SIGTERM, checks each
//! program exited with status 0 and collects the fixtures' summaries, the
//! radio's per-direction [`LinkStats`] and what the bridge and router last reported in
//! their status files ([`ProgramStatus`]). Every program's stderr is kept as a log in the output folder.

mod chain;
mod options;
mod report;

use std::path::PathBuf;
use std::time::Duration;

use crate::driver::fixture::FixtureError;
use crate::driver::program::ProgramMissing;
pub use crate::driver::radio_emulator::End;
pub(crate) use chain::Bridged;
pub use chain::{GcsLine, MavloraSession, Program, RadioCounters};
pub use options::{
    FcProfile, GcsPlan, Ground, MavsdkPlan, RadioPath, SessionDefaults, SessionOptions, Variant,
    sik_with_independent_loss, sik_with_loss,
};
pub use report::{ExitRecord, GCS_PHASE_FAILED, LinkNotice, ProgramStatus, SessionReport};

/// Why a session could not be brought up or finished.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// A program (bridge, router) is not where the options say.
    #[error(transparent)]
    ProgramMissing(#[from] ProgramMissing),
    /// A fixture did not print its `ready` line.
    #[error("{name} did not start within {timeout:?} (pymavlink and pyserial installed?): {reason}; see {}", log.display())]
    FixtureStart {
        name: String,
        timeout: Duration,
        log: PathBuf,
        /// What the fixture driver saw instead.
        reason: String,
    },
    /// Telemetry did not reach the ground station.
    #[error("no telemetry at the ground station within {timeout:?}; see the logs in {}", dir.display())]
    NoTelemetry { timeout: Duration, dir: PathBuf },
    /// The ground station did not finish its plan in time.
    #[error("the GCS fixture did not finish within {timeout:?}; see {}", log.display())]
    GcsTimeout { timeout: Duration, log: PathBuf },
    /// A fixture's output was not what its events say, or ended early.
    #[error(transparent)]
    Fixture(#[from] FixtureError),
    /// The radio setup does not make a radio.
    #[error("radio setup: {0}")]
    Radio(#[from] harness_radio::ConfigError),
    /// Starting or talking to a program failed (the message names it).
    #[error(transparent)]
    Driver(#[from] anyhow::Error),
    /// Files in the output folder.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

type Result<T> = std::result::Result<T, SessionError>;

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use harness_radio::RadioSetup;

    fn options(dir: &Path) -> SessionOptions {
        let repo = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let defaults = SessionDefaults {
            python: PathBuf::from("python3"),
            fixtures_dir: repo.join("fixtures"),
            bridge_program: PathBuf::from("/bin/true"),
            router_program: PathBuf::from("/bin/true"),
            profile_dir: repo.join("firmware/mavlora/profiles"),
            lossy_radio: sik_with_loss(0.1, 2.0).unwrap(),
            clean_radio: RadioSetup::builtin("sik-64k").unwrap(),
            c2_radio: sik_with_independent_loss(0.1).unwrap(),
            soak_s: 600.0,
        };
        defaults.options("t", &defaults.clean_radio, dir)
    }

    #[test]
    fn a_missing_program_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let mut o = options(dir.path());
        o.bridge_program = dir.path().join("no-such-bridge");
        let err = MavloraSession::start(o).err().unwrap();
        assert!(matches!(err, SessionError::ProgramMissing(_)), "{err}");
        assert!(err.to_string().contains("no-such-bridge"), "{err}");
    }

    #[test]
    fn a_fixture_that_does_not_start_names_its_log() {
        let dir = tempfile::tempdir().unwrap();
        let mut o = options(dir.path());
        o.fixtures_dir = dir.path().join("no-fixtures");
        let err = MavloraSession::start(o).err().unwrap();
        assert!(matches!(err, SessionError::FixtureStart { .. }), "{err}");
        assert!(err.to_string().contains("fc.log"), "{err}");
        let log = std::fs::read_to_string(dir.path().join("fc.log")).unwrap();
        assert!(log.contains("mavlora_fc.py"), "{log}");
    }

    #[test]
    fn gcs_budget_covers_every_retry_of_every_command() {
        let plan = GcsPlan {
            listen_s: 2.0,
            commands: 10,
            ..GcsPlan::default()
        };
        // 10 × (0.5 + 1.5 × 5) + 2 + 10 margin
        assert_eq!(plan.budget(), Duration::from_secs(92));
    }

    #[test]
    fn lossy_sik_has_the_asked_mean_loss_both_ways() {
        let s = sik_with_loss(0.1, 250.0).unwrap();
        for ge in [&s.uplink.burst, &s.downlink.burst] {
            let ge = ge.as_ref().unwrap();
            let mean = ge.p_good_to_bad / (ge.p_good_to_bad + ge.p_bad_to_good);
            assert!((mean - 0.1).abs() < 1e-9, "{ge:?}");
        }
        assert_ne!(s.uplink.seed, s.downlink.seed);
    }
}
