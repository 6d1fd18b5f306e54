//! cargo-fuzz target `profile`: the body (its invariants, in `../bodies/profile.rs`) also runs on
//! stable in `cargo test` (`tests/fuzz_corpus.rs`: corpus replay and mutations).
#![no_main]

#[path = "../bodies/profile.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
