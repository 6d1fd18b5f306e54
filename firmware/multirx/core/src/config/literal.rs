//! A [`Config`] as Rust source, so the firmware's build script can compile the
//! configuration file into the image as a constant (the paper's compile-time
//! config, but validated by the same code the host uses).

use core::fmt::{self, Write};

use super::{Config, Mode};

impl Config {
    /// Writes an expression of type `multirx_core::config::Config` equal to `self`.
    pub fn write_rust_literal(&self, out: &mut impl Write) -> fmt::Result {
        let mode = match self.mode {
            Mode::Parallel => "Parallel",
            Mode::Scan => "Scan",
        };
        writeln!(out, "multirx_core::config::Config {{")?;
        writeln!(out, "    mode: multirx_core::config::Mode::{mode},")?;
        writeln!(out, "    receivers: {},", self.receivers)?;
        for (name, d) in [
            ("frame_period", self.frame_period),
            ("silence_timeout", self.silence_timeout),
            ("scan_window", self.scan_window),
        ] {
            writeln!(
                out,
                "    {name}: multirx_core::time::Duration::from_micros({}),",
                d.as_micros()
            )?;
        }
        writeln!(out, "    acquire_frames: {},", self.acquire_frames)?;
        writeln!(out, "    pilot_channel: {},", self.pilot_channel)?;
        writeln!(out, "    pilot_values: {:?},", self.pilot_values)?;
        writeln!(out, "    no_receiver_value: {},", self.no_receiver_value)?;
        writeln!(
            out,
            "    flight_mode_channel: {},",
            self.flight_mode_channel
        )?;
        writeln!(out, "    auto_loiter_value: {},", self.auto_loiter_value)?;
        writeln!(out, "    neutral: {:?},", self.neutral)?;
        writeln!(out, "    throttle_channel: {:?},", self.throttle_channel)?;
        writeln!(
            out,
            "    ifs_channels: multirx_core::config::ChannelSet({:#06x}),",
            self.ifs_channels.0
        )?;
        write!(out, "}}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn literal_names_every_field() {
        let mut text = String::new();
        Config::new(Mode::Scan, 2)
            .write_rust_literal(&mut text)
            .unwrap();
        for field in [
            "mode: multirx_core::config::Mode::Scan",
            "receivers: 2",
            "frame_period: multirx_core::time::Duration::from_micros(7000)",
            "pilot_values: [445, 718, 991, 1264, 1537, 1810]",
            "ifs_channels: multirx_core::config::ChannelSet(0x0000)",
        ] {
            assert!(text.contains(field), "{field} missing from\n{text}");
        }
    }
}
