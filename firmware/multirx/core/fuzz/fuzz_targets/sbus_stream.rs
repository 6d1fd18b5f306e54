//! cargo-fuzz target `sbus_stream`: the body (its invariants, in `../bodies/sbus_stream.rs`) also runs on
//! stable in `cargo test` (`tests/fuzz_corpus.rs`: corpus replay and mutations).
#![no_main]

#[path = "../bodies/sbus_stream.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
