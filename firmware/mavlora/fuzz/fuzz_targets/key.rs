//! Signing key files: any bytes either give a key, and then the same key whatever trailing
//! whitespace follows, or are refused; never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mavlora::signing::SigningKey;

fuzz_target!(|data: &[u8]| {
    if let Some(key) = SigningKey::parse(data) {
        let mut padded = data.to_vec();
        padded.extend_from_slice(b"\n");
        if let Some(again) = SigningKey::parse(&padded) {
            assert_eq!(again, key, "a trailing newline changed the key");
        }
    }
});
