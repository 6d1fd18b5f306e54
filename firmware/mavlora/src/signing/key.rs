//! The shared secret and its file: 64 hexadecimal characters, an optional trailing newline,
//! nothing else, readable by its owner only (as OpenSSH treats private keys). A raw 32-byte
//! form is not accepted: a key file cut short or padded by an editor would otherwise still
//! load as some other key.

use std::path::Path;

/// A 32-byte MAVLink 2 signing key.
#[derive(Clone, PartialEq, Eq)]
pub struct SigningKey(pub [u8; 32]);

impl std::fmt::Debug for SigningKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // never print the secret
        f.write_str("SigningKey(..)")
    }
}

/// Why a key file could not be used. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum KeyError {
    /// The file could not be read.
    #[error("key file {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The IO error.
        source: std::io::Error,
    },
    /// Group or others have some access to the file: the secret is not kept to its owner.
    #[error(
        "key file {path} has mode {mode:04o}: group/others may access it; \
         `chmod 600 {path}` and keep it to the user running mavlora"
    )]
    Permissions {
        /// The file.
        path: String,
        /// Its permission bits.
        mode: u32,
    },
    /// Not 64 hexadecimal characters (with an optional trailing newline).
    #[error("key file {path}: {reason} (expected 64 hexadecimal characters, optionally a newline)")]
    Format {
        /// The file.
        path: String,
        /// What is wrong.
        reason: FormatError,
    },
}

/// What is wrong with a key file's contents.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FormatError {
    /// Too few or too many characters.
    #[error("{0} characters")]
    Length(usize),
    /// A character that is not a hexadecimal digit, at a 1-based column.
    #[error("{found:?} at column {column} is not a hexadecimal digit")]
    NotHex {
        /// 1-based position.
        column: usize,
        /// The character (byte) found.
        found: char,
    },
}

impl SigningKey {
    /// Reads a key file, refusing one that group or others may access.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, KeyError> {
        let path = path.as_ref();
        let shown = || path.display().to_string();
        let read = |source| KeyError::Read {
            path: shown(),
            source,
        };
        let meta = std::fs::metadata(path).map_err(read)?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            let mode = meta.permissions().mode() & 0o7777;
            if mode & 0o077 != 0 {
                return Err(KeyError::Permissions {
                    path: shown(),
                    mode,
                });
            }
        }
        #[cfg(not(unix))]
        let _ = meta;
        // A key is 65 bytes: a few more cannot be one, and a FIFO would hang start-up.
        let bytes = crate::input_file::read(path, 1024).map_err(read)?;
        Self::parse(&bytes).map_err(|reason| KeyError::Format {
            path: shown(),
            reason,
        })
    }

    /// A key from file contents: exactly 64 hexadecimal characters, then at most one `\n`
    /// (or `\r\n`).
    pub fn parse(bytes: &[u8]) -> Result<Self, FormatError> {
        let text = bytes
            .strip_suffix(b"\r\n")
            .or_else(|| bytes.strip_suffix(b"\n"))
            .unwrap_or(bytes);
        if let Some(column) = text.iter().position(|b| !b.is_ascii_hexdigit()) {
            return Err(FormatError::NotHex {
                column: column + 1,
                found: char::from(text[column]),
            });
        }
        if text.len() != 64 {
            return Err(FormatError::Length(text.len()));
        }
        let mut key = [0u8; 32];
        for (i, pair) in text.chunks(2).enumerate() {
            let digit = |b: u8| char::from(b).to_digit(16).unwrap_or(0) as u8;
            key[i] = digit(pair[0]) << 4 | digit(pair[1]);
        }
        Ok(Self(key))
    }

    /// The key as a key file holds it.
    pub fn to_hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEX: &str = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";

    fn want() -> SigningKey {
        SigningKey(core::array::from_fn(|i| i as u8))
    }

    #[test]
    fn hex_with_or_without_one_newline() {
        assert_eq!(SigningKey::parse(HEX.as_bytes()).unwrap(), want());
        assert_eq!(
            SigningKey::parse(format!("{HEX}\n").as_bytes()).unwrap(),
            want()
        );
        assert_eq!(
            SigningKey::parse(format!("{HEX}\r\n").as_bytes()).unwrap(),
            want()
        );
        assert_eq!(
            SigningKey::parse(HEX.to_uppercase().as_bytes()).unwrap(),
            want()
        );
        assert_eq!(want().to_hex(), HEX);
        assert_eq!(format!("{:?}", want()), "SigningKey(..)");
    }

    #[test]
    fn truncated_padded_raw_and_garbled_keys_are_refused() {
        assert_eq!(
            SigningKey::parse(&HEX.as_bytes()[..63]),
            Err(FormatError::Length(63))
        );
        assert_eq!(SigningKey::parse(b""), Err(FormatError::Length(0)));
        assert_eq!(
            SigningKey::parse(format!("{HEX}00").as_bytes()),
            Err(FormatError::Length(66))
        );
        // two newlines, a space inside, a line break inside
        assert!(SigningKey::parse(format!("{HEX}\n\n").as_bytes()).is_err());
        let spaced = format!("{} {}", &HEX[..32], &HEX[32..]);
        assert_eq!(
            SigningKey::parse(spaced.as_bytes()),
            Err(FormatError::NotHex {
                column: 33,
                found: ' '
            })
        );
        // a raw key: 32 bytes that are not hex digits
        assert!(SigningKey::parse(&[0x2a; 32]).is_err());
        assert!(SigningKey::parse(&[0xff; 32]).is_err());
    }

    #[cfg(unix)]
    #[test]
    fn key_file_others_can_read_is_refused_naming_file_and_mode() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = std::env::temp_dir().join(format!("mavlora-key-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("radio.key");
        std::fs::write(&path, HEX).unwrap();
        for mode in [0o644, 0o640, 0o604, 0o660] {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
            let err = SigningKey::load(&path).unwrap_err();
            assert!(matches!(err, KeyError::Permissions { mode: m, .. } if m == mode));
            let text = err.to_string();
            assert!(
                text.contains(&path.display().to_string()) && text.contains(&format!("{mode:04o}")),
                "{text}"
            );
        }
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(SigningKey::load(&path).unwrap(), want());
        std::fs::write(&path, &HEX[..40]).unwrap();
        let err = SigningKey::load(&path).unwrap_err().to_string();
        assert!(
            err.contains("radio.key") && err.contains("40 characters"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
