//! What a board can wire: every receiver and the independent fail-safe
//! system's input take one UART. The number lives here, once, so the
//! firmware's build script, the firmware itself and the rig that checks a
//! bench's configs before a run cannot disagree about it.

use crate::config::Config;

/// UARTs of the SAMD21G18 board for SBUS inputs: one RX pad per SERCOM, six
/// SERCOMs (`firmware/multirx/samd21/src/board.rs`).
pub const SAMD21_UARTS: u8 = 6;

/// UART inputs a board needs for `receivers` receivers, plus one for the IFS.
pub const fn uarts_needed(receivers: u8, ifs: bool) -> u8 {
    receivers + ifs as u8
}

/// A configuration needs more UART inputs than the board has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "{receivers} receivers{} need {} UART inputs; the board has {uarts}, so at most {} receivers{}",
    if *ifs { " and an [ifs] input" } else { "" },
    uarts_needed(*receivers, *ifs),
    uarts - *ifs as u8,
    if *ifs { " with [ifs]" } else { "" }
)]
pub struct DoesNotFit {
    /// Receivers the configuration names.
    pub receivers: u8,
    /// Whether it has `[ifs]` channels (the IFS takes a UART of its own).
    pub ifs: bool,
    /// UART inputs the board has.
    pub uarts: u8,
}

impl Config {
    /// Whether this configuration fits a board with `uarts` UART inputs.
    pub fn fits(&self, uarts: u8) -> Result<(), DoesNotFit> {
        let ifs = !self.ifs_channels.is_empty();
        if uarts_needed(self.receivers, ifs) <= uarts {
            Ok(())
        } else {
            Err(DoesNotFit {
                receivers: self.receivers,
                ifs,
                uarts,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{ChannelSet, Mode};

    #[test]
    fn the_ifs_takes_a_uart_of_its_own() {
        let mut c = Config::new(Mode::Parallel, 6);
        assert_eq!(c.fits(SAMD21_UARTS), Ok(()));
        c.ifs_channels = ChannelSet::EMPTY.with(4);
        let err = c.fits(SAMD21_UARTS).unwrap_err();
        assert_eq!(
            err.to_string(),
            "6 receivers and an [ifs] input need 7 UART inputs; the board has 6, so at most 5 receivers with [ifs]"
        );
        c.receivers = 5;
        assert_eq!(c.fits(SAMD21_UARTS), Ok(()));
    }
}
