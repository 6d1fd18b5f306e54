//! What the end-to-end tests share: the repository root, and (from `testkit`) a
//! child-process guard and pty pairs.
// Each test program uses its own part of this.
#![allow(dead_code, unused_imports)]

use std::path::PathBuf;

pub use testkit::{Guard, pty_pair};

/// The repository root, where `fixtures/` and `firmware/` are.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}
