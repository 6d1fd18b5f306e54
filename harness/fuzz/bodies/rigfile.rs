//! Arbitrary text as a rig file: a located error or a rig file, never a panic.
//! MultiRX configs come from memory (the shipped ones by file name), so the
//! fuzzer reaches the config checks without touching the disk.

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

pub fn run(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ =
            harness::rigfile::RigFile::from_str_with(text, "/fuzz/rigs/fuzz.toml", &read_config);
    }
}
