//! Arbitrary text as a configuration file: an error or a valid config, never a panic.

pub fn run(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(config) = multirx_core::Config::from_toml(text)
    {
        config
            .validate()
            .expect("from_toml returns only valid configs");
    }
}
