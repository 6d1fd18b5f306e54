//! Build script, after the atsamd-rs boards' (`boards/feather_m0`):
//!
//! 1. copies the selected memory layout to `OUT_DIR/memory.x` for cortex-m-rt's
//!    `link.x`: `memory/bare.x`, or `memory/uf2.x` with the `uf2` feature (8 KiB
//!    UF2 bootloader). No `memory.x` lives in this folder: the linker runs here
//!    and looks in its working directory before the search path, so one would
//!    shadow the selected layout;
//! 2. compiles the MultiRX configuration into the image: reads the TOML file
//!    named by `MULTIRX_CONFIG` (default `multirx.toml` here; relative paths
//!    are taken from this folder), validates it with the same code the host
//!    uses (`multirx_core::Config::from_toml_for_board`), checks it fits this
//!    board's UARTs (`multirx_core::board::SAMD21_UARTS`, the number the rig
//!    checks too), and writes `OUT_DIR/config.rs` with `pub const CONFIG`,
//!    its `CONFIG_HASH` and the image's `BUILD_ID` (the boot line's, which
//!    the rig checks against the config its rig file names), over the core
//!    version, the config and the source: the git commit (`unknown` outside
//!    a git tree) and a hash of the inputs (`multirx_core::provenance`,
//!    the list the rig hashes again from the tree it runs with).
//!
//! 3. passes the linker its arguments (`-Tlink.x`, `--nmagic`) itself: as
//!    `rustflags` in `.cargo/config.toml` they vanish whenever `RUSTFLAGS` is
//!    set in the environment (cargo takes one or the other), and the image
//!    would link without cortex-m-rt's script, i.e. without a vector table.
//!
//! A bad configuration fails the build with `file:line:column: message`.

use std::env;
use std::fs;
use std::path::{Path, PathBuf};

use multirx_core::Config;
use multirx_core::board::SAMD21_UARTS;
use multirx_core::boot::{ImageKind, build_id};
use multirx_core::provenance::{SAMD21_INPUTS, Source, existing_inputs, git_head_files};

/// Configuration file used when `MULTIRX_CONFIG` is not set.
const DEFAULT_CONFIG: &str = "multirx.toml";

fn main() {
    let manifest_dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let out_dir = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));

    if let Err(message) = memory_layout(&manifest_dir, &out_dir) {
        fail(&message);
    }
    if let Err(message) = configuration(&manifest_dir, &out_dir) {
        fail(&message);
    }
    println!("cargo::rerun-if-changed=build.rs");
}

/// Reports `message` as a build error and stops the build.
fn fail(message: &str) -> ! {
    for line in message.lines() {
        println!("cargo::error={line}");
    }
    std::process::exit(1);
}

fn memory_layout(manifest_dir: &Path, out_dir: &Path) -> Result<(), String> {
    let source = if env::var_os("CARGO_FEATURE_UF2").is_some() {
        "memory/uf2.x"
    } else {
        "memory/bare.x"
    };
    let from = manifest_dir.join(source);
    fs::copy(&from, out_dir.join("memory.x"))
        .map_err(|e| format!("{}: cannot copy the memory layout: {e}", from.display()))?;
    println!("cargo::rustc-link-search={}", out_dir.display());
    // cortex-m-rt's script (it INCLUDEs the memory.x above). `--nmagic`: no page
    // alignment, so the ELF headers are not put in a loadable segment at 0x0
    // (which, with the `uf2` layout, a flasher would write over the bootloader).
    println!("cargo::rustc-link-arg-bins=-Tlink.x");
    println!("cargo::rustc-link-arg-bins=--nmagic");
    println!("cargo::rerun-if-changed=memory");
    Ok(())
}

fn configuration(manifest_dir: &Path, out_dir: &Path) -> Result<(), String> {
    println!("cargo::rerun-if-env-changed=MULTIRX_CONFIG");
    let path = match env::var_os("MULTIRX_CONFIG") {
        Some(p) if !p.is_empty() => manifest_dir.join(p),
        _ => manifest_dir.join(DEFAULT_CONFIG),
    };
    println!("cargo::rerun-if-changed={}", path.display());
    let path = fs::canonicalize(&path).unwrap_or(path);
    let shown = path.display();

    let text = fs::read_to_string(&path)
        .map_err(|e| format!("{shown}: cannot read the MultiRX configuration: {e}"))?;
    let config =
        Config::from_toml_for_board(&text, SAMD21_UARTS).map_err(|e| format!("{shown}:{e}"))?;

    let mut literal = String::new();
    config
        .write_rust_literal(&mut literal)
        .map_err(|e| format!("{shown}: cannot write the configuration as Rust: {e}"))?;
    let config_hash = config.identity_hash();
    for input in existing_inputs(manifest_dir, SAMD21_INPUTS) {
        println!("cargo::rerun-if-changed={}", input.display());
    }
    for head in git_head_files(manifest_dir) {
        println!("cargo::rerun-if-changed={}", head.display());
    }
    let source = Source::of(manifest_dir, SAMD21_INPUTS, Some(&path))
        .map_err(|e| format!("cannot hash the firmware's input files: {e}"))?;
    let build_id = build_id(ImageKind::Samd21, config_hash, source.id());
    let commit = &source.commit;
    let inputs = source.inputs;
    let source = format!(
        "// Generated by build.rs from {shown}; do not edit.\n\
         /// The MultiRX configuration compiled into this image.\n\
         pub const CONFIG: multirx_core::Config = {literal};\n\
         /// `CONFIG.identity_hash()`, reported on the boot line.\n\
         pub const CONFIG_HASH: u64 = {config_hash:#018x};\n\
         /// `multirx_core::boot::build_id(ImageKind::Samd21, CONFIG_HASH, source)`,\n\
         /// source: commit {commit}, inputs {inputs:016x}.\n\
         pub const BUILD_ID: u64 = {build_id:#018x};\n"
    );
    let target = out_dir.join("config.rs");
    fs::write(&target, source).map_err(|e| format!("{}: {e}", target.display()))
}
