//! The binaries' options, each declared once: one struct per binary is both its clap parser
//! and its serde config file, and the options both binaries take are one struct,
//! [`RadioOptions`], in each. Flags win over the keys of the TOML file named by `--config`,
//! which win over the defaults; config-file keys are the flags' names with `_` (clap's ids,
//! which are also the fields' names).

use crate::Duration;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;

use super::{SigningStateFile, StatusReport, run_main};
use crate::schedule::SchedulerConfig;
use crate::signing::SigningConfig;

/// Options of both binaries: the config file, the radio port and budget, link-quality
/// reports, status lines and signing. Read from a config file beside the binary's own options
/// (which mark this field `#[serde(skip)]`); unknown keys are rejected by [`main`].
#[derive(clap::Args, serde::Deserialize, Default, Debug)]
pub struct RadioOptions {
    /// TOML file with any of the options below (flags win).
    #[arg(long)]
    #[serde(skip)]
    pub config: Option<PathBuf>,
    /// Radio serial device (or pty path).
    #[arg(long)]
    pub radio: Option<String>,
    /// Radio baud rate [default: 57600].
    #[arg(long)]
    pub radio_baud: Option<u32>,
    /// Radio budget of what this side sends, in bytes per second [default: 683, a LoRa SF7
    /// channel].
    #[arg(long)]
    pub rate: Option<u32>,
    /// Radio burst in bytes [default: 600].
    #[arg(long)]
    pub burst: Option<u32>,
    /// Most the radio may hold unsent, in ms at --rate, before the next frame is handed to it:
    /// a backlog waits in the bridge or router, where commands and a mode change overtake it,
    /// not in the radio's buffer, where nothing does; 0: no limit but --burst [default: the
    /// bridge 200, so a change of mode reaches the ground in ~0.5 s on LoRa SF7; the router 0].
    #[arg(long)]
    pub radio_backlog_ms: Option<u32>,
    /// Longest time between LINK_QUALITY reports (the keep-alive; reports go early when the
    /// loss changes or the peer goes quiet), 0.1..=86400 s [default: 0.4 % of --rate:
    /// 8.8 s at 683 B/s, 13.5 s signed].
    #[arg(long)]
    pub link_quality_period: Option<Seconds>,
    /// Seconds between status lines, 0.1..=86400 [default: 5].
    #[arg(long)]
    pub status_interval: Option<Seconds>,
    /// Also write the status as JSON lines to this file, created or truncated (`-`: stdout):
    /// a start line, a status line every --status-interval and a stop line; schema
    /// `c2-status/1`, every field in firmware/hostio/STATUS-JSON.md.
    #[arg(long)]
    pub status_json: Option<PathBuf>,
    /// MAVLink 2 signing key file for the radio link (64 hex characters, mode 600): our
    /// radio frames are signed, unsigned or replayed ones from the radio are dropped.
    /// Required unless --unsigned.
    #[arg(long)]
    pub key: Option<PathBuf>,
    /// Run the radio leg without signing (bench and lab only: anyone on the channel can
    /// command the drone). Shown on every status line as `signing="OFF"`.
    #[arg(long, num_args = 0, default_missing_value = "true")]
    pub unsigned: Option<bool>,
    /// Signing state file: the last timestamp and the streams accepted, so a restart neither
    /// reuses timestamps nor accepts frames captured before it [default: <key>.<role>-state].
    #[arg(long)]
    pub signing_state: Option<PathBuf>,
}

/// The radio link's signing as the options set it up.
#[derive(Debug)]
pub struct RadioSigning {
    /// Signing settings, `None` with `--unsigned`.
    pub config: Option<SigningConfig>,
    /// Where the state is stored, `None` with `--unsigned`.
    pub state_file: Option<SigningStateFile>,
}

impl RadioSigning {
    /// For the status line: `on` or `OFF`.
    pub fn label(&self) -> &'static str {
        if self.config.is_some() { "on" } else { "OFF" }
    }
}

impl RadioOptions {
    /// The radio's serial device: required.
    pub fn radio_port(&self) -> anyhow::Result<String> {
        self.radio
            .clone()
            .context("no radio port: --radio or `radio`")
    }

    /// The radio's baud rate.
    pub fn radio_baud(&self) -> u32 {
        self.radio_baud.unwrap_or(57_600)
    }

    /// Bytes per second this side may send over the radio.
    pub fn rate(&self) -> u32 {
        self.rate.unwrap_or(683)
    }

