//! Serial ports that carry SBUS.

use multirx_core::wire::sbus;
use serialport::{DataBits, Parity, SerialPortBuilder, StopBits};

/// A builder for the serial port at `path` with SBUS's UART settings, as
/// [`multirx_core::wire::sbus::BAUD`] states them (100000 baud 8E2); the caller adds its
/// timeout and opens it. On a pty these settings are accepted and ignored.
pub fn port(path: &str) -> SerialPortBuilder {
    serialport::new(path, sbus::BAUD)
        .data_bits(DataBits::try_from(sbus::DATA_BITS).expect("SBUS has 8 data bits"))
        .parity(match sbus::PARITY {
            sbus::Parity::None => Parity::None,
            sbus::Parity::Odd => Parity::Odd,
            sbus::Parity::Even => Parity::Even,
        })
        .stop_bits(StopBits::try_from(sbus::STOP_BITS).expect("SBUS has 2 stop bits"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sbus_is_100000_baud_8e2() {
        let want = serialport::new("/dev/null", 100_000)
            .data_bits(DataBits::Eight)
            .parity(Parity::Even)
            .stop_bits(StopBits::Two);
        assert_eq!(port("/dev/null"), want);
    }
}
