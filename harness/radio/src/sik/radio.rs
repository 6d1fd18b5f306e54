//! One SiK radio's firmware as the host sees it: the line discipline, the commands, the
//! registers in RAM and in EEPROM, and the `RADIO_STATUS` reports.
//!
//! Registers live three times, as in SiK: the EEPROM copy (`AT&W` writes it, boot reads
//! it), the RAM copy (`ATSn?` reads and `ATSn=` writes it; `ATZ` without `AT&W` loses
//! it), and the values the radio booted with, which the link runs on until the next boot
//! ([`Param::immediate`] ones apply at once).

use std::collections::VecDeque;

use timebase::{Duration, Instant};

use super::command::{CommandLine, Step};
use super::frames::FrameScanner;
use super::params::{Board, Param, Params};
use super::settings::Settings;
use super::status::{self, Splicer, StatusInputs};

/// Most bytes of a remote command's answer: SiK captures it into one packet buffer.
pub const REMOTE_ANSWER_MAX: usize = 252;

/// SiK's version string (`ATI1`).
const VERSION: &str = "2.2";

/// One SiK radio.
#[derive(Debug, Clone)]
pub struct SikRadio {
    board: Board,
    guard: Duration,
    eeprom: Params,
    ram: Params,
    boot: Params,
    line: CommandLine,
    /// Host → air: finds HEARTBEATs, which arm a report.
    outgoing: FrameScanner,
    splicer: Splicer,
    report_armed: bool,
    seq: u8,
    to_host: Vec<u8>,
    remote_commands: VecDeque<String>,
    changed: bool,
    boots: u32,
}

impl SikRadio {
    /// A radio on `board` with factory defaults, booted at `now`; `guard` is the escape's
    /// guard time ([`super::command::GUARD`] on real radios).
    pub fn new(board: Board, guard: Duration, now: Instant) -> SikRadio {
        let defaults = Params::defaults(&board);
        SikRadio::with_eeprom(board, defaults, guard, now)
    }

    /// As [`SikRadio::new`], with `eeprom` saved on it.
    pub fn with_eeprom(board: Board, eeprom: Params, guard: Duration, now: Instant) -> SikRadio {
        let mut r = SikRadio {
            line: CommandLine::new(now, guard),
            guard,
            eeprom,
            ram: eeprom,
            boot: eeprom,
            outgoing: FrameScanner::default(),
            splicer: Splicer::default(),
            report_armed: false,
            seq: 0,
            to_host: Vec::new(),
            remote_commands: VecDeque::new(),
            changed: true,
            boots: 0,
            board,
        };
        r.reboot(now);
        r.boots = 0;
        r
    }

    /// The registers in RAM (what `ATSn?` answers).
    pub fn params(&self) -> &Params {
        &self.ram
    }

    /// The registers saved (what the next boot loads).
    pub fn eeprom(&self) -> &Params {
        &self.eeprom
    }

    /// What the link runs on now.
    pub fn settings(&self) -> Settings {
        Settings::new(&self.boot, &self.ram)
    }

    /// Whether the radio is in command mode (it then passes no air data to the host).
    pub fn in_command_mode(&self) -> bool {
        self.line.active()
    }

    /// Boots since it was made (`ATZ`, `RTZ`).
    pub fn boots(&self) -> u32 {
        self.boots
    }

    /// Whether [`SikRadio::settings`] changed since the last call: the link needs its
    /// preset or its pairing looked at again.
    pub fn take_changed(&mut self) -> bool {
        std::mem::take(&mut self.changed)
    }

