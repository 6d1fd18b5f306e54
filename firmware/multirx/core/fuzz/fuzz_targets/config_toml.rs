//! cargo-fuzz target `config_toml`: the body (its invariants, in `../bodies/config_toml.rs`) also runs on
//! stable in `cargo test` (`tests/fuzz_corpus.rs`: corpus replay and mutations).
#![no_main]

#[path = "../bodies/config_toml.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
