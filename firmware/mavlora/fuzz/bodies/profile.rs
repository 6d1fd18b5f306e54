//! Profile files (TOML, from the operator): any text either parses into a profile whose
//! rules all name a message id and a rate that is finite and positive, or is refused with an
//! error that names the origin and a line; never a panic.

use mavlora::filter::Profile;

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match Profile::parse(text, "fuzz.toml") {
        Ok(profile) => {
            for (_, rule) in profile.rules() {
                let _ = format!("{rule:?}");
            }
        }
        Err(e) => {
            let message = e.to_string();
            assert!(
                message.contains("fuzz.toml"),
                "error without its origin: {message}"
            );
        }
    }
}
