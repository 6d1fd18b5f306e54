//! Arbitrary text as a rig file: a rig file, or an error that names the rig file and a line
//! and column in it (`fuzz.toml:N:M:`, or for a MultiRX config it names, that config's file
//! with the rig file's field); never a panic. MultiRX configs come from memory (the shipped
//! ones by file name), so the fuzzer reaches the config checks without touching the disk.

use std::io;
use std::path::Path;

const CONFIGS: [(&str, &str); 4] = [
    (
        "parallel.toml",
        include_str!("../../../rigs/multirx/parallel.toml"),
    ),
    ("scan.toml", include_str!("../../../rigs/multirx/scan.toml")),
    (
        "bench-parallel.toml",
        include_str!("../../../rigs/multirx/bench-parallel.toml"),
    ),
    (
        "bench-scan.toml",
        include_str!("../../../rigs/multirx/bench-scan.toml"),
    ),
];

fn read_config(path: &Path) -> io::Result<String> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    CONFIGS
        .iter()
        .find(|(file, _)| *file == name)
        .map(|(_, text)| text.to_string())
        .ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, "not a shipped config"))
}

/// `pat` followed by a digit somewhere in `message`.
fn followed_by_digit(message: &str, pat: &str) -> bool {
    message
        .match_indices(pat)
        .any(|(i, _)| message[i + pat.len()..].starts_with(|c: char| c.is_ascii_digit()))
}

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(e) =
        harness::rigfile::RigFile::from_str_with(text, "/fuzz/rigs/fuzz.toml", &read_config)
    {
        let message = e.to_string();
        assert!(
            message.contains("/fuzz/rigs/fuzz.toml"),
            "error without the rig file: {message}"
        );
        assert!(
            followed_by_digit(&message, ".toml:"),
            "error without a line: {message}"
        );
    }
}
