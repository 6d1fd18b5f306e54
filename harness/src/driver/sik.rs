//! SiK radios on the bench: a blocking AT-command client over the local radio's serial
//! port, which reaches the far radio with `RT` commands over the air.
//!
//! [`SikClient::read_both`] enters command mode (quiet, `+++`, quiet: the guard time is a
//! parameter, SiK's 1 s by default), reads `ATI`/`ATI5` and `RTI`/`RTI5` into a
//! [`SikRecord`] for `results.json`; [`check_match`] lists every setting the two radios must
//! share and do not; [`SikClient::set_both`] and [`SikClient::write_and_reboot`] change
//! them (remote first: once the local radio reboots into new settings the remote could no
//! longer be reached). Every error names the port and what came back.

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use serialport::SerialPort;

use harness_radio::sik::{Param, ParamEntry, parse_ati5};

/// SiK's escape guard time.
pub const GUARD: Duration = Duration::from_secs(1);

/// How long an answer may take: a remote one crosses the air twice (a TDM round each
/// way, about 0.25 s at 64 kbit/s, much longer at low air rates).
pub const ANSWER_TIMEOUT: Duration = Duration::from_secs(3);

/// Quiet after the first answer line that ends a multi-line answer.
const SETTLE: Duration = Duration::from_millis(150);

/// What went wrong talking to a radio.
#[derive(Debug, thiserror::Error)]
pub enum SikError {
    /// The port could not be opened.
    #[error("{port}: cannot open the radio's port: {source}")]
    Open {
        port: String,
        #[source]
        source: serialport::Error,
    },
    /// Reading or writing the port failed.
    #[error("{port}: serial I/O failed: {source}")]
    Io {
        port: String,
        #[source]
        source: std::io::Error,
    },
    /// Nothing at all came back.
    #[error("{port}: no answer to {command:?} within {} ms", timeout.as_millis())]
    NoAnswer {
        port: String,
        command: String,
        timeout: Duration,
    },
    /// Bytes came back, but not the answer SiK gives.
    #[error("{port}: garbage answer to {command:?}: {}", escape(bytes))]
    Garbage {
        port: String,
        command: String,
        bytes: Vec<u8>,
    },
    /// The radio answered `ERROR` (or something other than `OK`) to a set or a save.
    #[error("{port}: {command:?} refused: the radio answered {answer:?}")]
    Refused {
        port: String,
        command: String,
        answer: String,
    },
    /// The local radio echoed an `RT` command but the far radio never answered.
    #[error(
        "{port}: the remote radio did not answer {command:?} within {} ms (link down, out of range, or settings that do not pair)",
        timeout.as_millis()
    )]
    RemoteUnreachable {
        port: String,
        command: String,
        timeout: Duration,
    },
    /// The two radios differ on settings they must share.
    #[error("{port}: the radios' settings differ: {}", list(mismatches))]
    Mismatch {
        port: String,
        mismatches: Vec<Mismatch>,
    },
    /// A radio does not list a register the check needs.
    #[error("{port}: the {radio} radio does not list {name}")]
    Missing {
        port: String,
        radio: &'static str,
        name: &'static str,
    },
}

/// One setting two radios disagree on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Mismatch {
    /// Register name (`NETID`).
    pub name: String,
    /// The local radio's value.
    pub local: u32,
    /// The remote radio's value.
    pub remote: u32,
}

/// One radio as read: banner and registers.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RadioInfo {
    /// `ATI`'s answer (`SiK 2.2 on HM-TRP`).
    pub banner: String,
    /// Registers, by number.
    pub params: Vec<ParamEntry>,
}

impl RadioInfo {
    /// A register's value by name.
    pub fn get(&self, name: &str) -> Option<u32> {
        self.params.iter().find(|p| p.name == name).map(|p| p.value)
    }
}

/// Both radios of a link, for the run's record.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SikRecord {
    /// The port the local radio is on.
    pub port: String,
    /// The radio on that port.
    pub local: RadioInfo,
    /// The far radio, read over the air.
    pub remote: RadioInfo,
}

/// Which radio a command is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Which {
    /// The radio on the port (`AT`).
    Local,
    /// The far radio (`RT`).
    Remote,
}

impl Which {
    fn prefix(self) -> &'static str {
        match self {
            Which::Local => "AT",
            Which::Remote => "RT",
        }
    }
}

