//! The cargo-fuzz targets' invariants on stable, in every `cargo test`: each target's body
//! (`fuzz/bodies/<target>.rs`, the very file its `fuzz_target!` wraps) on every input of
//! `fuzz/corpus/<target>/` and `fuzz/artifacts/<target>/`, then on inputs mutated from them
//! (`ci/fuzz_replay.rs`). Coverage-guided fuzzing is `ci/fuzz.sh` (nightly).

#[path = "../../../../ci/fuzz_replay.rs"]
mod replay;

#[cfg(feature = "toml")]
#[path = "../fuzz/bodies/config_toml.rs"]
mod config_toml;
#[path = "../fuzz/bodies/sbus_stream.rs"]
mod sbus_stream;

use replay::{Target, check};

/// The parser is behind the `toml` feature; the workspace build has it (the rig enables it),
/// `cargo test -p multirx-core` alone does not, and says so here instead of passing.
#[test]
#[cfg_attr(
    not(feature = "toml"),
    ignore = "needs the `toml` feature: cargo test -p multirx-core --features toml"
)]
fn config_toml() {
    #[cfg(feature = "toml")]
    check(&Target {
        name: "config_toml",
        body: config_toml::run,
        mutations: 400_000,
    });
}

#[test]
fn sbus_stream() {
    check(&Target {
        name: "sbus_stream",
        body: sbus_stream::run,
        mutations: 200_000,
    });
}
