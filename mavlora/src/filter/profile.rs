//! Profile files: per message, what the bridge asks of the flight controller (`stream_hz`) and
//! what it lets onto the radio (`radio`). One file drives both of the paper's mechanisms, so
//! they cannot disagree.
//!
//! ```toml
//! [defaults]
//! radio = "pass"            # for messages not listed
//!
//! [messages.GLOBAL_POSITION_INT]   # a name from the dialect, or a numeric id: [messages.33]
//! stream_hz = 3             # SET_MESSAGE_INTERVAL to the flight controller; 0 stops the stream
//! radio = 3                 # "pass", "drop", or a maximum rate in Hz
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use crate::wire::known;

/// What happens to a message on its way to the radio.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RadioRule {
    /// Forward every frame.
    Pass,
    /// Forward none (the paper's filtering).
    Drop,
    /// Forward at most this many frames per second per sender (the paper's rate limiting).
    MaxRate(f64),
}

/// The profile's entry for one message id.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MessageRule {
    /// Radio treatment; the profile default if the entry does not say.
    pub radio: RadioRule,
    /// Rate to request from the flight controller; `Some(0.0)` stops the stream, `None`
    /// leaves the flight controller's own rate.
    pub stream_hz: Option<f64>,
}

/// A loaded profile.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    default_radio: RadioRule,
    rules: BTreeMap<u32, MessageRule>,
}

