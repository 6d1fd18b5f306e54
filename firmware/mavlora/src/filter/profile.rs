//! Profile files: per message, what the bridge asks of the flight controller (`stream_hz`) and
//! what it lets onto the radio (`radio`). One file drives both of the paper's mechanisms, so
//! they cannot disagree.
//!
//! ```toml
//! [defaults]
//! radio = "pass"            # for messages not listed
//! unlisted = "share"        # telemetry not listed: "share" what the listed leave, or "drop"
//!
//! [messages.GLOBAL_POSITION_INT]   # a name from the dialect, or a numeric id: [messages.33]
//! stream_hz = 3             # SET_MESSAGE_INTERVAL to the flight controller; 0 stops the stream
//! radio = 3                 # "pass", "drop", or a maximum rate in Hz
//!
//! [data_streams]            # REQUEST_DATA_STREAM, for MAVLink 1 autopilots (APM, old
//! all = 0                   # ArduPilot) that do not implement SET_MESSAGE_INTERVAL:
//! position = 3              # MAV_DATA_STREAM_* group (lower case, no prefix) -> Hz, 0 stops
//!
//! [compact]                 # the bridge's batching with --compact (CompactConfig)
//! sample_hz = 3             # position samples per second
//! batch_samples = 3         # samples per batch frame: a full batch leaves at once
//! batch_period_ms = 1000    # a batch that is not full leaves this long after its first sample
//! status_period_ms = 10000  # the vehicle's status rides along at least this often
//! coalesce_ms = 0           # hold frames so they share one radio packet (--coalesce-ms wins)
//! state_hz = 5              # HEARTBEAT and CURRENT_MODE asked of the autopilot; 0: not asked
//! ```

// MAV_DATA_STREAM / REQUEST_DATA_STREAM are deprecated upstream in favour of
// SET_MESSAGE_INTERVAL; they are used here on purpose, for MAVLink 1 autopilots.
#![allow(deprecated)]

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use crate::compact::{CompactConfig, MAX_BATCH_SAMPLES};
use crate::dialect::MavDataStream;
use crate::time::Duration;
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

/// What happens on the radio to periodic telemetry the profile does not list (an autopilot
/// that ignores the stream configuration, or sends messages nobody expected). Commands,
/// mission and parameter traffic are not telemetry and are not affected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Unlisted {
    /// Sent only with the budget the listed messages leave (the default).
    #[default]
    Share,
    /// Never sent (compact profiles: every byte is accounted for).
    Drop,
}

/// A loaded profile.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    default_radio: RadioRule,
    unlisted: Unlisted,
    rules: BTreeMap<u32, MessageRule>,
    data_streams: Vec<(MavDataStream, u16)>,
    compact: Option<CompactConfig>,
}

