//! Reading the small files an operator names (profile, config, key, signing state): regular
//! files only, and only up to a size, so a wrong path neither hangs start-up (a FIFO blocks
//! until someone writes to it) nor reads without end (`/dev/zero`: 1 GB in 0.6 s).

use std::io::{Error, ErrorKind, Read};
use std::path::Path;

/// The largest profile, config or key file read (each is a few kilobytes).
pub const MAX_TEXT_FILE: u64 = 1 << 20;

/// The file's bytes; an error of kind `InvalidInput` for something that is not a regular file
/// or is larger than `limit` bytes (a missing file keeps its `NotFound`).
pub fn read(path: &Path, limit: u64) -> Result<Vec<u8>, Error> {
    // Looked at before opening: opening a FIFO for reading blocks until a writer comes.
    if !std::fs::metadata(path)?.is_file() {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            "not a regular file (a FIFO, device or directory)",
        ));
    }
    let file = std::fs::File::open(path)?;
    // The path may have changed in between: the file opened is what counts.
    if !file.metadata()?.is_file() {
        return Err(Error::new(ErrorKind::InvalidInput, "not a regular file"));
    }
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            format!("larger than {limit} bytes"),
        ));
    }
    Ok(bytes)
}

/// As [`read`], as UTF-8 text.
pub fn read_to_string(path: &Path, limit: u64) -> Result<String, Error> {
    String::from_utf8(read(path, limit)?)
        .map_err(|e| Error::new(ErrorKind::InvalidData, format!("not UTF-8 text: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_device_a_directory_and_an_oversized_file_are_refused_a_small_file_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let small = dir.path().join("small.toml");
        std::fs::write(&small, "a = 1\n").unwrap();
        assert_eq!(read_to_string(&small, 100).unwrap(), "a = 1\n");
        let big = dir.path().join("big.toml");
        std::fs::write(&big, vec![b'#'; 101]).unwrap();
        assert!(
            read(&big, 100)
                .unwrap_err()
                .to_string()
                .contains("larger than 100")
        );
        for odd in [Path::new("/dev/zero"), dir.path()] {
            let e = read(odd, 100).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::InvalidInput, "{}", odd.display());
        }
        let missing = read(&dir.path().join("none"), 100).unwrap_err();
        assert_eq!(missing.kind(), ErrorKind::NotFound);
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_without_waiting_for_a_writer() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("key");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        let e = read(&fifo, 100).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::InvalidInput);
    }
}