/// Why a profile could not be loaded. Each names the file (or origin) and, where it can, the
/// line and key at fault.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The IO error.
        source: std::io::Error,
    },
    /// Not valid TOML, or a field the profile format does not have (unknown fields are
    /// rejected so typos do not silently pass everything).
    #[error("{origin}: {source}")]
    Syntax {
        /// The file.
        origin: String,
        /// The parser's error, which carries the line and column.
        source: Box<toml::de::Error>,
    },
    /// A message name the dialect does not define.
    #[error("{origin}:{line}: unknown message `{name}` (not in common.xml or mavlora.xml)")]
    UnknownMessage {
        /// The file.
        origin: String,
        /// 1-based line of the entry.
        line: usize,
        /// The name as written.
        name: String,
    },
    /// A `radio` value other than "pass", "drop" or a positive rate.
    #[error(
        "{origin}:{line}: `{key}`: radio = {value} (expected \"pass\", \"drop\" or a rate in Hz > 0)"
    )]
    InvalidRadio {
        /// The file.
        origin: String,
        /// 1-based line of the value.
        line: usize,
        /// The message key (or `defaults`).
        key: String,
        /// The value as parsed.
        value: String,
    },
    /// A `stream_hz` that is negative or not finite.
    #[error("{origin}:{line}: `{key}`: stream_hz = {value} (expected a rate in Hz >= 0)")]
    InvalidStreamRate {
        /// The file.
        origin: String,
        /// 1-based line of the value.
        line: usize,
        /// The message key.
        key: String,
        /// The value as parsed.
        value: f64,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileFile {
    #[serde(default)]
    defaults: Option<DefaultsFile>,
    #[serde(default)]
    messages: BTreeMap<Spanned<String>, RuleFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DefaultsFile {
    radio: Option<Spanned<RadioValue>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RuleFile {
    radio: Option<Spanned<RadioValue>>,
    stream_hz: Option<Spanned<f64>>,
}

#[derive(Deserialize, Debug)]
#[serde(untagged)]
enum RadioValue {
    Word(String),
    Rate(f64),
    Int(i64),
}

impl Profile {
    /// Reads and validates a profile file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ProfileError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| ProfileError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses profile text; `origin` names it in errors (usually the file path).
    pub fn parse(text: &str, origin: &str) -> Result<Self, ProfileError> {
        let file: ProfileFile = toml::from_str(text).map_err(|source| ProfileError::Syntax {
            origin: origin.to_owned(),
            source: Box::new(source),
        })?;
        let line_of = |span: std::ops::Range<usize>| text[..span.start].matches('\n').count() + 1;

        let default_radio = match file.defaults.and_then(|d| d.radio) {
            None => RadioRule::Pass,
            Some(value) => radio_rule(&value, "defaults", origin, line_of(value.span()))?,
        };

        let mut rules = BTreeMap::new();
        for (key, rule) in file.messages {
            let line = line_of(key.span());
            let name = key.get_ref();
            let id = match name.parse::<u32>() {
                Ok(id) => id,
                Err(_) => known::message_id(name).ok_or_else(|| ProfileError::UnknownMessage {
                    origin: origin.to_owned(),
                    line,
                    name: name.clone(),
                })?,
            };
            let radio = match &rule.radio {
                None => default_radio,
                Some(value) => radio_rule(value, name, origin, line_of(value.span()))?,
            };
            let stream_hz = match rule.stream_hz {
                None => None,
                Some(hz) if hz.get_ref().is_finite() && *hz.get_ref() >= 0.0 => Some(*hz.get_ref()),
                Some(hz) => {
                    return Err(ProfileError::InvalidStreamRate {
                        origin: origin.to_owned(),
                        line: line_of(hz.span()),
                        key: name.clone(),
                        value: *hz.get_ref(),
                    });
                }
            };
            rules.insert(id, MessageRule { radio, stream_hz });
        }
        Ok(Self {
            default_radio,
            rules,
        })
    }

    /// Radio treatment of message `id`.
    pub fn radio_rule(&self, id: u32) -> RadioRule {
        self.rules.get(&id).map_or(self.default_radio, |r| r.radio)
    }

    /// Radio treatment of messages the profile does not list.
    pub fn default_radio(&self) -> RadioRule {
        self.default_radio
    }

    /// The listed messages, by id.
    pub fn rules(&self) -> impl Iterator<Item = (u32, &MessageRule)> {
        self.rules.iter().map(|(id, r)| (*id, r))
    }
}

fn radio_rule(
    value: &Spanned<RadioValue>,
    key: &str,
    origin: &str,
    line: usize,
) -> Result<RadioRule, ProfileError> {
    let rate = match value.get_ref() {
        RadioValue::Word(w) if w == "pass" => return Ok(RadioRule::Pass),
        RadioValue::Word(w) if w == "drop" => return Ok(RadioRule::Drop),
        RadioValue::Word(_) => None,
        RadioValue::Rate(hz) => Some(*hz),
        RadioValue::Int(hz) => Some(*hz as f64),
    };
    match rate {
        Some(hz) if hz.is_finite() && hz > 0.0 => Ok(RadioRule::MaxRate(hz)),
        _ => Err(ProfileError::InvalidRadio {
            origin: origin.to_owned(),
            line,
            key: key.to_owned(),
            value: format!("{:?}", value.get_ref()),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = r#"
[defaults]
radio = "drop"

[messages.GLOBAL_POSITION_INT]
stream_hz = 3
radio = 3

[messages.HEARTBEAT]
radio = "pass"

[messages.30]
stream_hz = 0

[messages.VFR_HUD]
radio = 0.5
"#;

    #[test]
    fn names_ids_rates_and_defaults() {
        let p = Profile::parse(SAMPLE, "sample").unwrap();
        assert_eq!(p.radio_rule(33), RadioRule::MaxRate(3.0));
        assert_eq!(p.radio_rule(0), RadioRule::Pass);
        assert_eq!(p.radio_rule(74), RadioRule::MaxRate(0.5));
        // listed without `radio`: takes the default
        assert_eq!(p.radio_rule(30), RadioRule::Drop);
        // not listed at all
        assert_eq!(p.radio_rule(105), RadioRule::Drop);
        let streams: Vec<_> = p.rules().map(|(id, r)| (id, r.stream_hz)).collect();
        assert_eq!(
            streams,
            vec![(0, None), (30, Some(0.0)), (33, Some(3.0)), (74, None)]
        );
    }

    #[test]
    fn empty_profile_passes_everything() {
        let p = Profile::parse("", "empty").unwrap();
        assert_eq!(p.radio_rule(30), RadioRule::Pass);
    }

    #[test]
    fn unknown_message_names_the_line() {
        let err =
            Profile::parse("\n[messages.ATTITUDEE]\nradio = \"drop\"\n", "p.toml").unwrap_err();
        assert!(
            matches!(err, ProfileError::UnknownMessage { line: 2, .. }),
            "{err}"
        );
        assert_eq!(
            err.to_string(),
            "p.toml:2: unknown message `ATTITUDEE` (not in common.xml or mavlora.xml)"
        );
    }

    #[test]
    fn bad_radio_values_are_rejected_with_line() {
        for (value, line) in [("\"sometimes\"", 3), ("0", 3), ("-2.5", 3)] {
            let text = format!("[messages.ATTITUDE]\n\nradio = {value}\n");
            let err = Profile::parse(&text, "p.toml").unwrap_err();
            assert!(
                matches!(&err, ProfileError::InvalidRadio { line: l, .. } if *l == line),
                "{value}: {err}"
            );
        }
    }

    #[test]
    fn negative_stream_rate_is_rejected() {
        let err = Profile::parse("[messages.ATTITUDE]\nstream_hz = -1\n", "p").unwrap_err();
        assert!(
            matches!(err, ProfileError::InvalidStreamRate { line: 2, .. }),
            "{err}"
        );
    }

    #[test]
    fn unknown_fields_are_rejected() {
        let err = Profile::parse("[messages.ATTITUDE]\nrdio = \"drop\"\n", "p.toml").unwrap_err();
        assert!(matches!(err, ProfileError::Syntax { .. }));
        let text = err.to_string();
        assert!(
            text.starts_with("p.toml: ") && text.contains("rdio"),
            "{text}"
        );
    }

    #[test]
    fn missing_file_names_the_path() {
        let err = Profile::load("/nonexistent/profile.toml").unwrap_err();
        assert!(err.to_string().starts_with("/nonexistent/profile.toml: "));
    }
}

#[cfg(test)]
mod shipped_profiles {
    use super::*;

    #[test]
    fn px4_normal_loads_with_the_papers_choices() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/profiles/px4-normal.toml");
        let p = Profile::load(path).unwrap();
        let id = |name| known::message_id(name).unwrap();
        assert_eq!(
            p.radio_rule(id("GLOBAL_POSITION_INT")),
            RadioRule::MaxRate(3.0)
        );
        for dropped in [
            "ATTITUDE",
            "ATTITUDE_QUATERNION",
            "HIGHRES_IMU",
            "SERVO_OUTPUT_RAW",
        ] {
            assert_eq!(p.radio_rule(id(dropped)), RadioRule::Drop, "{dropped}");
        }
        for kept in [
            "HEARTBEAT",
            "COMMAND_LONG",
            "COMMAND_ACK",
            "MISSION_ITEM_INT",
            "LINK_QUALITY",
        ] {
            assert_eq!(p.radio_rule(id(kept)), RadioRule::Pass, "{kept}");
        }
    }
}
