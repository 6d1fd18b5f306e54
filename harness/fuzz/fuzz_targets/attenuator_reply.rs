//! cargo-fuzz target `attenuator_reply`: the body (its invariants, in
//! `../bodies/attenuator_reply.rs`) also runs on stable in `cargo test`
//! (`tests/fuzz_corpus.rs`: corpus replay and mutations).
#![no_main]

#[path = "../bodies/attenuator_reply.rs"]
mod body;

libfuzzer_sys::fuzz_target!(|data: &[u8]| body::run(data));
