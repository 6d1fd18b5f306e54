//! The configuration file (TOML), read by the emulated device at start and by
//! the firmware's build script. Unknown keys are rejected; errors name the
//! line, column and key.
//!
//! ```toml
//! mode = "parallel"        # or "scan", the paper's design
//! receivers = 2
//! frame_period_ms = 7      # output towards the flight controller
//!
//! [link]
//! silence_timeout_ms = 60  # no frame for this long = link lost
//! acquire_frames = 3       # valid frames in a row before a receiver may take control
//! scan_window_ms = 2000    # scan mode: listen this long to each receiver
//!
//! [pilot_channel]
//! channel = 10             # 1-based, as on the transmitter
//! values = [445, 718]      # one per receiver
//! none = 172               # no receiver active
//!
//! [flight_mode]
//! channel = 5
//! auto_loiter = 1811
//!
//! [neutral]                # what the flight controller gets while no receiver is active
//! values = [992, 992, 992, 992, 1811, 992, 992, 992, 992, 172, 992, 992, 992, 992, 992, 992]
//! throttle_channel = 3     # the channel your flight controller reads as throttle (AETR: 3)
//! throttle = 992           # its neutral: mid-stick holds altitude only in a hold mode
//!
//! [ifs]
//! channels = [5]           # channels the independent fail-safe system may override
//! ```
//!
//! The default neutral is 992 (mid-stick) on every channel, throttle
//! included. That is safe only when the flight controller maps
//! `flight_mode.auto_loiter` on `flight_mode.channel` to a position/altitude
//! hold (PX4 Hold, ArduPilot Loiter), where mid throttle means "hold
//! altitude"; in a manual or stabilised mode it is about half thrust. Name the
//! throttle channel and its neutral (`neutral.throttle_channel`,
//! `neutral.throttle`) for your flight controller;
//! [`Config::from_toml_for_bench`], which the rig uses for a board, refuses a
//! file that does not.

use serde::Deserialize;

use super::{Config, ConfigError, MAX_RECEIVERS, Mode};
use crate::time::Duration;

