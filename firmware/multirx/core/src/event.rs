//! What MultiRX reports: receiver power, link changes, which receiver is in
//! control. The firmware writes these as status lines on a spare UART and the
//! emulated device on its status port; the rig reads them to power emulated
//! receivers and to time handovers, and a ground station may log them.
//!
//! Line format (ASCII, one event a line, receivers 0-based):
//! ```text
//! <micros> power <rx> on|off
//! <micros> link <rx> off|silent|failsafe|acquiring|up
//! <micros> active <rx>|none
//! <micros> ifs on|off
//! <micros> overflow <rx>|ifs <total>
//! <micros> boot build <hex> config <hex> reset <cause> first-frame-us <n>
//! ```
//!
//! The boot line ([`crate::boot::BootReport`]) is not an engine event: the
//! device writes it once its first frame is out. [`StatusLine`] reads either.

use core::fmt;

use crate::boot::BootReport;
use crate::mux::LinkState;
use crate::time::Instant;

/// A change inside MultiRX.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Event {
    /// A receiver's power switch changed.
    Power { rx: u8, on: bool },
    /// A receiver's link changed state.
    Link { rx: u8, state: LinkState },
    /// Control passed to a receiver, or to nobody (neutral sticks, auto-loiter).
    Active { rx: Option<u8> },
    /// The independent fail-safe system started or stopped overriding channels.
    Ifs { overriding: bool },
    /// Bytes from receiver `rx` (`None`: the IFS input) were lost between the
    /// UART and the engine (the board's queue was full); `total` such losses on
    /// that input so far. The frame they belonged to was dropped.
    Overflow { rx: Option<u8>, total: u32 },
}

/// An event and when it happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TimedEvent {
    pub at: Instant,
    pub event: Event,
}

impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Event::Power { rx, on } => write!(f, "power {rx} {}", on_off(on)),
            Event::Link { rx, state } => write!(f, "link {rx} {}", state.name()),
            Event::Active { rx: Some(rx) } => write!(f, "active {rx}"),
            Event::Active { rx: None } => write!(f, "active none"),
            Event::Ifs { overriding } => write!(f, "ifs {}", on_off(overriding)),
            Event::Overflow {
                rx: Some(rx),
                total,
            } => write!(f, "overflow {rx} {total}"),
            Event::Overflow { rx: None, total } => write!(f, "overflow ifs {total}"),
        }
    }
}

impl fmt::Display for TimedEvent {
    /// One status line, without its newline.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.at.as_micros(), self.event)
    }
}

fn on_off(on: bool) -> &'static str {
    if on { "on" } else { "off" }
}

/// A status line that is not one of ours.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("not a MultiRX status line (expected `<micros> power|link|active|ifs|overflow ...`)")]
pub struct StatusLineError;

impl TimedEvent {
    /// Parses one status line (surrounding whitespace ignored).
    pub fn parse_line(line: &str) -> Result<TimedEvent, StatusLineError> {
        let mut words = line.split_ascii_whitespace();
        let mut next = || words.next().ok_or(StatusLineError);
        let at = Instant::from_micros(next()?.parse().map_err(|_| StatusLineError)?);
        let rx = |w: &str| w.parse::<u8>().map_err(|_| StatusLineError);
        let on = |w: &str| match w {
            "on" => Ok(true),
            "off" => Ok(false),
            _ => Err(StatusLineError),
        };
        let event = match next()? {
            "power" => Event::Power {
                rx: rx(next()?)?,
                on: on(next()?)?,
            },
            "link" => Event::Link {
                rx: rx(next()?)?,
                state: LinkState::from_name(next()?).ok_or(StatusLineError)?,
            },
            "active" => match next()? {
                "none" => Event::Active { rx: None },
                w => Event::Active { rx: Some(rx(w)?) },
            },
            "ifs" => Event::Ifs {
                overriding: on(next()?)?,
            },
            "overflow" => Event::Overflow {
                rx: match next()? {
                    "ifs" => None,
                    w => Some(rx(w)?),
                },
                total: next()?.parse().map_err(|_| StatusLineError)?,
            },
            _ => return Err(StatusLineError),
        };
        if next().is_ok() {
            return Err(StatusLineError);
        }
        Ok(TimedEvent { at, event })
    }
}

/// Any line on the status output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StatusLine {
    Event(TimedEvent),
    Boot(BootReport),
}

impl StatusLine {
    /// Parses one status line: an event or the boot line.
    pub fn parse(line: &str) -> Result<StatusLine, StatusLineError> {
        if line.split_ascii_whitespace().nth(1) == Some("boot") {
            return BootReport::parse_line(line)
                .map(StatusLine::Boot)
                .map_err(|_| StatusLineError);
        }
        TimedEvent::parse_line(line).map(StatusLine::Event)
    }
}

impl fmt::Display for StatusLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StatusLine::Event(e) => e.fmt(f),
            StatusLine::Boot(b) => b.fmt(f),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boot::ResetCause;
    use crate::time::Duration;

    #[test]
    fn status_lines_round_trip_events_and_the_boot_line() {
        let lines = [
            StatusLine::Event(TimedEvent {
                at: Instant::from_micros(7),
                event: Event::Active { rx: Some(1) },
            }),
            StatusLine::Event(TimedEvent {
                at: Instant::from_micros(8),
                event: Event::Overflow {
                    rx: Some(3),
                    total: 12,
                },
            }),
            StatusLine::Event(TimedEvent {
                at: Instant::from_micros(9),
                event: Event::Overflow {
                    rx: None,
                    total: u32::MAX,
                },
            }),
            StatusLine::Boot(BootReport {
                at: Instant::from_micros(41_000),
                build_id: 1,
                config_hash: u64::MAX,
                reset: ResetCause::Watchdog,
                first_frame: Duration::from_micros(40_123),
            }),
        ];
        for line in lines {
            let text = line.to_string();
            assert_eq!(StatusLine::parse(&text), Ok(line), "{text}");
        }
        assert_eq!(StatusLine::parse("5 boot build x"), Err(StatusLineError));
    }

    #[test]
    fn lines_round_trip() {
        let events = [
            Event::Power { rx: 3, on: true },
            Event::Link {
                rx: 0,
                state: LinkState::Failsafe,
            },
            Event::Active { rx: Some(5) },
            Event::Active { rx: None },
            Event::Ifs { overriding: false },
        ];
        for event in events {
            let timed = TimedEvent {
                at: Instant::from_micros(1_234_567),
                event,
            };
            let line = timed.to_string();
            assert_eq!(TimedEvent::parse_line(&line), Ok(timed), "{line}");
        }
    }

    #[test]
    fn garbage_lines_are_refused() {
        for line in [
            "",
            "12",
            "12 power",
            "12 power x on",
            "12 active 1 2",
            "x active 1",
            "12 link 0 meh",
        ] {
            assert_eq!(TimedEvent::parse_line(line), Err(StatusLineError), "{line}");
        }
    }
}