/// Lists every [`Param::MUST_MATCH`] setting the two radios disagree on.
pub fn check_match(record: &SikRecord) -> Result<(), SikError> {
    let names = Param::MUST_MATCH.iter().map(|p| p.name());
    let mut mismatches = Vec::new();
    for name in names {
        let get = |info: &RadioInfo, radio| {
            info.get(name).ok_or(SikError::Missing {
                port: record.port.clone(),
                radio,
                name,
            })
        };
        let (local, remote) = (get(&record.local, "local")?, get(&record.remote, "remote")?);
        if local != remote {
            mismatches.push(Mismatch {
                name: name.into(),
                local,
                remote,
            });
        }
    }
    if mismatches.is_empty() {
        Ok(())
    } else {
        Err(SikError::Mismatch {
            port: record.port.clone(),
            mismatches,
        })
    }
}

/// A blocking AT client on one radio's port.
pub struct SikClient {
    port: Box<dyn SerialPort>,
    path: String,
    guard: Duration,
    timeout: Duration,
}

impl SikClient {
    /// Opens `path` at `baud` (8N1; SiK's default is 57600).
    pub fn open(path: &str, baud: u32) -> Result<SikClient, SikError> {
        let port = serialport::new(path, baud)
            .timeout(Duration::from_millis(10))
            .open()
            .map_err(|source| SikError::Open {
                port: path.into(),
                source,
            })?;
        Ok(SikClient {
            port,
            path: path.into(),
            guard: GUARD,
            timeout: ANSWER_TIMEOUT,
        })
    }

    /// With a shorter (or longer) escape guard time.
    pub fn guard(mut self, guard: Duration) -> Self {
        self.guard = guard;
        self
    }

