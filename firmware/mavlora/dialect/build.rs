//! Generates the MavLora dialect from `../message_definitions/mavlora.xml` with mavlink-bindgen,
//! the generator the `mavlink` crate uses for its own dialects (see its `build/main.rs`).

use std::collections::HashSet;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use mavlink_bindgen::XmlDefinitions;

fn main() -> ExitCode {
    // Read when run, not when compiled: a build script binary reused from another checkout
    // sharing the target folder would otherwise read that checkout's definitions.
    let manifest_dir = PathBuf::from(
        std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"),
    );
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
    if let Err(error) = write_ardupilot_crc_extras(&definitions, &out_dir) {
        eprintln!("cannot read ardupilotmega.xml: {error}");
        return ExitCode::FAILURE;
    }
    // The generated code carries `cfg(feature = "serde")` and similar for features this crate
    // does not offer.
    println!(
        "cargo::rustc-check-cfg=cfg(feature, values(\"serde\", \"arbitrary\", \"ts-rs\", \"mav2-message-extensions\"))"
    );
    ExitCode::SUCCESS
}

/// The CRC_EXTRA of every message ArduPilot speaks (`ardupilotmega.xml` and its includes), as
/// a sorted `(id, extra)` table in `ardupilotmega_crc_extra.rs`: enough to check and rebuild
/// their frames without generating (and compiling) their types, which nothing here decodes.
fn write_ardupilot_crc_extras(definitions: &Path, out_dir: &Path) -> Result<(), String> {
    let files = [
        "ardupilotmega.xml",
        "uAvionix.xml",
        "icarous.xml",
        "loweheiser.xml",
        "cubepilot.xml",
        "csAirLink.xml",
    ];
    for file in files {
        println!(
            "cargo::rerun-if-changed={}",
            definitions.join(file).display()
        );
    }
    let profile = mavlink_bindgen::parser::parse_profile(
        definitions,
        Path::new("ardupilotmega.xml"),
        &mut HashSet::new(),
    )
    .map_err(|e| e.to_string())?;
    let mut table: Vec<(u32, u8)> = profile
        .messages
        .values()
        .map(|m| (m.id, mavlink_bindgen::parser::extra_crc(m)))
        .collect();
    table.sort_unstable();
    let mut code = String::from(
        "/// `(message id, CRC_EXTRA)` of `ardupilotmega.xml` and its includes, by id.\n",
    );
    let _ = writeln!(
        code,
        "pub const ARDUPILOTMEGA_CRC_EXTRA: [(u32, u8); {}] = [",
        table.len()
    );
    for (id, extra) in table {
        let _ = writeln!(code, "    ({id}, {extra}),");
    }
    code.push_str("];\n");
    fs::write(out_dir.join("ardupilotmega_crc_extra.rs"), code).map_err(|e| e.to_string())
}
