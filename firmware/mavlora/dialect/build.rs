//! Generates the MavLora dialect from `../message_definitions/mavlora.xml` with mavlink-bindgen,
//! the generator the `mavlink` crate uses for its own dialects (see its `build/main.rs`).

use std::fs;
use std::path::PathBuf;
use std::process::ExitCode;

use mavlink_bindgen::XmlDefinitions;

fn main() -> ExitCode {
    let manifest_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let definitions = manifest_dir.join("../message_definitions");
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));

    let result = match mavlink_bindgen::generate(
        XmlDefinitions::Files(vec![definitions.join("mavlora.xml")]),
        &out_dir,
    ) {
        Ok(result) => result,
        Err(error) => {
            eprintln!("mavlink-bindgen failed on mavlora.xml: {error}");
            return ExitCode::FAILURE;
        }
    };
    // bindgen reports only the top file; the included ones change the output too.
    mavlink_bindgen::emit_cargo_build_messages(&result);
    for included in ["common.xml", "standard.xml", "minimal.xml"] {
        println!(
            "cargo::rerun-if-changed={}",
            definitions.join(included).display()
        );
    }

    // bindgen's own mod.rs gates each dialect on a `dialect-<name>` feature; this crate *is*
    // the dialect, so declare the module unconditionally, with the lints generated code trips.
    let module = "#[allow(non_camel_case_types, non_snake_case, deprecated, unused_imports, \
                  missing_docs, clippy::all, rustdoc::all)]\npub mod mavlora;\n";
    if let Err(error) = fs::write(out_dir.join("dialect_mod.rs"), module) {
        eprintln!("cannot write dialect_mod.rs: {error}");
        return ExitCode::FAILURE;
    }
    // The generated code carries `cfg(feature = "serde")` and similar for features this crate
    // does not offer.
    println!(
        "cargo::rustc-check-cfg=cfg(feature, values(\"serde\", \"arbitrary\", \"ts-rs\", \"mav2-message-extensions\"))"
    );
    ExitCode::SUCCESS
}
