//! The serial line discipline of a SiK radio (`at.c`): the `+++` escape with its guard
//! times, then the command line with echo, backspace and the 16-character limit.
//!
//! The escape is SiK's state machine (`at_plus_detector`, `at_timer`), run on exact times
//! instead of the firmware's 10 ms ticks: the line must be quiet for the guard time, then
//! carry exactly `+++`, then be quiet for the guard time again; any other byte on the way
//! starts over, so `+++` inside data is data. A fourth `+` restarts the final wait, as in
//! the firmware. In data mode every byte, the `+++` included, still goes to the air.

use timebase::{Duration, Instant};

/// SiK's guard time: 100 ticks of its 100 Hz timer.
pub const GUARD: Duration = Duration::from_millis(1000);

/// `AT_CMD_MAXLEN`: a longer line abandons command mode.
pub const MAX_LINE: usize = 16;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Plus {
    /// Waiting for the line to be quiet.
    Idle,
    /// Quiet long enough; this many `+` seen.
    Seen(u8),
    /// `+++` seen; waiting for quiet again.
    Enable,
}

/// What one byte from the host did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// Data mode: the byte goes to the air.
    Data(u8),
    /// Command mode: these bytes go back to the host (the echo).
    Echo(Vec<u8>),
    /// Command mode: a line ended (echoed `\r\n` first); run it.
    Line(Vec<u8>, String),
    /// Command mode: ignored byte (not printable).
    Ignored,
    /// The line overflowed: back to data mode, the byte dropped.
    Abandoned,
}

/// Line discipline state.
#[derive(Debug, Clone)]
pub struct CommandLine {
    guard: Duration,
    active: bool,
    plus: Plus,
    /// When the guard timer runs out, if it runs.
    deadline: Option<Instant>,
    line: Vec<u8>,
}

impl CommandLine {
    /// A line just booted at `now`: data mode, guard timer running.
    pub fn new(now: Instant, guard: Duration) -> CommandLine {
        CommandLine {
            guard,
            active: false,
            plus: Plus::Idle,
            deadline: Some(now + guard),
            line: Vec::new(),
        }
    }

    /// Whether the radio is in command mode.
    pub fn active(&self) -> bool {
        self.active
    }

    /// When [`CommandLine::advance`] has something to do.
    pub fn poll_timeout(&self) -> Option<Instant> {
        if self.active { None } else { self.deadline }
    }

    /// Runs the guard timer to `now`; `true` when that entered command mode (the firmware
    /// then runs an empty `AT`: the host sees `OK`).
    pub fn advance(&mut self, now: Instant) -> bool {
        let Some(deadline) = self.deadline else {
            return false;
        };
        if self.active || deadline > now {
            return false;
        }
        self.deadline = None;
        match self.plus {
            Plus::Idle => self.plus = Plus::Seen(0),
            Plus::Enable => {
                self.plus = Plus::Idle;
                self.active = true;
                self.line.clear();
                return true;
            }
            Plus::Seen(_) => {}
        }
        false
    }

    /// Leaves command mode (`ATO`): the guard timer starts again.
    pub fn leave(&mut self, now: Instant) {
        self.active = false;
        self.line.clear();
        self.deadline = Some(now + self.guard);
    }

    /// One byte from the host at `now` (after [`CommandLine::advance`] to `now`).
    pub fn feed(&mut self, now: Instant, c: u8) -> Step {
        if !self.active {
            self.detect(now, c);
            return Step::Data(c);
        }
        match c {
            b'\r' => {
                let line = String::from_utf8_lossy(&std::mem::take(&mut self.line)).into_owned();
                Step::Line(b"\r\n".to_vec(), line)
            }
            b'\x08' | b'\x7f' => {
                if self.line.pop().is_some() {
                    Step::Echo(b"\x08 \x08".to_vec())
                } else {
                    Step::Ignored
                }
            }
            _ if self.line.len() < MAX_LINE => {
                if c.is_ascii_graphic() || c == b' ' {
                    let c = c.to_ascii_uppercase();
                    self.line.push(c);
                    Step::Echo(vec![c])
                } else {
                    Step::Ignored
                }
            }
            _ => {
                // A runaway line: most likely an escape that was not meant as one.
                self.active = false;
                self.line.clear();
                Step::Abandoned
            }
        }
    }

    fn detect(&mut self, now: Instant, c: u8) {
        if c != b'+' {
            self.plus = Plus::Idle;
        }
        match self.plus {
            Plus::Seen(n) if n < 2 => self.plus = Plus::Seen(n + 1),
            Plus::Seen(_) => {
                self.plus = Plus::Enable;
                self.deadline = Some(now + self.guard);
            }
            Plus::Idle | Plus::Enable => self.deadline = Some(now + self.guard),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(ms: u64) -> Instant {
        Instant::ZERO + Duration::from_millis(ms)
    }

    /// Feeds `bytes` at `ms`, after running the timer; returns whether command mode began.
    fn send(l: &mut CommandLine, ms: u64, bytes: &[u8]) -> bool {
        let mut entered = l.advance(at(ms));
        for &b in bytes {
            l.feed(at(ms), b);
        }
        entered |= l.advance(at(ms));
        entered
    }

    #[test]
    fn guarded_escape_enters_command_mode_after_the_second_guard() {
        let mut l = CommandLine::new(at(0), GUARD);
        assert!(!send(&mut l, 1000, b"+++"));
        assert!(!send(&mut l, 1999, b""));
        assert!(send(&mut l, 2000, b""));
        assert!(l.active());
    }

    #[test]
    fn plus_too_soon_after_data_is_data() {
        let mut l = CommandLine::new(at(0), GUARD);
        send(&mut l, 1500, b"hello");
        assert!(!send(&mut l, 2000, b"+++"), "0.5 s after data");
        assert!(!send(&mut l, 5000, b""));
        assert!(!l.active());
        // Data right after the escape cancels it too.
        send(&mut l, 7000, b"+++");
        send(&mut l, 7500, b"x");
        assert!(!send(&mut l, 9000, b""));
        // So does a fourth byte that is not `+`, or a `+` split by other data.
        send(&mut l, 11000, b"++x+");
        assert!(!send(&mut l, 13000, b""));
        // A fourth `+` restarts the final wait but still counts.
        send(&mut l, 15000, b"+++");
        send(&mut l, 15900, b"+");
        assert!(!send(&mut l, 16000, b""));
        assert!(send(&mut l, 16900, b""));
    }

    #[test]
    fn the_line_echoes_uppercase_and_a_long_line_abandons_command_mode() {
        let mut l = CommandLine::new(at(0), GUARD);
        send(&mut l, 1000, b"+++");
        assert!(send(&mut l, 2000, b""));
        assert_eq!(l.feed(at(2001), b'a'), Step::Echo(b"A".to_vec()));
        assert_eq!(l.feed(at(2001), b'\x7f'), Step::Echo(b"\x08 \x08".to_vec()));
        for &b in b"ati" {
            l.feed(at(2001), b);
        }
        assert_eq!(
            l.feed(at(2001), b'\r'),
            Step::Line(b"\r\n".to_vec(), "ATI".into())
        );
        for _ in 0..MAX_LINE {
            l.feed(at(2002), b'A');
        }
        assert_eq!(l.feed(at(2002), b'A'), Step::Abandoned);
        assert!(!l.active());
    }
}
