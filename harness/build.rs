//! Hashes the emulated device's source as its own build script does
//! (`multirx_core::provenance::Source::emulator`), so the rig knows the build
//! id the `multirx-emu` built beside it reports: `MULTIRX_EMULATOR_SOURCE_ID`
//! (16 hex digits).

use std::env;
use std::path::PathBuf;

use multirx_core::provenance::{EMULATOR_INPUTS, Source, existing_inputs};

fn main() {
    let dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"))
        .join("../firmware/multirx/emulator");
    let source = match Source::emulator(&dir) {
        Ok(source) => source,
        Err(e) => {
            println!(
                "cargo::error=cannot hash the emulated device's input files in {}: {e}",
                dir.display()
            );
            std::process::exit(1);
        }
    };
    for path in existing_inputs(&dir, EMULATOR_INPUTS) {
        println!("cargo::rerun-if-changed={}", path.display());
    }
    println!("cargo::rerun-if-changed=build.rs");
    println!(
        "cargo::rustc-env=MULTIRX_EMULATOR_SOURCE_ID={:016x}",
        source.id()
    );
}
