//! A probe on the emulated board's TX pin: when each frame for the flight
//! controller was handed to the port, as CLOCK_MONOTONIC seconds, and how long
//! the host had held the device clock so far (seconds), one line per frame:
//! `12.345678901 0.012345678`. A logic analyser gives the same on real hardware; the rig reads it to
//! judge the device's own cadence apart from the serial transport's latency.

use std::fs::File;
use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};

pub struct TxTap {
    file: Option<File>,
}

impl TxTap {
    pub fn create(path: &Path) -> Result<TxTap> {
        let file =
            File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        Ok(TxTap { file: Some(file) })
    }

    /// Notes a frame leaving at `sent` (CLOCK_MONOTONIC), `held` held so far.
    /// A write error stops the tap, never the device.
    pub fn frame_sent(&mut self, sent: std::time::Duration, held: std::time::Duration) {
        let Some(file) = &mut self.file else { return };
        // Unbuffered: the rig may read the file while the device runs.
        if let Err(e) = writeln!(
            file,
            "{}.{:09} {}.{:09}",
            sent.as_secs(),
            sent.subsec_nanos(),
            held.as_secs(),
            held.subsec_nanos()
        ) {
            tracing::warn!(error = %e, "TX tap stopped");
            self.file = None;
        }
    }
}
