//! SiK firmware (ArduPilot SiK 2.x: mRo, Holybro, RFD900 radios) as the host sees it, as
//! sans-IO state fed `(now, bytes)`:
//!
//! - [`params`]: the S registers, their checks and the `ATI5` listing;
//! - [`command`]: the `+++` escape with SiK's guard times, the command line and its echo;
//! - [`SikRadio`]: one radio's commands (`AT`, `ATI`, `ATI1`, `ATI5`, `ATSn?`, `ATSn=`,
//!   `AT&W`, `AT&F`, `ATZ`, `ATO`, `RT...` handed out), RAM/EEPROM/boot semantics;
//! - [`Settings`]: what the registers mean to the link model (pairing, preset);
//! - [`status`] and [`frames`]: `RADIO_STATUS` as SiK makes it, spliced between frames;
//! - [`SikPair`]: both radios around a [`crate::Radio`], `RT` commands carried between.
//!
//! Not reproduced, by design or for want of a model:
//! - boot time (a reboot is instant), the bootloader (`AT&UPDATE`), RFD900's `AT+` calibration
//!   commands, `ATI2`..`ATI4` and `ATI6`/`ATI7` (board id, band code, bootloader version, TDM
//!   and RSSI reports): they answer `ERROR`; `AT&T` test displays switch but print nothing;
//! - `DUTY_CYCLE`, `LBT_RSSI`, `MAX_WINDOW`, `OPPRESEND`, `RTSCTS`, `MANCHESTER`'s coding gain,
//!   `SERIAL_SPEED` (a pty has no baud rate): kept and reported, not applied to the air;
//! - frequency hopping: `MIN_FREQ`/`MAX_FREQ`/`NUM_CHANNELS` only decide whether two radios
//!   pair, the preset's frequency stays the rig's;
//! - link loss of `RT` command packets (they get through whenever the link is up both ways);
//! - air rates other than 64 kbit/s keep the 64 kbit/s bench-fitted sensitivity, and a rate
//!   so low that a full packet overruns SiK's longest window is refused by the model
//!   ([`crate::ConfigError::WindowTooShort`]) where the firmware would shorten its packets;
//! - `rxerrors` and `fixed` in `RADIO_STATUS` stay 0: the model has no CRC failures or Golay
//!   corrections to count.

pub mod command;
pub mod frames;
pub mod pair;
pub mod params;
mod radio;
pub mod settings;
pub mod status;

pub use pair::{End, SikPair};
pub use params::{Board, Param, ParamEntry, Params, parse_ati5};
pub use radio::{REMOTE_ANSWER_MAX, SikRadio};
pub use settings::Settings;

#[cfg(test)]
mod tests;
