//! MultiRX configuration: what the paper kept in a config file compiled into
//! the firmware. The firmware's build script and the emulated device both read
//! the same TOML file ([`Config::from_toml`], feature `toml`) and both run
//! [`Config::validate`], so a bad value fails the build or the start, never a flight.

#[cfg(feature = "toml")]
mod file;
mod literal;

#[cfg(feature = "toml")]
pub use file::ConfigFileError;

use crate::time::Duration;
use crate::wire::Channels;

/// Receivers a MultiRX can multiplex: as many as the board has UARTs (with
/// an IFS input, one fewer: see [`Config::fits`]).
pub const MAX_RECEIVERS: usize = crate::board::SAMD21_UARTS as usize;

/// How receivers are used. Named in config and rig files as `"parallel"` or `"scan"`
/// ([`Mode::as_str`], [`Display`](core::fmt::Display), [`FromStr`](core::str::FromStr), and
/// serde with feature `toml`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(
    feature = "toml",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "lowercase")
)]
pub enum Mode {
    /// Every receiver powered and monitored on its own UART; hand over as soon
    /// as the active one reports failsafe or falls silent.
    Parallel,
    /// The paper's design: one receiver powered at a time; with none active,
    /// power each in turn and listen for a window.
    Scan,
}

impl Mode {
    /// Both modes, in the order the rig runs their suites by default.
    pub const ALL: [Mode; 2] = [Mode::Parallel, Mode::Scan];

    /// Lower-case name, as in config files, rig files and measurement names.
    pub const fn as_str(self) -> &'static str {
        match self {
            Mode::Parallel => "parallel",
            Mode::Scan => "scan",
        }
    }
}

impl core::fmt::Display for Mode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A mode name that is neither `parallel` nor `scan`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("unknown mode, expected `parallel` or `scan`")]
pub struct UnknownMode;

impl core::str::FromStr for Mode {
    type Err = UnknownMode;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Mode::ALL
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or(UnknownMode)
    }
}

/// A set of channels, by 0-based index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct ChannelSet(pub u16);

impl ChannelSet {
    pub const EMPTY: ChannelSet = ChannelSet(0);

    pub const fn contains(self, channel: u8) -> bool {
        channel < 16 && self.0 & (1 << channel) != 0
    }

    #[must_use]
    pub const fn with(self, channel: u8) -> Self {
        ChannelSet(self.0 | (1 << (channel & 15)))
    }

    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Channels in the set, ascending.
    pub fn iter(self) -> impl Iterator<Item = u8> {
        (0..16u8).filter(move |&c| self.contains(c))
    }
}

/// Everything MultiRX needs to know; channel numbers here are 0-based
/// (the TOML file uses the 1-based numbers pilots use).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Config {
    pub mode: Mode,
    /// Receivers wired, 1..=6.
    pub receivers: u8,
    /// Output period towards the flight controller (7 ms high speed, 14 ms normal).
    pub frame_period: Duration,
    /// A receiver that sent no frame for this long has lost its link.
    pub silence_timeout: Duration,
    /// Scan mode: how long to listen to a freshly powered receiver.
    pub scan_window: Duration,
    /// Consecutive valid frames before a receiver counts as having a link.
    pub acquire_frames: u8,
    /// Channel rewritten to say which receiver is active.
    pub pilot_channel: u8,
    /// Pilot channel value for each receiver.
    pub pilot_values: [u16; MAX_RECEIVERS],
    /// Pilot channel value when no receiver is active.
    pub no_receiver_value: u16,
    /// The flight-mode channel.
    pub flight_mode_channel: u8,
    /// Flight-mode channel value that selects auto-loiter (hold position).
    pub auto_loiter_value: u16,
    /// Channel values sent while no receiver is active (neutral sticks). 992
    /// (mid-stick) on every channel by default, throttle included: that holds
    /// the aircraft only if the flight controller flies the auto-loiter value
    /// of the flight-mode channel as a position/altitude hold, where mid
    /// throttle means "keep altitude". In a manual or stabilised mode mid
    /// throttle is about half thrust. So the throttle's neutral is named
    /// apart ([`Config::throttle_channel`]), and a bench run requires it.
    pub neutral: Channels,
    /// The channel the flight controller reads as throttle, when the config
    /// file names it with its neutral (`[neutral] throttle_channel`,
    /// `throttle`); `None` when it leaves the throttle at the default neutral.
    pub throttle_channel: Option<u8>,
    /// Channels the independent fail-safe system may override.
    pub ifs_channels: ChannelSet,
}

