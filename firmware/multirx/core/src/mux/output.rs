//! The frame MultiRX sends the flight controller.

use crate::config::Config;
use crate::wire::{Flags, Footer, SbusRepr};

/// Composes the output frame.
///
/// - With an active receiver: its channels, with the pilot channel rewritten
///   to that receiver's value.
/// - With none: neutral sticks, the flight-mode channel at auto-loiter and the
///   pilot channel at the "no receiver" value.
/// - Either way the independent fail-safe system's channels replace ours while
///   its link is up, and the failsafe flag is never set: the flight controller
///   must not see RC loss while MultiRX is alive.
pub fn compose(
    config: &Config,
    active: Option<(u8, &SbusRepr)>,
    ifs: Option<&SbusRepr>,
) -> SbusRepr {
    let mut out = match active {
        Some((rx, frame)) => {
            let mut out = *frame;
            out.channels[usize::from(config.pilot_channel)] = config.pilot_values[usize::from(rx)];
            out.flags.failsafe = false;
            out
        }
        None => {
            let mut channels = config.neutral;
            channels[usize::from(config.flight_mode_channel)] = config.auto_loiter_value;
            channels[usize::from(config.pilot_channel)] = config.no_receiver_value;
            SbusRepr {
                channels,
                flags: Flags::default(),
                footer: Footer::Sbus,
            }
        }
    };
    if let Some(ifs) = ifs {
        for ch in config.ifs_channels.iter() {
            out.channels[usize::from(ch)] = ifs.channels[usize::from(ch)];
        }
    }
    // SBUS2 telemetry slots belong to the receiver's bus, not ours.
    out.footer = Footer::Sbus;
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{ChannelSet, Mode};

    #[test]
    fn active_receiver_is_forwarded_with_pilot_channel() {
        let config = Config::new(Mode::Parallel, 2);
        let mut frame = SbusRepr::default();
        frame.channels[0] = 1500;
        frame.flags.frame_lost = true;
        frame.footer = Footer::Sbus2(2);
        let out = compose(&config, Some((1, &frame)), None);
        assert_eq!(out.channels[0], 1500);
        assert_eq!(out.channels[9], config.pilot_values[1]);
        assert!(out.flags.frame_lost && !out.flags.failsafe);
        assert_eq!(out.footer, Footer::Sbus);
    }

    #[test]
    fn nobody_active_means_neutral_and_loiter() {
        let config = Config::new(Mode::Scan, 2);
        let out = compose(&config, None, None);
        assert_eq!(out.channels[4], config.auto_loiter_value);
        assert_eq!(out.channels[9], config.no_receiver_value);
        assert_eq!(out.channels[0], config.neutral[0]);
    }

    #[test]
    fn ifs_overrides_only_its_channels() {
        let mut config = Config::new(Mode::Parallel, 2);
        config.ifs_channels = ChannelSet::EMPTY.with(4);
        let ifs = SbusRepr {
            channels: [100; 16],
            ..SbusRepr::default()
        };
        let out = compose(&config, None, Some(&ifs));
        assert_eq!(out.channels[4], 100);
        assert_eq!(out.channels[0], config.neutral[0]);
        assert_eq!(out.channels[9], config.no_receiver_value);
    }
}