    /// Burst in bytes.
    pub fn burst(&self) -> u32 {
        self.burst.unwrap_or(600)
    }

    /// The most the radio may hold unsent (`None`: no limit but the burst), `default` unless
    /// the option says.
    pub fn radio_backlog(&self, default: Option<Duration>) -> Option<Duration> {
        match self.radio_backlog_ms {
            None => default,
            Some(0) => None,
            Some(ms) => Some(Duration::from_millis(ms.into())),
        }
    }

    /// The radio budget scheduler's settings: a rate of at least 1 byte/s and a burst that
    /// holds one largest frame.
    pub fn scheduler(&self) -> Result<SchedulerConfig, UsageError> {
        if self.rate() == 0 {
            return Err(UsageError::option("rate", "0 bytes/s: must be at least 1"));
        }
        if (self.burst() as usize) < crate::wire::MAX_FRAME_LEN {
            return Err(UsageError::option(
                "burst",
                format!(
                    "{} bytes: must hold one largest MAVLink frame ({} bytes)",
                    self.burst(),
                    crate::wire::MAX_FRAME_LEN
                ),
            ));
        }
        Ok(SchedulerConfig::for_radio(self.rate(), self.burst()))
    }

    /// Link-quality settings for this side's radio budget (signed reports are longer), with
    /// `--link-quality-period` as the keep-alive when given.
    pub fn link_quality(&self, signed: bool) -> crate::quality::LinkQualityConfig {
        let mut q = crate::quality::LinkQualityConfig::for_budget(self.rate(), signed);
        if let Some(period) = self.link_quality_period() {
            q = crate::quality::LinkQualityConfig {
                period,
                window: Duration::from_secs(4).max(period * 2),
                quiet_after: (period * 3) / 2 + Duration::from_millis(500),
                peer_timeout: (period * 5) / 2 + Duration::from_secs(5),
                ..q
            };
        }
        q
    }

    /// Time between `LINK_QUALITY` reports, when given (the engine has its default).
    pub fn link_quality_period(&self) -> Option<Duration> {
        self.link_quality_period.map(Duration::from)
    }

    /// What the start line shows of these options, defaults applied (STATUS-JSON.md).
    pub fn start_options(&self) -> serde_json::Value {
        serde_json::json!({
            "radio": self.radio,
            "radio_baud": self.radio_baud(),
            "rate": self.rate(),
            "burst": self.burst(),
            "signing": if self.unsigned.unwrap_or(false) { "OFF" } else { "on" },
            "status_interval_s": self.status_every().as_secs_f64(),
        })
    }

    /// Time between status lines.
    pub fn status_every(&self) -> Duration {
        self.status_interval
            .map_or(Duration::from_secs(5), Duration::from)
    }

    /// Radio link signing as link `link_id`: with the key file and the state file (default
    /// `<key>.<role>-state`), which is read, locked and written once at once (so a state
    /// path that cannot be written fails now, not at the first save). No key is a usage
    /// error unless `--unsigned` says so.
    pub fn signing(&self, link_id: u8, role: &str) -> anyhow::Result<RadioSigning> {
        let unsigned = self.unsigned.unwrap_or(false);
        let key = match (&self.key, unsigned) {
            (Some(_), true) => {
                return Err(UsageError::option(
                    "unsigned",
                    "given together with --key / `key`: choose one",
                )
                .into());
            }
            (None, true) => {
                if self.signing_state.is_some() {
                    return Err(
                        UsageError::option("signing_state", "has no use with --unsigned").into(),
                    );
                }
                tracing::warn!(
                    "radio link NOT signed (--unsigned): anyone on the radio channel can inject and replay frames"
                );
                return Ok(RadioSigning {
                    config: None,
                    state_file: None,
                });
            }
            (None, false) => {
                return Err(UsageError::option(
                    "key",
                    "the radio link is signed: give a key file (--key / `key`), or \
                     --unsigned / `unsigned = true` to run it without signing",
                )
                .into());
            }
            (Some(key), false) => key,
        };
        let path = self
            .signing_state
            .clone()
            .unwrap_or_else(|| SigningStateFile::default_path(key, role));
        let (file, config) =
            SigningStateFile::resume(path, crate::signing::SigningKey::load(key)?, link_id)?;
        tracing::info!(key = %key.display(), "radio link signing on");
        Ok(RadioSigning {
            config: Some(config),
            state_file: Some(file),
        })
    }
}