/// `MAV_DATA_STREAM` groups by their profile key, in the order `all` first: a request for
/// `all` resets every group, so it must go before the specific ones.
pub const DATA_STREAMS: [(&str, MavDataStream); 9] = [
    ("all", MavDataStream::MAV_DATA_STREAM_ALL),
    ("raw_sensors", MavDataStream::MAV_DATA_STREAM_RAW_SENSORS),
    (
        "extended_status",
        MavDataStream::MAV_DATA_STREAM_EXTENDED_STATUS,
    ),
    ("rc_channels", MavDataStream::MAV_DATA_STREAM_RC_CHANNELS),
    (
        "raw_controller",
        MavDataStream::MAV_DATA_STREAM_RAW_CONTROLLER,
    ),
    ("position", MavDataStream::MAV_DATA_STREAM_POSITION),
    ("extra1", MavDataStream::MAV_DATA_STREAM_EXTRA1),
    ("extra2", MavDataStream::MAV_DATA_STREAM_EXTRA2),
    ("extra3", MavDataStream::MAV_DATA_STREAM_EXTRA3),
];

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
    /// A `radio` value other than "pass", "drop" or a rate within [`MIN_RATE_HZ`] ..=
    /// [`MAX_RATE_HZ`].
    #[error(
        "{origin}:{line}: `{key}`: radio = {value} (expected \"pass\", \"drop\" or a rate in Hz, 0.001..=1000000)"
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
    /// A `[data_streams]` key that is not a `MAV_DATA_STREAM` group.
    #[error("{origin}:{line}: unknown data stream `{name}` (expected one of {expected})")]
    UnknownDataStream {
        /// The file.
        origin: String,
        /// 1-based line of the key.
        line: usize,
        /// The key as written.
        name: String,
        /// The accepted keys.
        expected: String,
    },
    /// A `[data_streams]` rate outside 0..=65535 Hz (the field is a `u16`).
    #[error("{origin}:{line}: data stream `{name}` = {value} (expected 0..=65535 Hz, 0 stops it)")]
    InvalidDataStreamRate {
        /// The file.
        origin: String,
        /// 1-based line of the value.
        line: usize,
        /// The key.
        name: String,
        /// The value as written.
        value: i64,
    },
    /// A `stream_hz` other than 0 or a rate within [`MIN_RATE_HZ`] ..= [`MAX_RATE_HZ`].
    #[error(
        "{origin}:{line}: `{key}`: stream_hz = {value} (expected 0 to stop it or a rate in Hz, 0.001..=1000000)"
    )]
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
    /// A `[compact]` value outside its range.
    #[error("{origin}:{line}: compact.{key} = {value} (expected {expected})")]
    InvalidCompact {
        /// The file.
        origin: String,
        /// 1-based line of the value.
        line: usize,
        /// The key.
        key: &'static str,
        /// The value as parsed.
        value: f64,
        /// The range it must be in.
        expected: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileFile {
    #[serde(default)]
    defaults: Option<DefaultsFile>,
    #[serde(default)]
    messages: BTreeMap<Spanned<String>, RuleFile>,
    #[serde(default)]
    data_streams: BTreeMap<Spanned<String>, Spanned<i64>>,
    #[serde(default)]
    compact: Option<CompactFile>,
}

/// `[compact]`: every key optional, the rest from [`CompactConfig::default`].
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CompactFile {
    sample_hz: Option<Spanned<f64>>,
    batch_samples: Option<Spanned<i64>>,
    batch_period_ms: Option<Spanned<i64>>,
    status_period_ms: Option<Spanned<i64>>,
    coalesce_ms: Option<Spanned<i64>>,
    state_hz: Option<Spanned<f64>>,
}

/// Ranges of the `[compact]` keys.
pub const COMPACT_SAMPLE_HZ: std::ops::RangeInclusive<f64> = 0.1..=50.0;
/// See [`COMPACT_SAMPLE_HZ`].
pub const COMPACT_BATCH_PERIOD_MS: std::ops::RangeInclusive<i64> = 50..=60_000;
/// See [`COMPACT_SAMPLE_HZ`].
pub const COMPACT_STATUS_PERIOD_MS: std::ops::RangeInclusive<i64> = 500..=600_000;
/// See [`COMPACT_SAMPLE_HZ`]; 0 leaves the autopilot's own rates.
pub const COMPACT_STATE_HZ: std::ops::RangeInclusive<f64> = 0.0..=50.0;
/// See [`COMPACT_SAMPLE_HZ`].
pub const COMPACT_COALESCE_MS: std::ops::RangeInclusive<i64> = 0..=60_000;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DefaultsFile {
    radio: Option<Spanned<RadioValue>>,
    #[serde(default)]
    unlisted: Unlisted,
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
        let text = crate::input_file::read_to_string(path, crate::input_file::MAX_TEXT_FILE)
            .map_err(|source| ProfileError::Read {
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

        let unlisted = file
            .defaults
            .as_ref()
            .map_or(Unlisted::Share, |d| d.unlisted);
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
                Some(hz) if *hz.get_ref() == 0.0 || rate_in_range(*hz.get_ref()) => {
                    Some(*hz.get_ref())
                }
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

        let mut data_streams = Vec::new();
        for (key, hz) in file.data_streams {
            let name = key.get_ref();
            let Some(&(_, id)) = DATA_STREAMS.iter().find(|(n, _)| n == name) else {
                return Err(ProfileError::UnknownDataStream {
                    origin: origin.to_owned(),
                    line: line_of(key.span()),
                    name: name.clone(),
                    expected: DATA_STREAMS.map(|(n, _)| n).join(", "),
                });
            };
            let rate =
                u16::try_from(*hz.get_ref()).map_err(|_| ProfileError::InvalidDataStreamRate {
                    origin: origin.to_owned(),
                    line: line_of(hz.span()),
                    name: name.clone(),
                    value: *hz.get_ref(),
                })?;
            data_streams.push((id, rate));
        }
        // MAV_DATA_STREAM_ALL (0) first: it overrides the groups sent before it.
        data_streams.sort_by_key(|&(id, _)| id as u32);
        let compact = file
            .compact
            .map(|c| compact_config(c, origin, &line_of))
            .transpose()?;
        Ok(Self {
            default_radio,
            unlisted,
            rules,
            data_streams,
            compact,
        })
    }

    /// The `[compact]` table: the bridge's batching with `--compact` (`None`: the profile
    /// has none; [`CompactConfig::default`] then).
    pub fn compact(&self) -> Option<CompactConfig> {
        self.compact
    }

    /// `REQUEST_DATA_STREAM` groups and rates (Hz, 0 = stop), `MAV_DATA_STREAM_ALL` first.
    pub fn data_streams(&self) -> &[(MavDataStream, u16)] {
        &self.data_streams
    }

    /// Radio treatment of message `id`.
    pub fn radio_rule(&self, id: u32) -> RadioRule {
        self.rules.get(&id).map_or(self.default_radio, |r| r.radio)
    }

    /// Radio treatment of messages the profile does not list.
    pub fn default_radio(&self) -> RadioRule {
        self.default_radio
    }

    /// Whether the profile names message `id` for the radio (listed, and not dropped): named
    /// telemetry gets its rate before anything unnamed.
    pub fn names(&self, id: u32) -> bool {
        self.rules
            .get(&id)
            .is_some_and(|r| r.radio != RadioRule::Drop)
    }

    /// What happens to periodic telemetry the profile does not name.
    pub fn unlisted(&self) -> Unlisted {
        self.unlisted
    }

    /// The listed messages, by id.
    pub fn rules(&self) -> impl Iterator<Item = (u32, &MessageRule)> {
        self.rules.iter().map(|(id, r)| (*id, r))
    }
}

/// The lowest rate a profile may give (one frame per 1000 s): below it the limiter's
/// interval and `SET_MESSAGE_INTERVAL`'s 32-bit microseconds overflow.
pub const MIN_RATE_HZ: f64 = 1e-3;
/// The highest rate a profile may give (an interval of 1 µs).
pub const MAX_RATE_HZ: f64 = 1e6;

fn rate_in_range(hz: f64) -> bool {
    (MIN_RATE_HZ..=MAX_RATE_HZ).contains(&hz)
}

fn compact_config(
    file: CompactFile,
    origin: &str,
    line_of: &dyn Fn(std::ops::Range<usize>) -> usize,
) -> Result<CompactConfig, ProfileError> {
    let mut c = CompactConfig::default();
    let invalid =
        |key: &'static str, v: &Spanned<f64>, expected: String| ProfileError::InvalidCompact {
            origin: origin.to_owned(),
            line: line_of(v.span()),
            key,
            value: *v.get_ref(),
            expected,
        };
    let int = |v: &Spanned<i64>| Spanned::new(v.span(), *v.get_ref() as f64);
    let ms = |key: &'static str,
              v: &Option<Spanned<i64>>,
              range: std::ops::RangeInclusive<i64>|
     -> Result<Option<Duration>, ProfileError> {
        match v {
            None => Ok(None),
            Some(v) if range.contains(v.get_ref()) => {
                Ok(Some(Duration::from_millis(*v.get_ref() as u64)))
            }
            Some(v) => Err(invalid(
                key,
                &int(v),
                format!("{}..={} ms", range.start(), range.end()),
            )),
        }
    };
    let hz = |key: &'static str,
              v: &Option<Spanned<f64>>,
              range: std::ops::RangeInclusive<f64>|
     -> Result<Option<f64>, ProfileError> {
        match v {
            None => Ok(None),
            Some(v) if range.contains(v.get_ref()) => Ok(Some(*v.get_ref())),
            Some(v) => Err(invalid(
                key,
                v,
                format!("{}..={} Hz", range.start(), range.end()),
            )),
        }
    };
    if let Some(hz) = hz("sample_hz", &file.sample_hz, COMPACT_SAMPLE_HZ)? {
        c.sample_hz = hz;
    }
    if let Some(n) = &file.batch_samples {
        if !(1..=MAX_BATCH_SAMPLES as i64).contains(n.get_ref()) {
            return Err(invalid(
                "batch_samples",
                &int(n),
                format!("1..={MAX_BATCH_SAMPLES} samples"),
            ));
        }
        c.batch_samples = *n.get_ref() as usize;
    }
    if let Some(d) = ms(
        "batch_period_ms",
        &file.batch_period_ms,
        COMPACT_BATCH_PERIOD_MS,
    )? {
        c.batch_period = d;
    }
    if let Some(d) = ms(
        "status_period_ms",
        &file.status_period_ms,
        COMPACT_STATUS_PERIOD_MS,
    )? {
        c.status_period = d;
    }
    if let Some(d) = ms("coalesce_ms", &file.coalesce_ms, COMPACT_COALESCE_MS)? {
        c.coalesce = d;
    }
    if let Some(hz) = hz("state_hz", &file.state_hz, COMPACT_STATE_HZ)? {
        c.state_hz = hz;
    }
    Ok(c)
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
        Some(hz) if rate_in_range(hz) => Ok(RadioRule::MaxRate(hz)),
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
    fn data_streams_all_first_and_checked() {
        let p = Profile::parse(
            "[data_streams]\nposition = 3\nall = 0\nextended_status = 1\n",
            "p",
        )
        .unwrap();
        let ids: Vec<_> = p
            .data_streams()
            .iter()
            .map(|&(s, hz)| (s as u32, hz))
            .collect();
        assert_eq!(ids, vec![(0, 0), (2, 1), (6, 3)]);
        let err =
            Profile::parse("[data_streams]\n\nposition = 3\npositon = 1\n", "p.toml").unwrap_err();
        assert!(
            matches!(err, ProfileError::UnknownDataStream { line: 4, .. }),
            "{err}"
        );
        assert!(err.to_string().contains("extra3"), "{err}");
        let err = Profile::parse("[data_streams]\nall = -1\n", "p.toml").unwrap_err();
        assert!(
            matches!(
                err,
                ProfileError::InvalidDataStreamRate {
                    line: 2,
                    value: -1,
                    ..
                }
            ),
            "{err}"
        );
    }

    #[test]
    fn unlisted_telemetry_shares_by_default_and_can_be_dropped() {
        let p = Profile::parse(SAMPLE, "sample").unwrap();
        assert_eq!(p.unlisted(), Unlisted::Share);
        assert!(p.names(33) && p.names(0) && !p.names(105));
        let p = Profile::parse(
            "[defaults]\nunlisted = \"drop\"\n[messages.33]\nradio = 3\n",
            "p",
        )
        .unwrap();
        assert_eq!(p.unlisted(), Unlisted::Drop);
        let err = Profile::parse("[defaults]\n\nunlisted = \"keep\"\n", "p.toml").unwrap_err();
        assert!(err.to_string().contains("line 3"), "{err}");
    }

    #[test]
    fn compact_table_sets_the_batching_and_checks_every_key() {
        let p = Profile::parse(
            "[compact]\nsample_hz = 4\nbatch_samples = 2\nbatch_period_ms = 700\n\
             status_period_ms = 5000\ncoalesce_ms = 250\nstate_hz = 2\n",
            "p.toml",
        )
        .unwrap();
        assert_eq!(
            p.compact(),
            Some(CompactConfig {
                sample_hz: 4.0,
                batch_samples: 2,
                batch_period: Duration::from_millis(700),
                status_period: Duration::from_secs(5),
                coalesce: Duration::from_millis(250),
                state_hz: 2.0,
            })
        );
        // keys left out keep the defaults; no table, no settings
        let p = Profile::parse("[compact]\nbatch_samples = 4\n", "p.toml").unwrap();
        assert_eq!(
            p.compact(),
            Some(CompactConfig {
                batch_samples: 4,
                ..CompactConfig::default()
            })
        );
        assert_eq!(Profile::parse("", "p").unwrap().compact(), None);
        // unknown keys and values out of range name the file and line
        let err = Profile::parse("[compact]\n\nbatch_period = 1000\n", "p.toml").unwrap_err();
        assert!(matches!(err, ProfileError::Syntax { .. }), "{err}");
        let text = err.to_string();
        assert!(
            text.starts_with("p.toml: ")
                && text.contains("line 3")
                && text.contains("batch_period"),
            "{text}"
        );
        for (line, value) in [
            ("sample_hz = 0", 2),
            ("sample_hz = 100", 2),
            ("batch_samples = 0", 2),
            ("batch_samples = 11", 2),
            ("batch_period_ms = 10", 2),
            ("status_period_ms = 99", 2),
            ("coalesce_ms = -1", 2),
            ("coalesce_ms = 60001", 2),
            ("state_hz = -1", 2),
            ("state_hz = 51", 2),
        ] {
            let err = Profile::parse(&format!("[compact]\n{line}\n"), "p.toml").unwrap_err();
            assert!(
                matches!(&err, ProfileError::InvalidCompact { line: l, .. } if *l == value),
                "{line}: {err}"
            );
            assert!(err.to_string().starts_with("p.toml:2: compact."), "{err}");
        }
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
        for (value, line) in [
            ("\"sometimes\"", 3),
            ("0", 3),
            ("-2.5", 3),
            ("1e-30", 3),
            ("inf", 3),
            ("nan", 3),
            ("1e9", 3),
        ] {
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

    #[test]
    fn every_shipped_profile_loads() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/profiles");
        let mut n = 0;
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            Profile::load(&path).unwrap_or_else(|e| panic!("{e}"));
            n += 1;
        }
        assert!(n >= 3, "only {n} profiles in {dir}");
        let ardupilot = Profile::load(format!("{dir}/ardupilot-mavlink1.toml")).unwrap();
        assert_eq!(ardupilot.data_streams()[0].0 as u32, 0, "`all` goes first");
    }

    #[test]
    fn compact_profiles_drop_unlisted_telemetry_and_ship_the_default_batching() {
        // Their byte promise holds for any autopilot version: what they do not list is
        // dropped, not sent with spare budget. Their [compact] tables say what the default is.
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/profiles");
        for name in ["px4-compact.toml", "ardupilot-compact.toml"] {
            let p = Profile::load(format!("{dir}/{name}")).unwrap();
            assert_eq!(p.unlisted(), Unlisted::Drop, "{name}");
            assert_eq!(p.compact(), Some(CompactConfig::default()), "{name}");
            // a ground station's REQUEST_MESSAGE for it is answered, not dropped as unlisted
            assert!(
                p.names(known::message_id("AUTOPILOT_VERSION").unwrap()),
                "{name}"
            );
        }
    }
}
