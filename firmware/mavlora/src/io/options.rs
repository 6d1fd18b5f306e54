//! The binaries' options, each declared once: one struct per binary is both its clap parser
//! and its serde config file, and the options both binaries take are one struct,
//! [`RadioOptions`], in each. Flags win over the keys of the TOML file named by `--config`,
//! which win over the defaults; config-file keys are the flags' names with `_` (clap's ids,
//! which are also the fields' names).

use crate::Duration;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;

use super::{run_main, signing_from_key_file};
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
    /// Seconds between LINK_QUALITY reports [default: 5].
    #[arg(long)]
    pub link_quality_period: Option<f64>,
    /// Seconds between status lines [default: 5].
    #[arg(long)]
    pub status_interval: Option<f64>,
    /// MAVLink 2 signing key file (64 hex characters or 32 bytes) for the radio link: our
    /// radio frames are signed, unsigned or replayed ones from the radio are dropped.
    #[arg(long)]
    pub key: Option<PathBuf>,
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

    /// The radio budget scheduler's settings.
    pub fn scheduler(&self) -> SchedulerConfig {
        SchedulerConfig::for_radio(self.rate(), self.burst())
    }

    /// Time between `LINK_QUALITY` reports, when given (the engine has its default).
    pub fn link_quality_period(&self) -> Option<Duration> {
        self.link_quality_period.map(Duration::from_secs_f64)
    }

    /// Time between status lines.
    pub fn status_every(&self) -> Duration {
        Duration::from_secs_f64(self.status_interval.unwrap_or(5.0))
    }

    /// Radio link signing with the key file, when given, as link `link_id`.
    pub fn signing(&self, link_id: u8) -> anyhow::Result<Option<SigningConfig>> {
        self.key
            .as_deref()
            .map(|path| signing_from_key_file(path, link_id))
            .transpose()
    }
}

/// A binary's `main`: parses its options `T` (bad usage exits with 2), then, with logging
/// set up, reads the config file `--config` names under the flags and calls `run` (an error
/// exits with 1, see [`run_main`]). `shared` finds the [`RadioOptions`] in a `T`.
pub fn main<T>(
    shared: fn(&mut T) -> &mut RadioOptions,
    run: fn(T) -> anyhow::Result<()>,
) -> ExitCode
where
    T: clap::Parser + serde::de::DeserializeOwned + Default,
{
    let matches = T::command().get_matches();
    run_main(|| run(load_options(&matches, shared)?))
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
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading config {}", path.display()))?;
    let in_file = |e: toml::de::Error| anyhow::anyhow!("{}: {e}", path.display());
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
