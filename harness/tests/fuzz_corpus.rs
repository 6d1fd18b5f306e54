//! The cargo-fuzz target's invariants on stable, in every `cargo test`: the `rigfile` body
//! (`fuzz/bodies/rigfile.rs`, the very file its `fuzz_target!` wraps) on every input of
//! `fuzz/corpus/rigfile/` and `fuzz/artifacts/rigfile/`, then on inputs mutated from them
//! (`ci/fuzz_replay.rs`). Coverage-guided fuzzing is `ci/fuzz.sh` (nightly).

#[path = "../../ci/fuzz_replay.rs"]
mod replay;

#[path = "../fuzz/bodies/rigfile.rs"]
mod rigfile;

use replay::{Target, check};

#[test]
fn rigfile() {
    check(&Target {
        name: "rigfile",
        body: rigfile::run,
        mutations: 200_000,
    });
}