/// A period option in seconds: a finite number within [`Seconds::MIN`] ..= [`Seconds::MAX`],
/// checked where it is read (a flag: clap reports it; a config-file key: the file's line),
/// so that no out-of-range value reaches `Duration::from_secs_f64` (which panics on
/// negative, infinite or huge values) or a busy loop.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(try_from = "f64")]
pub struct Seconds(Duration);

impl Seconds {
    /// The shortest period an option takes.
    pub const MIN: f64 = 0.1;
    /// The longest period an option takes (one day).
    pub const MAX: f64 = 86_400.0;
}

/// A period out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0} is not a number of seconds in 0.1..=86400")]
pub struct SecondsError(String);

impl TryFrom<f64> for Seconds {
    type Error = SecondsError;

    fn try_from(s: f64) -> Result<Self, Self::Error> {
        if (Self::MIN..=Self::MAX).contains(&s) {
            Ok(Self(Duration::from_secs_f64(s)))
        } else {
            Err(SecondsError(s.to_string()))
        }
    }
}

impl std::str::FromStr for Seconds {
    type Err = SecondsError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let value: f64 = s.trim().parse().map_err(|_| SecondsError(s.to_owned()))?;
        Self::try_from(value)
    }
}

impl From<Seconds> for Duration {
    fn from(s: Seconds) -> Self {
        s.0
    }
}

/// A loss threshold in percent: a finite number in 0..=100, checked where it is read.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(try_from = "f64")]
pub struct Percent(f64);

impl Percent {
    /// As a fraction, 0..=1.
    pub fn fraction(self) -> f64 {
        self.0 / 100.0
    }
}

/// A percentage out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0} is not a percentage in 0..=100")]
pub struct PercentError(String);

impl TryFrom<f64> for Percent {
    type Error = PercentError;

    fn try_from(p: f64) -> Result<Self, Self::Error> {
        if (0.0..=100.0).contains(&p) {
            Ok(Self(p))
        } else {
            Err(PercentError(p.to_string()))
        }
    }
}

impl std::str::FromStr for Percent {
    type Err = PercentError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let value: f64 = s.trim().parse().map_err(|_| PercentError(s.to_owned()))?;
        Self::try_from(value)
    }
}

/// A rise in decibels: a finite number in 0..=60, checked where it is read.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(try_from = "f64")]
pub struct Decibels(f64);

impl Decibels {
    /// The value, dB.
    pub fn db(self) -> f64 {
        self.0
    }
}

/// A decibel value out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0} is not a rise in dB in 0..=60")]
pub struct DecibelsError(String);

impl TryFrom<f64> for Decibels {
    type Error = DecibelsError;

    fn try_from(db: f64) -> Result<Self, Self::Error> {
        if (0.0..=60.0).contains(&db) {
            Ok(Self(db))
        } else {
            Err(DecibelsError(db.to_string()))
        }
    }
}

impl std::str::FromStr for Decibels {
    type Err = DecibelsError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let value: f64 = s.trim().parse().map_err(|_| DecibelsError(s.to_owned()))?;
        Self::try_from(value)
    }
}

/// A bad value the types let through, or a bad config file: exit status 2, like clap's
/// usage errors. The message names the option (`--flag` / `key`) or `file:line`.
#[derive(Debug, thiserror::Error)]
pub enum UsageError {
    /// An option's value out of its range.
    #[error("--{flag} / `{key}`: {reason}")]
    Option {
        /// The flag's name (without `--`).
        flag: String,
        /// The config-file key.
        key: String,
        /// What is wrong.
        reason: String,
    },
    /// A config file that does not read or parse, or holds a bad value.
    #[error("{path}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Config {
        /// The file.
        path: String,
        /// 1-based line of the fault, when known.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
}

impl UsageError {
    /// An option `id` (clap's id, the config-file key) out of range.
    pub fn option(id: &str, reason: impl Into<String>) -> Self {
        Self::Option {
            flag: id.replace('_', "-"),
            key: id.to_owned(),
            reason: reason.into(),
        }
    }
}

/// A binary: its options (one struct, both its clap parser and its config file's serde
/// schema), and what it runs with them.
pub trait Program: clap::Parser + serde::de::DeserializeOwned + Default {
    /// Its name on the status lines.
    const NAME: &'static str;
    /// Where its [`RadioOptions`] are.
    fn shared(&mut self) -> &mut RadioOptions;
    /// Its own options that matter on its start line, beside the [`RadioOptions`]' (effective
    /// values, defaults applied).
    fn start_options(&self) -> serde_json::Value;
    /// Runs it; it reports its status to `report` and ends with the stop line's final status.
    fn run(self, report: &mut StatusReport) -> anyhow::Result<()>;
}

