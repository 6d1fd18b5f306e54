//! Arbitrary text as a rig file: a located error or a rig file, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = harness::rigfile::RigFile::from_str(text, "/fuzz/rigs/fuzz.toml");
    }
});
