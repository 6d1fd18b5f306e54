//! Signing key files: any bytes either give a key (exactly 64 hex digits, optionally one line
//! end) that prints back as the same hex, or are refused with an error; never a panic.

use mavlora::signing::SigningKey;

pub fn run(data: &[u8]) {
    match SigningKey::parse(data) {
        Ok(key) => {
            let hex = key.to_hex();
            assert_eq!(hex.len(), 64);
            assert!(
                data[..64].eq_ignore_ascii_case(hex.as_bytes()),
                "key is not the file's hex"
            );
            assert!(
                SigningKey::parse(hex.as_bytes()).ok() == Some(key),
                "hex does not round-trip"
            );
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
}