/// Lowest raw value receivers send (≈ 1000 µs on PX4).
pub const RAW_MIN: u16 = 172;
/// Highest raw value receivers send (≈ 2000 µs on PX4).
pub const RAW_MAX: u16 = 1811;
/// Centre value (≈ 1494 µs on PX4).
pub const RAW_CENTER: u16 = 992;

impl Config {
    /// Defaults for `receivers` receivers in `mode`: 7 ms output, 60 ms silence
    /// timeout, 2 s scan window, pilot channel 10, flight-mode channel 5.
    pub fn new(mode: Mode, receivers: u8) -> Self {
        Config {
            mode,
            receivers,
            frame_period: Duration::from_millis(7),
            silence_timeout: Duration::from_millis(60),
            scan_window: Duration::from_millis(2000),
            acquire_frames: 3,
            pilot_channel: 9,
            pilot_values: default_pilot_values(),
            no_receiver_value: RAW_MIN,
            flight_mode_channel: 4,
            auto_loiter_value: RAW_MAX,
            neutral: [RAW_CENTER; 16],
            throttle_channel: None,
            ifs_channels: ChannelSet::EMPTY,
        }
    }

    /// Receiver indices in use.
    pub fn receiver_indices(&self) -> core::ops::Range<u8> {
        0..self.receivers
    }

    /// Checks every field; the error names the TOML field at fault.
    pub fn validate(&self) -> Result<(), ConfigError> {
        range("receivers", self.receivers.into(), 1, MAX_RECEIVERS as u32)?;
        range(
            "frame_period_ms",
            self.frame_period.as_millis() as u32,
            5,
            20,
        )?;
        range(
            "link.silence_timeout_ms",
            self.silence_timeout.as_millis() as u32,
            20,
            1000,
        )?;
        range(
            "link.scan_window_ms",
            self.scan_window.as_millis() as u32,
            200,
            10_000,
        )?;
        if self.scan_window <= self.silence_timeout {
            return Err(ConfigError::Inconsistent {
                field: "link.scan_window_ms",
                reason: "must be longer than link.silence_timeout_ms",
            });
        }
        range("link.acquire_frames", self.acquire_frames.into(), 1, 20)?;
        range(
            "pilot_channel.channel",
            u32::from(self.pilot_channel) + 1,
            1,
            16,
        )?;
        range(
            "flight_mode.channel",
            u32::from(self.flight_mode_channel) + 1,
            1,
            16,
        )?;
        if self.pilot_channel == self.flight_mode_channel {
            return Err(ConfigError::ChannelClash {
                field: "flight_mode.channel",
                channel: self.flight_mode_channel + 1,
                other: "the pilot channel",
            });
        }
        if let Some(throttle) = self.throttle_channel {
            range("neutral.throttle_channel", u32::from(throttle) + 1, 1, 16)?;
            for (channel, other) in [
                (self.pilot_channel, "the pilot channel"),
                (self.flight_mode_channel, "the flight-mode channel"),
            ] {
                if throttle == channel {
                    return Err(ConfigError::ChannelClash {
                        field: "neutral.throttle_channel",
                        channel: throttle + 1,
                        other,
                    });
                }
            }
        }
        if self.ifs_channels.contains(self.pilot_channel) {
            return Err(ConfigError::ChannelClash {
                field: "ifs.channels",
                channel: self.pilot_channel + 1,
                other: "the pilot channel, which only MultiRX may set",
            });
        }
        let max = u32::from(crate::wire::SbusFrame::<&[u8]>::MAX_VALUE);
        range("pilot_channel.none", self.no_receiver_value.into(), 0, max)?;
        range(
            "flight_mode.auto_loiter",
            self.auto_loiter_value.into(),
            0,
            max,
        )?;
        for value in self.neutral {
            range("neutral.values", value.into(), 0, max)?;
        }
        let used = &self.pilot_values[..usize::from(self.receivers)];
        for (i, &value) in used.iter().enumerate() {
            range("pilot_channel.values", value.into(), 0, max)?;
            if value == self.no_receiver_value || used[..i].contains(&value) {
                return Err(ConfigError::DuplicatePilotValue {
                    field: "pilot_channel.values",
                    value,
                });
            }
        }
        Ok(())
    }
}

