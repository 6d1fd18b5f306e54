//! `.tlog` files as MAVProxy writes them: each frame preceded by its receive time as an
//! 8-byte big-endian count of microseconds since the Unix epoch. QGroundControl and
//! MAVProxy (`mavlogdump.py`) read them.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

/// A `.tlog` writer.
#[derive(Debug)]
pub struct Tlog {
    out: BufWriter<File>,
}

impl Tlog {
    /// Creates (truncates) `path`.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        Ok(Self {
            out: BufWriter::new(File::create(path)?),
        })
    }

    /// Appends one frame stamped with the wall clock.
    pub fn record(&mut self, frame: &[u8]) -> std::io::Result<()> {
        let micros = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as u64);
        self.record_at(micros, frame)
    }

    /// Appends one frame with a given timestamp.
    pub fn record_at(&mut self, unix_micros: u64, frame: &[u8]) -> std::io::Result<()> {
        self.out.write_all(&unix_micros.to_be_bytes())?;
        self.out.write_all(frame)
    }

    /// Flushes buffered frames to the file.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_is_big_endian_timestamp_then_frame() {
        let path = std::env::temp_dir().join(format!("mavlora-tlog-{}.tlog", std::process::id()));
        let mut t = Tlog::create(&path).unwrap();
        t.record_at(0x0102_0304_0506_0708, &[0xFD, 0x00]).unwrap();
        t.flush().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(bytes, [1, 2, 3, 4, 5, 6, 7, 8, 0xFD, 0x00]);
    }
}
