//! cargo-fuzz target `key`: the body (its invariants, in `../bodies/key.rs`) also runs on
//! stable in `cargo test` (`tests/fuzz_corpus.rs`: corpus replay and mutations).
#![no_main]

#[path = "../bodies/key.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