/// A binary's `main`: parses its options `P` (bad usage exits with 2), then, with logging
/// set up, reads the config file `--config` names under the flags, opens the status file
/// (`--status-json`) with its start line and calls [`Program::run`] (an error exits with 1 or
/// 2, see [`run_main`]). A program that ends before it got running still gets its stop line,
/// with the error.
pub fn main<P: Program>() -> ExitCode {
    let matches = P::command().get_matches();
    run_main(|| {
        let mut options: P = load_options(&matches, P::shared)?;
        let mut report = StatusReport::open(P::NAME, options.shared().status_json.as_deref())?;
        let mut shown = options.shared().start_options();
        if let (serde_json::Value::Object(all), serde_json::Value::Object(own)) =
            (&mut shown, options.start_options())
        {
            all.extend(own);
        }
        report.start(&shown)?;
        let result = options.run(&mut report);
        report.stop::<()>(None, &result);
        result
    })
}

/// The options given in `matches`, over those of the config file they name, over
/// `T::default()` (every option `None`).
fn load_options<T>(
    matches: &clap::ArgMatches,
    shared: fn(&mut T) -> &mut RadioOptions,
) -> anyhow::Result<T>
where
    T: clap::Parser + serde::de::DeserializeOwned + Default,
{
    let mut flags = T::from_arg_matches(matches)?;
    let mut options = match shared(&mut flags).config.take() {
        Some(path) => load_config(&path, shared)?,
        None => T::default(),
    };
    // Sets only the options given on the command line: absent ones have no default in clap.
    options.update_from_arg_matches(matches)?;
    Ok(options)
}

/// Reads a binary's TOML config file: its own options and the [`RadioOptions`] (not
/// `#[serde(flatten)]`, which would lose the location of a bad value); a key that is neither
/// is an error naming the file, line and key.
fn load_config<T>(path: &Path, shared: fn(&mut T) -> &mut RadioOptions) -> anyhow::Result<T>
where
    T: clap::CommandFactory + serde::de::DeserializeOwned,
{
    use serde::Deserializer as _;
    let text =
        crate::input_file::read_to_string(path, crate::input_file::MAX_TEXT_FILE).map_err(|e| {
            UsageError::Config {
                path: path.display().to_string(),
                line: None,
                message: format!("cannot read: {e}"),
            }
        })?;
    let in_file = |e: toml::de::Error| {
        let start = e.span().map(|span| span.start.min(text.len()));
        // The key on the line at fault, when the fault is in a `key = value` line.
        let key = start
            .and_then(|at| text[..at].rsplit('\n').next())
            .and_then(|before| before.split_once('='))
            .map(|(key, _)| format!("`{}`: ", key.trim()))
            .unwrap_or_default();
        UsageError::Config {
            path: path.display().to_string(),
            line: start.map(|at| text[..at].matches('\n').count() + 1),
            message: format!("{key}{}", e.message().trim()),
        }
    };
    let keys: Vec<String> = T::command()
        .get_arguments()
        .map(|a| a.get_id().to_string())
        .filter(|id| id != "config")
        .collect();
    toml::Deserializer::parse(&text)
        .and_then(|d| d.deserialize_map(KnownKeys(&keys)))
        .map_err(in_file)?;
    let mut options: T = toml::from_str(&text).map_err(in_file)?;
    *shared(&mut options) = toml::from_str(&text).map_err(in_file)?;
    Ok(options)
}

/// A table whose keys must be among the given ones; values are not looked at.
struct KnownKeys<'a>(&'a [String]);

impl<'de> serde::de::Visitor<'de> for KnownKeys<'_> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a table of options")
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while map.next_key_seed(KnownKey(self.0))?.is_some() {
            map.next_value::<serde::de::IgnoredAny>()?;
        }
        Ok(())
    }
}

/// One key of [`KnownKeys`]: the error comes from the key, so it carries the key's location.
struct KnownKey<'a>(&'a [String]);

impl<'de> serde::de::DeserializeSeed<'de> for KnownKey<'_> {
    type Value = ();

    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        use serde::Deserialize as _;
        let key = String::deserialize(d)?;
        if self.0.contains(&key) {
            return Ok(());
        }
        let known: Vec<String> = self.0.iter().map(|k| format!("`{k}`")).collect();
        Err(serde::de::Error::custom(format!(
            "unknown field `{key}`, expected one of {}",
            known.join(", ")
        )))
    }
}
