//! The cargo-fuzz targets' invariants on stable, in every `cargo test`: each body
//! (`fuzz/bodies/<target>.rs`, the very file its `fuzz_target!` wraps) on every input of
//! `fuzz/corpus/<target>/` and `fuzz/artifacts/<target>/`, then on inputs mutated from them
//! (`ci/fuzz_replay.rs`). Coverage-guided fuzzing is `ci/fuzz.sh` (nightly).

#[path = "../../ci/fuzz_replay.rs"]
mod replay;

#[path = "../fuzz/bodies/rigfile.rs"]
mod rigfile;

#[path = "../fuzz/bodies/attenuator_reply.rs"]
mod attenuator_reply;

use replay::{Target, check};

#[test]
fn rigfile() {
    check(&Target {
        name: "rigfile",
        body: rigfile::run,
        mutations: 200_000,
    });
}

#[test]
fn attenuator_reply() {
    check(&Target {
        name: "attenuator_reply",
        body: attenuator_reply::run,
        mutations: 200_000,
    });
}