/// Evenly spread over the stick range so a ground station can tell them apart
/// at a glance: none = 172, receivers 445, 718, 991, 1264, 1537, 1810.
pub const fn default_pilot_values() -> [u16; MAX_RECEIVERS] {
    let mut values = [0u16; MAX_RECEIVERS];
    let mut i = 0;
    while i < MAX_RECEIVERS {
        values[i] = RAW_MIN + (i as u16 + 1) * 273;
        i += 1;
    }
    values
}

fn range(field: &'static str, value: u32, min: u32, max: u32) -> Result<(), ConfigError> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(ConfigError::OutOfRange {
            field,
            value,
            min,
            max,
        })
    }
}

/// A configuration value MultiRX cannot fly with. `field` is the TOML key.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// A number outside what the hardware or the protocol allows.
    #[error("{field}: {value} is outside {min}..={max}")]
    OutOfRange {
        field: &'static str,
        value: u32,
        min: u32,
        max: u32,
    },
    /// One channel given two jobs (1-based channel number).
    #[error("{field}: channel {channel} is already {other}")]
    ChannelClash {
        field: &'static str,
        channel: u8,
        other: &'static str,
    },
    /// Two receivers, or a receiver and "none", share a pilot-channel value.
    #[error("{field}: value {value} is used twice; each receiver and 'none' need their own")]
    DuplicatePilotValue { field: &'static str, value: u16 },
    /// Values that are each fine but not together.
    #[error("{field}: {reason}")]
    Inconsistent {
        field: &'static str,
        reason: &'static str,
    },
}

impl ConfigError {
    /// The TOML key at fault, for locating it in the file.
    pub fn field(&self) -> &'static str {
        match self {
            ConfigError::OutOfRange { field, .. }
            | ConfigError::ChannelClash { field, .. }
            | ConfigError::DuplicatePilotValue { field, .. }
            | ConfigError::Inconsistent { field, .. } => field,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mode_names_round_trip() {
        for mode in Mode::ALL {
            assert_eq!(mode.as_str().parse(), Ok(mode));
            assert_eq!(format!("{mode}"), mode.as_str());
        }
        assert_eq!("Scan".parse::<Mode>(), Err(UnknownMode));
    }

    #[test]
    fn defaults_are_valid_for_every_receiver_count() {
        for n in 1..=6 {
            for mode in [Mode::Parallel, Mode::Scan] {
                Config::new(mode, n).validate().unwrap();
            }
        }
    }

    #[test]
    fn errors_name_the_field() {
        let mut c = Config::new(Mode::Parallel, 7);
        assert_eq!(c.validate().unwrap_err().field(), "receivers");
        c.receivers = 2;
        c.flight_mode_channel = c.pilot_channel;
        assert_eq!(c.validate().unwrap_err().field(), "flight_mode.channel");
        c.flight_mode_channel = 4;
        c.pilot_values[1] = c.pilot_values[0];
        let err = c.validate().unwrap_err();
        assert_eq!(err.field(), "pilot_channel.values");
        c.pilot_values = default_pilot_values();
        c.ifs_channels = ChannelSet::EMPTY.with(c.pilot_channel);
        assert_eq!(c.validate().unwrap_err().field(), "ifs.channels");
    }

    #[test]
    fn unused_pilot_values_may_repeat() {
        let mut c = Config::new(Mode::Scan, 2);
        c.pilot_values[4] = c.pilot_values[5];
        c.validate().unwrap();
    }
}
