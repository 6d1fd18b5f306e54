//! Compiles the emulated device's source into its build id: a hash of its
//! input files (`multirx_core::provenance::Source::emulator`), as
//! `MULTIRX_SOURCE_ID` (16 hex digits). The rig's own build script computes
//! the same from the same tree, so a `multirx-emu` left from an older build
//! fails the rig's identity check.

use std::env;
use std::path::PathBuf;

use multirx_core::provenance::{EMULATOR_INPUTS, Source, existing_inputs};

fn main() {
    let dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let source = match Source::emulator(&dir) {
        Ok(source) => source,
        Err(e) => {
            println!("cargo::error=cannot hash the emulated device's input files: {e}");
            std::process::exit(1);
        }
    };
    for path in existing_inputs(&dir, EMULATOR_INPUTS) {
        println!("cargo::rerun-if-changed={}", path.display());
    }
    println!("cargo::rustc-env=MULTIRX_SOURCE_ID={:016x}", source.id());
}