    /// With another answer timeout.
    pub fn timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }

    /// The port's path.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Quiet, `+++`, quiet, then waits for `OK`. Data arriving before it is skipped. A
    /// radio already in command mode echoes the `+++` instead: a `\r` then ends that line
    /// (not a command, so the radio ignores it) and the radio is ready as well.
    pub fn enter_command_mode(&mut self) -> Result<(), SikError> {
        const CMD: &str = "+++";
        std::thread::sleep(self.guard);
        self.drain()?;
        self.write(CMD.as_bytes())?;
        std::thread::sleep(self.guard);
        let deadline = Instant::now() + self.timeout;
        let mut got = Vec::new();
        let mut quiet_since = Instant::now();
        while Instant::now() < deadline {
            let before = got.len();
            self.read_some(&mut got)?;
            if got.len() != before {
                quiet_since = Instant::now();
            }
            if got.ends_with(b"OK\r\n") {
                return Ok(());
            }
            if got == CMD.as_bytes() && quiet_since.elapsed() >= SETTLE {
                self.write(b"\r")?;
                return self.read_echo("");
            }
        }
        Err(self.silent_or_garbage(CMD, got))
    }

    /// `ATO`: back to data mode.
    pub fn leave_command_mode(&mut self) -> Result<(), SikError> {
        self.command(Which::Local, "O", false).map(drop)
    }

    /// `ATI` or `RTI`: the firmware banner.
    pub fn banner(&mut self, which: Which) -> Result<String, SikError> {
        let lines = self.command(which, "I", false)?;
        let cmd = format!("{}I", which.prefix());
        match lines.as_slice() {
            [banner] if !banner.is_empty() && banner.is_ascii() => Ok(banner.clone()),
            _ => Err(self.garbage(&cmd, lines.join("\r\n").into_bytes())),
        }
    }

    /// `ATI5` or `RTI5`, parsed. A remote answer travels in one packet and may be cut: a
    /// broken last line is dropped and the registers missing are asked for one by one.
    pub fn params(&mut self, which: Which) -> Result<Vec<ParamEntry>, SikError> {
        let mut lines = self.command(which, "I5", true)?;
        let cmd = format!("{}I5", which.prefix());
        let mut entries = Vec::new();
        let last = lines.len().saturating_sub(1);
        for (i, line) in lines.drain(..).enumerate() {
            match parse_ati5(&line) {
                Ok(mut e) => entries.append(&mut e),
                Err(_) if which == Which::Remote && i == last && i > 0 => {}
                Err(_) => return Err(self.garbage(&cmd, line.into_bytes())),
            }
        }
        if entries.is_empty() {
            return Err(self.garbage(&cmd, Vec::new()));
        }
        for p in Param::ALL {
            if entries.iter().any(|e| e.number == p.number()) {
                continue;
            }
            let value = self.get(which, p)?;
            entries.push(ParamEntry {
                number: p.number(),
                name: p.name().into(),
                value,
            });
        }
        entries.sort_by_key(|e| e.number);
        Ok(entries)
    }

    /// `ATSn?` / `RTSn?`.
    pub fn get(&mut self, which: Which, param: Param) -> Result<u32, SikError> {
        let body = format!("S{}?", param.number());
        let lines = self.command(which, &body, false)?;
        match lines.as_slice() {
            [v] if v.parse::<u32>().is_ok() => Ok(v.parse().unwrap_or_default()),
            _ => Err(self.garbage(
                &format!("{}{body}", which.prefix()),
                lines.join("\r\n").into_bytes(),
            )),
        }
    }

    /// `ATSn=v` / `RTSn=v`; anything but `OK` is an error.
    pub fn set(&mut self, which: Which, param: Param, value: u32) -> Result<(), SikError> {
        let body = format!("S{}={value}", param.number());
        self.expect_ok(which, &body)
    }

    /// Sets `param` on the remote radio, then on the local one.
    pub fn set_both(&mut self, param: Param, value: u32) -> Result<(), SikError> {
        self.set(Which::Remote, param, value)?;
        self.set(Which::Local, param, value)
    }

    /// `RT&W`, `RTZ`, `AT&W`, `ATZ`: both radios save and reboot into what was set (the
    /// remote first, while the two still pair; half the answer timeout is left for the
    /// `RTZ` to cross). Leaves the local radio in data mode.
    pub fn write_and_reboot(&mut self) -> Result<(), SikError> {
        self.expect_ok(Which::Remote, "&W")?;
        self.reboot(Which::Remote)?;
        // `RTZ` has no answer to wait for, and a local radio rebooted into other settings
        // would never send it: give it time to leave and arrive.
        std::thread::sleep(self.timeout / 2);
        self.expect_ok(Which::Local, "&W")?;
        self.reboot(Which::Local)
    }

    /// Enters command mode, reads both radios, leaves command mode.
    pub fn read_both(&mut self) -> Result<SikRecord, SikError> {
        self.enter_command_mode()?;
        let local = RadioInfo {
            banner: self.banner(Which::Local)?,
            params: self.params(Which::Local)?,
        };
        let remote = RadioInfo {
            banner: self.banner(Which::Remote)?,
            params: self.params(Which::Remote)?,
        };
        self.leave_command_mode()?;
        Ok(SikRecord {
            port: self.path.clone(),
            local,
            remote,
        })
    }

    fn reboot(&mut self, which: Which) -> Result<(), SikError> {
        // `Z` answers nothing but its echo; the radio is gone right after.
        let cmd = format!("{}Z", which.prefix());
        self.drain()?;
        self.write(format!("{cmd}\r").as_bytes())?;
        self.read_echo(&cmd)
    }

    fn expect_ok(&mut self, which: Which, body: &str) -> Result<(), SikError> {
        let lines = self.command(which, body, false)?;
        match lines.as_slice() {
            [ok] if ok == "OK" => Ok(()),
            _ => Err(SikError::Refused {
                port: self.path.clone(),
                command: format!("{}{body}", which.prefix()),
                answer: lines.join("\\r\\n"),
            }),
        }
    }

    /// Sends `<prefix><body>\r`, checks the echo, returns the answer's lines: the first
    /// line alone, or (`many`) every line until the port is quiet for a moment.
    fn command(&mut self, which: Which, body: &str, many: bool) -> Result<Vec<String>, SikError> {
        let cmd = format!("{}{body}", which.prefix());
        self.drain()?;
        self.write(format!("{cmd}\r").as_bytes())?;
        self.read_echo(&cmd)?;
        // `ATO` answers nothing.
        if which == Which::Local && body == "O" {
            return Ok(Vec::new());
        }
        let deadline = Instant::now() + self.timeout;
        let mut got = Vec::new();
        let mut quiet_since = Instant::now();
        loop {
            let before = got.len();
            self.read_some(&mut got)?;
            let now = Instant::now();
            if got.len() != before {
                quiet_since = now;
            }
            let complete = got.ends_with(b"\r\n");
            // One line ends at its line break; a listing when the port falls quiet (a
            // remote one may be cut mid-line).
            let done = if many {
                !got.is_empty() && now - quiet_since >= SETTLE
            } else {
                complete
            };
            if done {
                break;
            }
            if !complete && !many && got.len() > 1024 {
                return Err(self.garbage(&cmd, got));
            }
            if now >= deadline {
                if got.is_empty() {
                    return Err(match which {
                        Which::Remote => SikError::RemoteUnreachable {
                            port: self.path.clone(),
                            command: cmd,
                            timeout: self.timeout,
                        },
                        Which::Local => SikError::NoAnswer {
                            port: self.path.clone(),
                            command: cmd,
                            timeout: self.timeout,
                        },
                    });
                }
                return Err(self.garbage(&cmd, got));
            }
        }
        let text = String::from_utf8(got).map_err(|e| self.garbage(&cmd, e.into_bytes()))?;
        let lines: Vec<String> = text.split("\r\n").map(str::to_string).collect();
        let lines: Vec<String> = match lines.split_last() {
            Some((last, rest)) if last.is_empty() => rest.to_vec(),
            _ => lines,
        };
        if many {
            Ok(lines)
        } else {
            Ok(lines.into_iter().take(1).collect())
        }
    }

    /// Reads the radio's echo of `cmd` and its line break.
    fn read_echo(&mut self, cmd: &str) -> Result<(), SikError> {
        let want = format!("{cmd}\r\n").into_bytes();
        let deadline = Instant::now() + self.timeout;
        let mut got = Vec::new();
        while got.len() < want.len() && Instant::now() < deadline {
            let room = want.len() - got.len();
            self.read_exact_some(&mut got, room)?;
            if !want.starts_with(&got) {
                // Read a little more for the error's sake.
                std::thread::sleep(SETTLE);
                self.read_some(&mut got)?;
                return Err(self.garbage(cmd, got));
            }
        }
        if got == want {
            Ok(())
        } else {
            Err(self.silent_or_garbage(cmd, got))
        }
    }

    fn silent_or_garbage(&self, cmd: &str, got: Vec<u8>) -> SikError {
        if got.is_empty() {
            SikError::NoAnswer {
                port: self.path.clone(),
                command: cmd.into(),
                timeout: self.timeout,
            }
        } else {
            self.garbage(cmd, got)
        }
    }

    fn garbage(&self, cmd: &str, bytes: Vec<u8>) -> SikError {
        SikError::Garbage {
            port: self.path.clone(),
            command: cmd.into(),
            bytes,
        }
    }

    fn io(&self, source: std::io::Error) -> SikError {
        SikError::Io {
            port: self.path.clone(),
            source,
        }
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), SikError> {
        self.port
            .write_all(bytes)
            .and_then(|()| self.port.flush())
            .map_err(|e| self.io(e))
    }

    /// Throws away whatever is waiting (telemetry, status reports, a stale answer).
    fn drain(&mut self) -> Result<(), SikError> {
        // Bounded: a radio streaming telemetry never falls quiet.
        let mut sink = Vec::new();
        for _ in 0..64 {
            let before = sink.len();
            self.read_some(&mut sink)?;
            if sink.len() == before {
                break;
            }
            sink.clear();
        }
        Ok(())
    }

    /// Reads what arrives within the port's short timeout.
    fn read_some(&mut self, into: &mut Vec<u8>) -> Result<(), SikError> {
        self.read_exact_some(into, 4096)
    }

    fn read_exact_some(&mut self, into: &mut Vec<u8>, most: usize) -> Result<(), SikError> {
        let mut buf = [0u8; 4096];
        let most = most.min(buf.len());
        match self.port.read(&mut buf[..most]) {
            Ok(n) => {
                into.extend_from_slice(&buf[..n]);
                Ok(())
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(()),
            Err(e) => Err(self.io(e)),
        }
    }
}

/// Bytes for an error message: printable ASCII as is, the rest escaped.
fn escape(bytes: &[u8]) -> String {
    bytes.escape_ascii().to_string()
}

fn list(mismatches: &[Mismatch]) -> String {
    mismatches
        .iter()
        .map(|m| format!("{} local {} remote {}", m.name, m.local, m.remote))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests;