/// Why a configuration file was refused. Lines and columns are 1-based.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigFileError {
    /// Not valid TOML, a missing key, a wrong type or a key we do not know.
    #[error("{line}:{column}: {message}")]
    Syntax {
        line: usize,
        column: usize,
        message: String,
    },
    /// Well-formed, but a value MultiRX cannot fly with.
    #[error("{line}:{column}: {message}")]
    Invalid {
        line: usize,
        column: usize,
        /// Dotted TOML key, e.g. `link.silence_timeout_ms`.
        field: String,
        message: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    mode: Mode,
    receivers: u8,
    frame_period_ms: Option<u64>,
    #[serde(default)]
    link: LinkSection,
    #[serde(default)]
    pilot_channel: PilotSection,
    #[serde(default)]
    flight_mode: FlightModeSection,
    #[serde(default)]
    neutral: NeutralSection,
    #[serde(default)]
    ifs: IfsSection,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct LinkSection {
    silence_timeout_ms: Option<u64>,
    acquire_frames: Option<u8>,
    scan_window_ms: Option<u64>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct PilotSection {
    channel: Option<u8>,
    values: Option<Vec<u16>>,
    none: Option<u16>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct FlightModeSection {
    channel: Option<u8>,
    auto_loiter: Option<u16>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct NeutralSection {
    values: Option<Vec<u16>>,
    throttle_channel: Option<u8>,
    throttle: Option<u16>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct IfsSection {
    #[serde(default)]
    channels: Vec<u8>,
}

impl Config {
    /// Reads and validates a configuration file's text.
    pub fn from_toml(text: &str) -> Result<Config, ConfigFileError> {
        let file: File = toml::from_str(text).map_err(|e| {
            let (line, column) = e
                .span()
                .map(|s| line_column(text, s.start))
                .unwrap_or((1, 1));
            ConfigFileError::Syntax {
                line,
                column,
                message: e.message().trim().to_string(),
            }
        })?;
        let invalid = |field: &str, message: String| {
            let (line, column) = locate(text, field);
            ConfigFileError::Invalid {
                line,
                column,
                field: field.to_string(),
                message: format!("{field}: {message}"),
            }
        };
        let from_config_error = |e: ConfigError| invalid(e.field(), strip_field(&e));

        let mut config = Config::new(file.mode, file.receivers);
        // Reject before indexing arrays by it.
        if !(1..=MAX_RECEIVERS as u8).contains(&file.receivers) {
            return Err(invalid(
                "receivers",
                format!("{} is outside 1..={MAX_RECEIVERS}", file.receivers),
            ));
        }
        if let Some(ms) = file.frame_period_ms {
            config.frame_period = Duration::from_millis(ms);
        }
        if let Some(ms) = file.link.silence_timeout_ms {
            config.silence_timeout = Duration::from_millis(ms);
        }
        if let Some(n) = file.link.acquire_frames {
            config.acquire_frames = n;
        }
        if let Some(ms) = file.link.scan_window_ms {
            config.scan_window = Duration::from_millis(ms);
        }
        if let Some(ch) = file.pilot_channel.channel {
            config.pilot_channel = channel_index(ch).ok_or_else(|| {
                invalid("pilot_channel.channel", format!("{ch} is outside 1..=16"))
            })?;
        }
        if let Some(values) = file.pilot_channel.values {
            if values.len() != usize::from(file.receivers) {
                return Err(invalid(
                    "pilot_channel.values",
                    format!(
                        "{} values given for {} receivers",
                        values.len(),
                        file.receivers
                    ),
                ));
            }
            config.pilot_values[..values.len()].copy_from_slice(&values);
        }
        if let Some(v) = file.pilot_channel.none {
            config.no_receiver_value = v;
        }
        if let Some(ch) = file.flight_mode.channel {
            config.flight_mode_channel = channel_index(ch)
                .ok_or_else(|| invalid("flight_mode.channel", format!("{ch} is outside 1..=16")))?;
        }
        if let Some(v) = file.flight_mode.auto_loiter {
            config.auto_loiter_value = v;
        }
        if let Some(values) = file.neutral.values {
            config.neutral = values.as_slice().try_into().map_err(|_| {
                invalid(
                    "neutral.values",
                    format!("{} values given, SBUS has 16 channels", values.len()),
                )
            })?;
        }
        match (file.neutral.throttle_channel, file.neutral.throttle) {
            (Some(ch), Some(value)) => {
                let index = channel_index(ch).ok_or_else(|| {
                    invalid(
                        "neutral.throttle_channel",
                        format!("{ch} is outside 1..=16"),
                    )
                })?;
                config.throttle_channel = Some(index);
                config.neutral[usize::from(index)] = value;
            }
            (None, None) => {}
            (Some(_), None) => {
                return Err(invalid(
                    "neutral.throttle_channel",
                    "given without neutral.throttle, its neutral value".into(),
                ));
            }
            (None, Some(_)) => {
                return Err(invalid(
                    "neutral.throttle",
                    "given without neutral.throttle_channel, the channel it is for".into(),
                ));
            }
        }
        for ch in file.ifs.channels {
            let index = channel_index(ch)
                .ok_or_else(|| invalid("ifs.channels", format!("{ch} is outside 1..=16")))?;
            config.ifs_channels = config.ifs_channels.with(index);
        }
        config.validate().map_err(from_config_error)?;
        Ok(config)
    }

    /// [`Config::from_toml`], then whether it fits a board with `uarts` UART
    /// inputs ([`Config::fits`]); a config that does not is refused at its
    /// `receivers` key.
    pub fn from_toml_for_board(text: &str, uarts: u8) -> Result<Config, ConfigFileError> {
        let config = Config::from_toml(text)?;
        config.fits(uarts).map_err(|e| {
            let (line, column) = locate(text, "receivers");
            ConfigFileError::Invalid {
                line,
                column,
                field: "receivers".into(),
                message: format!("receivers: {e}"),
            }
        })?;
        Ok(config)
    }
}

impl Config {
    /// [`Config::from_toml_for_board`] for a run on real hardware: the file
    /// must also name the throttle channel's neutral (`[neutral]
    /// throttle_channel` and `throttle`), since the default, mid-stick on
    /// every channel, is safe only with a flight controller that flies the
    /// auto-loiter value as a hold (module doc). Refused at `[neutral]` if the
    /// file has that section, else at its first line.
    pub fn from_toml_for_bench(text: &str, uarts: u8) -> Result<Config, ConfigFileError> {
        let config = Config::from_toml_for_board(text, uarts)?;
        if config.throttle_channel.is_none() {
            let field = "neutral.throttle_channel";
            let (line, column) = locate(text, field);
            return Err(ConfigFileError::Invalid {
                line,
                column,
                field: field.into(),
                message: format!(
                    "{field}: a run on real hardware needs the throttle channel's neutral named \
                     (e.g. [neutral] throttle_channel = 3, throttle = 992): the default, {} on every \
                     channel, is mid throttle, which holds altitude only if the flight controller \
                     flies flight_mode.auto_loiter = {} on channel {} as a position/altitude hold, \
                     and is about half thrust in a manual or stabilised mode",
                    super::RAW_CENTER,
                    config.auto_loiter_value,
                    config.flight_mode_channel + 1
                ),
            });
        }
        Ok(config)
    }
}

fn channel_index(one_based: u8) -> Option<u8> {
    (1..=16).contains(&one_based).then(|| one_based - 1)
}

/// The error's text without its leading `field: `, which `invalid` adds back.
fn strip_field(e: &ConfigError) -> String {
    let text = e.to_string();
    let prefix = format!("{}: ", e.field());
    text.strip_prefix(&prefix).unwrap_or(&text).to_string()
}

fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Line and column of a dotted key in `text`; of its closest present parent
/// when the key itself is absent (a default that failed validation), else 1:1.
fn locate(text: &str, dotted: &str) -> (usize, usize) {
    let Ok(root) = toml::de::DeTable::parse(text) else {
        return (1, 1);
    };
    let mut table = root.get_ref();
    let mut found = None;
    for part in dotted.split('.') {
        let Some((key, value)) = table.iter().find(|(k, _)| k.get_ref() == part) else {
            break;
        };
        found = Some(key.span().start);
        match value.get_ref() {
            toml::de::DeValue::Table(inner) => table = inner,
            _ => break,
        }
    }
    found.map_or((1, 1), |offset| line_column(text, offset))
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "mode = \"scan\"\nreceivers = 2\n\n[link]\nscan_window_ms = 1500\n\n[pilot_channel]\nchannel = 8\nvalues = [300, 600]\nnone = 100\n\n[ifs]\nchannels = [5, 6]\n";

    #[test]
    fn reads_a_full_file() {
        let c = Config::from_toml(GOOD).unwrap();
        assert_eq!(c.mode, Mode::Scan);
        assert_eq!(c.receivers, 2);
        assert_eq!(c.scan_window, Duration::from_millis(1500));
        assert_eq!(c.pilot_channel, 7);
        assert_eq!(&c.pilot_values[..2], &[300, 600]);
        assert_eq!(c.no_receiver_value, 100);
        assert!(c.ifs_channels.contains(4) && c.ifs_channels.contains(5));
    }

    #[test]
    fn the_throttle_neutral_is_named_with_its_channel() {
        let text =
            "mode = \"scan\"\nreceivers = 2\n[neutral]\nthrottle_channel = 3\nthrottle = 172\n";
        let c = Config::from_toml(text).unwrap();
        assert_eq!(c.throttle_channel, Some(2));
        assert_eq!(c.neutral[2], 172);
        assert_eq!(c.neutral[0], crate::config::RAW_CENTER);
        // On the bench too.
        assert_eq!(Config::from_toml_for_bench(text, 6).unwrap(), c);

        let half = "mode = \"scan\"\nreceivers = 2\n[neutral]\nthrottle_channel = 3\n";
        assert_eq!(
            Config::from_toml(half).unwrap_err().to_string(),
            "4:1: neutral.throttle_channel: given without neutral.throttle, its neutral value"
        );
        let clash =
            "mode = \"scan\"\nreceivers = 2\n[neutral]\nthrottle_channel = 5\nthrottle = 992\n";
        let err = Config::from_toml(clash).unwrap_err().to_string();
        assert!(
            err.contains("neutral.throttle_channel") && err.contains("flight-mode"),
            "{err}"
        );
    }

    #[test]
    fn a_bench_config_without_the_throttle_neutral_is_refused_at_its_line() {
        // The default neutral, mid-stick, flies; it is only refused for real hardware.
        let text = "mode = \"scan\"\nreceivers = 2\n\n[neutral]\nvalues = [992, 992, 992, 992, 1811, 992, 992, 992, 992, 172, 992, 992, 992, 992, 992, 992]\n";
        assert!(Config::from_toml_for_board(text, 6).is_ok());
        let err = Config::from_toml_for_bench(text, 6).unwrap_err();
        let shown = err.to_string();
        assert!(
            shown.starts_with("4:2: neutral.throttle_channel: "),
            "{shown}"
        );
        assert!(
            shown.contains("channel 5") && shown.contains("1811"),
            "{shown}"
        );
        // No [neutral] at all: the file's first line.
        let err = Config::from_toml_for_bench("mode = \"scan\"\nreceivers = 2\n", 6).unwrap_err();
        assert!(
            err.to_string().starts_with("1:1: neutral.throttle_channel"),
            "{err}"
        );
    }

    #[test]
    fn unknown_key_is_a_syntax_error_with_its_line() {
        let text = "mode = \"scan\"\nreceivers = 2\n[link]\nsilence_timeout = 60\n";
        match Config::from_toml(text).unwrap_err() {
            ConfigFileError::Syntax { line, message, .. } => {
                assert_eq!(line, 4);
                assert!(message.contains("silence_timeout"), "{message}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn invalid_value_names_field_and_line() {
        let text = "mode = \"parallel\"\nreceivers = 2\n\n[link]\nacquire_frames = 3\nsilence_timeout_ms = 5\n";
        let err = Config::from_toml(text).unwrap_err();
        assert_eq!(
            err.to_string(),
            "6:1: link.silence_timeout_ms: 5 is outside 20..=1000"
        );
    }

    #[test]
    fn wrong_count_of_pilot_values() {
        let text = "mode = \"parallel\"\nreceivers = 3\n[pilot_channel]\nvalues = [300, 600]\n";
        let err = Config::from_toml(text).unwrap_err();
        assert_eq!(
            err.to_string(),
            "4:1: pilot_channel.values: 2 values given for 3 receivers"
        );
    }

    #[test]
    fn channel_zero_is_refused() {
        let text = "mode = \"parallel\"\nreceivers = 1\n[flight_mode]\nchannel = 0\n";
        let err = Config::from_toml(text).unwrap_err();
        assert_eq!(
            err.to_string(),
            "4:1: flight_mode.channel: 0 is outside 1..=16"
        );
    }

    #[test]
    fn a_config_too_large_for_the_board_names_receivers() {
        let text = "mode = \"scan\"\nreceivers = 6\n[ifs]\nchannels = [5]\n";
        Config::from_toml(text).unwrap();
        let err = Config::from_toml_for_board(text, crate::board::SAMD21_UARTS).unwrap_err();
        assert_eq!(
            err.to_string(),
            "2:1: receivers: 6 receivers and an [ifs] input need 7 UART inputs; the board has 6, so at most 5 receivers with [ifs]"
        );
    }

    #[test]
    fn too_many_receivers() {
        let err = Config::from_toml("mode = \"scan\"\nreceivers = 9\n").unwrap_err();
        assert_eq!(err.to_string(), "2:1: receivers: 9 is outside 1..=6");
    }
}
