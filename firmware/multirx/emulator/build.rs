//! Compiles the emulated device's source into its build id: the git commit
//! (`unknown` outside a git tree) and a hash of its input files
//! (`multirx_core::provenance::EMULATOR_INPUTS`), as `MULTIRX_SOURCE_ID`
//! (16 hex digits, `Source::id`) and `MULTIRX_SOURCE_COMMIT`. The rig's own build script computes the same
//! from the same tree, so a `multirx-emu` left from an older build fails the
//! rig's identity check.

use std::env;
use std::path::PathBuf;

use multirx_core::provenance::{EMULATOR_INPUTS, Source, git_head_files};

fn main() {
    let dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let source = match Source::of(&dir, EMULATOR_INPUTS, None) {
        Ok(source) => source,
        Err(e) => {
            println!("cargo::error=cannot hash the emulated device's input files: {e}");
            std::process::exit(1);
        }
    };
    // Only paths that exist: cargo reruns the script every build for a missing one.
    for path in EMULATOR_INPUTS
        .iter()
        .map(|i| dir.join(i))
        .chain(git_head_files(&dir))
        .filter(|p| p.exists())
    {
        println!("cargo::rerun-if-changed={}", path.display());
    }
    println!("cargo::rustc-env=MULTIRX_SOURCE_COMMIT={}", source.commit);
    println!("cargo::rustc-env=MULTIRX_SOURCE_ID={:016x}", source.id());
}
