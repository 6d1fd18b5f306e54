//! The cargo-fuzz targets' invariants on stable, in every `cargo test`: each target's body
//! (`fuzz/bodies/<target>.rs`, the very file its `fuzz_target!` wraps) on every input of
//! `fuzz/corpus/<target>/` and `fuzz/artifacts/<target>/`, then on inputs mutated from them
//! (`ci/fuzz_replay.rs`). Coverage-guided fuzzing is `ci/fuzz.sh` (nightly).

#[path = "../../../ci/fuzz_replay.rs"]
mod replay;

#[path = "../fuzz/bodies/engines.rs"]
mod engines;
#[path = "../fuzz/bodies/key.rs"]
mod key;
#[path = "../fuzz/bodies/params.rs"]
mod params;
#[path = "../fuzz/bodies/profile.rs"]
mod profile;
#[path = "../fuzz/bodies/reader.rs"]
mod reader;

use replay::{Target, check};

#[test]
fn engines() {
    check(&Target {
        name: "engines",
        body: engines::run,
        mutations: 50_000,
    });
}

#[test]
fn key() {
    check(&Target {
        name: "key",
        body: key::run,
        mutations: 200_000,
    });
}

#[test]
fn params() {
    check(&Target {
        name: "params",
        body: params::run,
        mutations: 10_000,
    });
}

#[test]
fn profile() {
    check(&Target {
        name: "profile",
        body: profile::run,
        mutations: 50_000,
    });
}

#[test]
fn reader() {
    check(&Target {
        name: "reader",
        body: reader::run,
        mutations: 200_000,
    });
}
