//! cargo-fuzz target `reader`: the body (its invariants, in `../bodies/reader.rs`) also runs on
//! stable in `cargo test` (`tests/fuzz_corpus.rs`: corpus replay and mutations).
#![no_main]

#[path = "../bodies/reader.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
