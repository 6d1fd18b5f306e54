//! The shared secret.

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

/// Why a key file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum KeyError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The IO error.
        source: std::io::Error,
    },
    /// Neither 64 hex characters nor 32 raw bytes.
    #[error("{path}: expected 64 hexadecimal characters or 32 raw bytes")]
    Format {
        /// The file.
        path: String,
    },
}

impl SigningKey {
    /// Reads a key file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, KeyError> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|source| KeyError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&bytes).ok_or_else(|| KeyError::Format {
            path: path.display().to_string(),
        })
    }

    /// A key from file contents: 64 hex characters (whitespace ignored) or 32 raw bytes.
    pub fn parse(bytes: &[u8]) -> Option<Self> {
        let text: Vec<u8> = bytes
            .iter()
            .copied()
            .filter(|b| !b.is_ascii_whitespace())
            .collect();
        if text.len() == 64 && text.iter().all(u8::is_ascii_hexdigit) {
            let mut key = [0u8; 32];
            for (i, pair) in text.chunks(2).enumerate() {
                let s = std::str::from_utf8(pair).ok()?;
                key[i] = u8::from_str_radix(s, 16).ok()?;
            }
            return Some(Self(key));
        }
        <[u8; 32]>::try_from(bytes).ok().map(Self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_and_raw_forms() {
        let hex = "000102030405060708090a0b0c0d0e0f\n101112131415161718191a1b1c1d1e1f\n";
        let want: [u8; 32] = core::array::from_fn(|i| i as u8);
        assert_eq!(SigningKey::parse(hex.as_bytes()), Some(SigningKey(want)));
        assert_eq!(SigningKey::parse(&want), Some(SigningKey(want)));
        assert_eq!(SigningKey::parse(b"too short"), None);
        assert_eq!(format!("{:?}", SigningKey(want)), "SigningKey(..)");
    }
}
