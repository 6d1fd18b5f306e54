//! What a signer must remember across restarts (MAVLink signing spec, "Timestamp handling"):
//! its own timestamp, so it starts from the larger of the stored value and the clock, and the
//! last timestamp accepted from each stream, so a frame captured before a restart is still a
//! replay after it. Text, one item per line, so an operator can read it:
//!
//! ```text
//! mavlora-signing-state 1
//! timestamp 371958470123
//! stream 2 255 190 371958469000    # link id, system id, component id, last timestamp
//! ```
//!
//! Reading and writing the file is the driver's ([`crate::io::SigningStateFile`]). A state
//! holding a timestamp more than [`MAX_AHEAD`] ahead of the clock is refused
//! ([`SigningState::check_ahead`]), never loaded: resuming from it would wedge the link.

use std::collections::BTreeMap;

use super::signer::MAX_AHEAD;

/// A stream of signed frames: (link id, system id, component id).
pub type StreamKey = (u8, u8, u8);

const MAGIC: &str = "mavlora-signing-state 1";

/// A signer's persistent state; timestamps in 10 µs units since 2015-01-01 00:00 UTC.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SigningState {
    /// The last timestamp this side used or adopted.
    pub timestamp: u64,
    /// The last timestamp accepted per stream.
    pub streams: BTreeMap<StreamKey, u64>,
}

/// A state file that does not parse: the 1-based line and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}: {reason}")]
pub struct StateError {
    /// 1-based line.
    pub line: usize,
    /// What is wrong.
    pub reason: String,
}

/// A stored timestamp more than [`MAX_AHEAD`] ahead of the clock.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "`{entry}` is {seconds} s ahead of this clock, more than the {allowed} s a timestamp may be \
     ahead: this clock is behind (set it: NTP, GPS or an RTC), or a key holder stamped a frame \
     into the future and a version without this check kept it. Resuming from it would make \
     this side's frames look like replays to its peer. If the clock is right, remove the file \
     (the next start is a fresh state)",
    allowed = MAX_AHEAD / 100_000
)]
pub struct AheadError {
    /// The entry as the file writes it (`timestamp T`, `stream LINK SYS COMP T`).
    pub entry: String,
    /// How far ahead of the clock, whole seconds.
    pub seconds: u64,
}

impl SigningState {
    /// Whether every timestamp is at most [`MAX_AHEAD`] ahead of `clock` (10 µs units since
    /// 2015-01-01): a signer never accepts one beyond, so a state holding one was stamped by a
    /// clock that is now behind, or kept a timestamp a key holder stamped into the future.
    pub fn check_ahead(&self, clock: u64) -> Result<(), AheadError> {
        let limit = clock + MAX_AHEAD;
        let own = (self.timestamp > limit)
            .then(|| (format!("timestamp {}", self.timestamp), self.timestamp));
        let stream = self
            .streams
            .iter()
            .find(|&(_, &t)| t > limit)
            .map(|((link, sys, comp), &t)| (format!("stream {link} {sys} {comp} {t}"), t));
        match own.or(stream) {
            Some((entry, t)) => Err(AheadError {
                entry,
                seconds: (t - clock) / 100_000,
            }),
            None => Ok(()),
        }
    }

    /// Parses the text form (see the module doc).
    pub fn parse(text: &str) -> Result<Self, StateError> {
        let mut state = Self::default();
        let mut lines = text.lines().enumerate();
        let err = |line: usize, reason: String| StateError {
            line: line + 1,
            reason,
        };
        match lines.next() {
            Some((_, first)) if first.trim() == MAGIC => {}
            _ => return Err(err(0, format!("expected `{MAGIC}`"))),
        }
        for (n, line) in lines {
            let line = line.split('#').next().unwrap_or("").trim();
            let words: Vec<&str> = line.split_whitespace().collect();
            let number = |w: &str| -> Result<u64, StateError> {
                w.parse::<u64>()
                    .ok()
                    .filter(|&v| v < 1 << 48)
                    .ok_or_else(|| err(n, format!("`{w}` is not a 48-bit timestamp")))
            };
            let byte = |w: &str| -> Result<u8, StateError> {
                w.parse::<u8>()
                    .map_err(|_| err(n, format!("`{w}` is not a number 0..=255")))
            };
            match words.as_slice() {
                [] => {}
                ["timestamp", t] => state.timestamp = number(t)?,
                ["stream", link, sys, comp, t] => {
                    let key = (byte(link)?, byte(sys)?, byte(comp)?);
                    state.streams.insert(key, number(t)?);
                }
                _ => {
                    return Err(err(
                        n,
                        format!("expected `timestamp T` or `stream LINK SYS COMP T`, got `{line}`"),
                    ));
                }
            }
        }
        Ok(state)
    }

    /// The text form.
    pub fn to_text(&self) -> String {
        let mut out = format!("{MAGIC}\ntimestamp {}\n", self.timestamp);
        for ((link, sys, comp), t) in &self.streams {
            out.push_str(&format!("stream {link} {sys} {comp} {t}\n"));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_reads_comments() {
        let mut s = SigningState {
            timestamp: 371_958_470_123,
            ..Default::default()
        };
        s.streams.insert((2, 255, 190), 371_958_469_000);
        s.streams.insert((1, 1, 1), 5);
        assert_eq!(SigningState::parse(&s.to_text()).unwrap(), s);
        let commented = "mavlora-signing-state 1\n# saved by hand\ntimestamp 7 # ok\n\n";
        assert_eq!(SigningState::parse(commented).unwrap().timestamp, 7);
    }

    /// Regression: a state file kept a timestamp a key holder stamped at 2^48 - 60, and the
    /// restarted side signed from there (wrapping) and refused its peer as replays.
    #[test]
    fn a_state_stamped_beyond_the_bound_ahead_of_the_clock_is_refused_naming_the_entry() {
        let clock = 300_000_000_000;
        let mut s = SigningState {
            timestamp: clock + MAX_AHEAD,
            ..Default::default()
        };
        s.streams.insert((1, 1, 1), clock - 5);
        assert_eq!(s.check_ahead(clock), Ok(()), "up to the bound is fine");
        let wedged = (1u64 << 48) - 60;
        s.streams.insert((2, 255, 190), wedged);
        let e = s.check_ahead(clock).unwrap_err();
        assert_eq!(e.entry, format!("stream 2 255 190 {wedged}"));
        assert_eq!(e.seconds, (wedged - clock) / 100_000);
        assert!(e.to_string().contains("ahead of this clock"), "{e}");
        s.timestamp = clock + MAX_AHEAD + 1;
        assert!(
            s.check_ahead(clock)
                .unwrap_err()
                .entry
                .starts_with("timestamp ")
        );
    }

    #[test]
    fn bad_files_name_the_line() {
        assert_eq!(SigningState::parse("").unwrap_err().line, 1);
        let e = SigningState::parse("mavlora-signing-state 1\ntimestamp x\n").unwrap_err();
        assert_eq!(e.line, 2);
        let e = SigningState::parse("mavlora-signing-state 1\nstream 1 2 300 4\n").unwrap_err();
        assert_eq!((e.line, e.reason.contains("300")), (2, true));
        let too_big = format!("mavlora-signing-state 1\ntimestamp {}\n", 1u64 << 48);
        assert_eq!(SigningState::parse(&too_big).unwrap_err().line, 2);
    }
}