    /// When the guard timer next needs [`SikRadio::handle_timeout`].
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.line.poll_timeout()
    }

    /// Runs the guard timer.
    pub fn handle_timeout(&mut self, now: Instant) {
        if self.line.advance(now) {
            // The firmware stuffs an empty `AT` into the buffer: the host sees `OK`.
            self.run("AT", now);
        }
    }

    /// Bytes from the host; what goes to the air is appended to `to_air`.
    pub fn handle_host_input(&mut self, now: Instant, bytes: &[u8], to_air: &mut Vec<u8>) {
        self.handle_timeout(now);
        for &b in bytes {
            match self.line.feed(now, b) {
                Step::Data(b) => {
                    to_air.push(b);
                    if let Some(end) = self.outgoing.push(b) {
                        self.report_armed |= end.heartbeat;
                    }
                }
                Step::Echo(e) => self.to_host.extend_from_slice(&e),
                Step::Line(e, line) => {
                    self.to_host.extend_from_slice(&e);
                    self.command(&line, now);
                }
                Step::Ignored | Step::Abandoned => {}
            }
            self.handle_timeout(now);
        }
    }

    /// Data from the far radio: to the host, unless in command mode (SiK drops it then).
    pub fn handle_air_data(&mut self, bytes: &[u8]) {
        if !self.line.active() {
            self.splicer.data(bytes, &mut self.to_host);
        }
    }

    /// A remote command's answer arriving over the air: printed as it came.
    pub fn handle_remote_answer(&mut self, bytes: &[u8]) {
        self.to_host.extend_from_slice(bytes);
    }

    /// A command sent by the far radio (`RT...`): run as `AT...`, its answer captured
    /// (at most [`REMOTE_ANSWER_MAX`] bytes) for the trip back. No echo.
    pub fn execute_remote(&mut self, line: &str, now: Instant) -> Vec<u8> {
        let Some(rest) = line.strip_prefix("RT") else {
            return Vec::new();
        };
        let before = self.to_host.len();
        self.run(&format!("AT{rest}"), now);
        let mut answer = self.to_host.split_off(before);
        answer.truncate(REMOTE_ANSWER_MAX);
        answer
    }

    /// The next `RT` command the host typed, for the caller to carry to the far radio.
    pub fn poll_remote_command(&mut self) -> Option<String> {
        self.remote_commands.pop_front()
    }

    /// Whether a HEARTBEAT went out since the last report and one is due (framing on,
    /// not in command mode), as SiK's main loop checks.
    pub fn report_due(&self) -> bool {
        self.report_armed && self.ram.get(Param::Mavlink) != 0 && !self.line.active()
    }

    /// Writes the due report, between frames of the data to the host.
    pub fn send_report(&mut self, inputs: &StatusInputs) {
        self.report_armed = false;
        let frame = status::encode(&status::radio_status(inputs), self.seq);
        self.seq = self.seq.wrapping_add(1);
        self.splicer.insert(frame, &mut self.to_host);
    }

    /// Bytes for the host's serial port.
    pub fn take_host_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.to_host)
    }

    fn command(&mut self, line: &str, now: Instant) {
        if line.starts_with("RT") {
            self.remote_commands.push_back(line.to_string());
        } else if line.starts_with("AT") {
            self.run(line, now);
        }
        // Anything else is dropped silently, as `at_command` does.
    }

    /// Runs one `AT` line (typed here or sent by the far radio).
    fn run(&mut self, line: &str, now: Instant) {
        let cmd = &line.as_bytes()[2..];
        let answer: Option<String> = match cmd.first() {
            None => Some("OK".into()),
            Some(b'I') => self.info(&cmd[1..]),
            Some(b'S') => Some(self.register(&cmd[1..])),
            Some(b'&') => match cmd.get(1) {
                Some(b'W') => {
                    self.ram.set_format();
                    self.eeprom = self.ram;
                    Some("OK".into())
                }
                Some(b'F') => {
                    self.ram = Params::defaults(&self.board);
                    self.changed = true;
                    Some("OK".into())
                }
                // Test displays: switched, but their output is not modelled.
                Some(b'T') if matches!(&cmd[2..], b"" | b"=RSSI" | b"=TDM") => None,
                _ => Some("ERROR".into()),
            },
            Some(b'O') => {
                self.line.leave(now);
                None
            }
            Some(b'Z') => {
                self.reboot(now);
                None
            }
            _ => Some("ERROR".into()),
        };
        if let Some(a) = answer {
            self.to_host.extend_from_slice(a.as_bytes());
            self.to_host.extend_from_slice(b"\r\n");
        }
    }

    fn info(&self, rest: &[u8]) -> Option<String> {
        Some(match rest.first() {
            None | Some(b'0') => self.board.banner.clone(),
            Some(b'1') => VERSION.into(),
            Some(b'5') => self.ram.ati5().trim_end_matches("\r\n").into(),
            _ => "ERROR".into(),
        })
    }

    /// `ATSn?` / `ATSn=v`, parsed as `at_s` does: digits up to the first non-digit.
    fn register(&mut self, rest: &[u8]) -> String {
        let (n, rest) = parse_number(rest);
        let Some(param) = Param::from_number(n) else {
            return "ERROR".into();
        };
        match rest.first() {
            Some(b'?') => self.ram.get(param).to_string(),
            Some(b'=') if param != Param::Format => {
                let (value, _) = parse_number(&rest[1..]);
                if self.ram.set(&self.board, param, value) {
                    if param.immediate() {
                        self.changed = true;
                    }
                    "OK".into()
                } else {
                    "ERROR".into()
                }
            }
            _ => "ERROR".into(),
        }
    }

    fn reboot(&mut self, now: Instant) {
        let mut loaded = self.eeprom;
        loaded.fill_band(&self.board);
        self.ram = loaded;
        self.boot = loaded;
        self.line = CommandLine::new(now, self.guard);
        self.outgoing = FrameScanner::default();
        self.splicer = Splicer::default();
        self.report_armed = false;
        self.changed = true;
        self.boots += 1;
    }
}

/// SiK's `at_parse_number`: decimal digits, wrapping on overflow like its `uint32_t`.
fn parse_number(s: &[u8]) -> (u32, &[u8]) {
    let digits = s.iter().take_while(|b| b.is_ascii_digit()).count();
    let n = s[..digits].iter().fold(0u32, |acc, d| {
        acc.wrapping_mul(10).wrapping_add(u32::from(d - b'0'))
    });
    (n, &s[digits..])
}
