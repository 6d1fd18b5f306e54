//! The Telnet link to a Mini-Circuits unit (TCP port 23): one command line out, one
//! answer line back, CR LF. No login and no prompt (the public drivers that talk to these
//! units read one line per command and expect neither). Should a unit offer Telnet
//! options, [`Decoder`] refuses them and keeps them out of the answer text.

use std::collections::VecDeque;
use std::io::{self, ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use super::minicircuits::LinkError;

const IAC: u8 = 255;
const DONT: u8 = 254;
const DO: u8 = 253;
const WONT: u8 = 252;
const WILL: u8 = 251;
const SB: u8 = 250;
const SE: u8 = 240;

/// Longest answer line kept whole; a longer run without a line end is cut here (it is
/// garbage in this protocol, and memory stays bounded).
const MAX_LINE: usize = 256;

/// Where the decoder is in the Telnet byte stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Data,
    Iac,
    /// After IAC DO/DONT/WILL/WONT: the option byte comes next.
    Option(u8),
    /// Inside IAC SB ... IAC SE.
    Sub,
    SubIac,
}

/// Splits the bytes a device sends into answer lines, taking out Telnet commands and
/// queueing the refusals of any options the device asks for. Pure: no IO.
#[derive(Debug)]
pub struct Decoder {
    state: State,
    line: Vec<u8>,
    lines: VecDeque<Vec<u8>>,
    replies: Vec<u8>,
}

impl Default for Decoder {
    fn default() -> Self {
        Decoder {
            state: State::Data,
            line: Vec::new(),
            lines: VecDeque::new(),
            replies: Vec::new(),
        }
    }
}

impl Decoder {
    /// Takes in bytes as they arrived.
    pub fn push(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.state = match self.state {
                State::Data => match b {
                    IAC => State::Iac,
                    b'\r' | b'\n' => {
                        self.end_line();
                        State::Data
                    }
                    // Telnet's CR NUL (a bare CR) leaves a NUL at the start of a line.
                    0 if self.line.is_empty() => State::Data,
                    _ => {
                        self.line.push(b);
                        if self.line.len() >= MAX_LINE {
                            self.end_line();
                        }
                        State::Data
                    }
                },
                State::Iac => match b {
                    IAC => {
                        self.line.push(IAC);
                        State::Data
                    }
                    DO | DONT | WILL | WONT => State::Option(b),
                    SB => State::Sub,
                    _ => State::Data,
                },
                State::Option(verb) => {
                    // Refuse what the device offers or asks: the link stays plain NVT text.
                    match verb {
                        DO => self.replies.extend_from_slice(&[IAC, WONT, b]),
                        WILL => self.replies.extend_from_slice(&[IAC, DONT, b]),
                        _ => {}
                    }
                    State::Data
                }
                State::Sub => {
                    if b == IAC {
                        State::SubIac
                    } else {
                        State::Sub
                    }
                }
                State::SubIac => {
                    if b == SE {
                        State::Data
                    } else {
                        State::Sub
                    }
                }
            };
        }
    }

    fn end_line(&mut self) {
        if !self.line.is_empty() {
            self.lines.push_back(std::mem::take(&mut self.line));
        }
    }

    /// The next complete, non-empty line.
    pub fn next_line(&mut self) -> Option<Vec<u8>> {
        self.lines.pop_front()
    }

    /// Bytes owed to the device (option refusals).
    pub fn take_replies(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.replies)
    }
}

/// An open Telnet session. After a timeout or a failure the session is dropped: a late
/// answer would otherwise be read as the answer to the next command.
pub(crate) struct TelnetLink {
    stream: Option<TcpStream>,
    decoder: Decoder,
    timeout: Duration,
}

impl TelnetLink {
    pub(crate) fn connect(addr: SocketAddr, timeout: Duration) -> Result<Self, LinkError> {
        let stream = TcpStream::connect_timeout(&addr, timeout).map_err(|e| match e.kind() {
            ErrorKind::TimedOut | ErrorKind::WouldBlock => LinkError::Timeout,
            _ => LinkError::Lost(e),
        })?;
        // One short line per exchange: do not hold it back for coalescing.
        stream.set_nodelay(true).map_err(LinkError::Lost)?;
        Ok(TelnetLink {
            stream: Some(stream),
            decoder: Decoder::default(),
            timeout,
        })
    }

    /// Sends `command` and returns the next answer line.
    pub(crate) fn exchange(&mut self, command: &str) -> Result<Vec<u8>, LinkError> {
        let result = self.exchange_inner(command);
        if result.is_err() {
            self.stream = None;
        }
        result
    }

    fn exchange_inner(&mut self, command: &str) -> Result<Vec<u8>, LinkError> {
        let Some(stream) = self.stream.as_mut() else {
            return Err(LinkError::Lost(io::Error::new(
                ErrorKind::NotConnected,
                "session closed after an earlier failure",
            )));
        };
        // Anything unasked-for (a greeting, a straggler) must not pass for this answer.
        discard_pending(stream, &mut self.decoder)?;
        stream
            .write_all(format!("{command}\r\n").as_bytes())
            .map_err(LinkError::Lost)?;
        let deadline = Instant::now() + self.timeout;
        let mut buf = [0u8; 512];
        loop {
            let replies = self.decoder.take_replies();
            if !replies.is_empty() {
                stream.write_all(&replies).map_err(LinkError::Lost)?;
            }
            while let Some(line) = self.decoder.next_line() {
                // A unit (or a terminal server in front of one) in echo mode sends the
                // command back first: that is not its answer.
                if line != command.as_bytes() {
                    return Ok(line);
                }
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(LinkError::Timeout);
            }
            stream
                .set_read_timeout(Some(left.max(Duration::from_millis(1))))
                .map_err(LinkError::Lost)?;
            match stream.read(&mut buf) {
                Ok(0) => {
                    return Err(LinkError::Lost(io::Error::new(
                        ErrorKind::UnexpectedEof,
                        "the device closed the connection",
                    )));
                }
                Ok(n) => self.decoder.push(&buf[..n]),
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(LinkError::Lost(e)),
            }
        }
    }
}

/// Reads what already arrived without waiting and drops its complete lines.
fn discard_pending(stream: &mut TcpStream, decoder: &mut Decoder) -> Result<(), LinkError> {
    stream.set_nonblocking(true).map_err(LinkError::Lost)?;
    let mut buf = [0u8; 512];
    let outcome = loop {
        match stream.read(&mut buf) {
            Ok(0) => {
                break Err(LinkError::Lost(io::Error::new(
                    ErrorKind::UnexpectedEof,
                    "the device closed the connection",
                )));
            }
            Ok(n) => decoder.push(&buf[..n]),
            Err(e) if e.kind() == ErrorKind::WouldBlock => break Ok(()),
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => break Err(LinkError::Lost(e)),
        }
    };
    stream.set_nonblocking(false).map_err(LinkError::Lost)?;
    while let Some(line) = decoder.next_line() {
        tracing::debug!(line = %line.escape_ascii(), "attenuator: dropped an unasked-for line");
    }
    outcome
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(d: &mut Decoder) -> Vec<Vec<u8>> {
        std::iter::from_fn(|| d.next_line()).collect()
    }

    #[test]
    fn splits_lines_on_cr_lf_in_any_chunking() {
        let mut d = Decoder::default();
        d.push(b"MN=RCDAT-6");
        assert!(d.next_line().is_none(), "no line before its end");
        d.push(b"000-90\r");
        d.push(b"\n1\r\n\r\n30.25\n\r");
        assert_eq!(
            lines(&mut d),
            vec![
                b"MN=RCDAT-6000-90".to_vec(),
                b"1".to_vec(),
                b"30.25".to_vec()
            ]
        );
    }

    #[test]
    fn refuses_options_and_keeps_them_out_of_the_text() {
        let mut d = Decoder::default();
        // DO ECHO, WILL SUPPRESS-GO-AHEAD, a subnegotiation, an escaped 255, DONT 1.
        d.push(&[
            IAC, DO, 1, b'4', IAC, WILL, 3, b'2', IAC, SB, 24, 1, 9, IAC, SE, IAC, IAC, IAC, DONT,
            1, b'\r', b'\n',
        ]);
        assert_eq!(lines(&mut d), vec![vec![b'4', b'2', IAC]]);
        assert_eq!(d.take_replies(), vec![IAC, WONT, 1, IAC, DONT, 3]);
        assert!(d.take_replies().is_empty());
    }

    #[test]
    fn cuts_endless_lines() {
        let mut d = Decoder::default();
        d.push(&[b'x'; MAX_LINE * 2 + 3]);
        let got = lines(&mut d);
        assert_eq!(got.len(), 2);
        assert!(got.iter().all(|l| l.len() == MAX_LINE));
    }

    proptest::proptest! {
        /// Any bytes: no panic, no empty line, no line end inside a line, none too long.
        #[test]
        fn decoder_takes_any_bytes(chunks in proptest::collection::vec(proptest::collection::vec(proptest::num::u8::ANY, 0..64), 0..16)) {
            let mut d = Decoder::default();
            for c in &chunks {
                d.push(c);
                let _ = d.take_replies();
            }
            for line in lines(&mut d) {
                proptest::prop_assert!(!line.is_empty() && line.len() <= MAX_LINE);
                proptest::prop_assert!(!line.contains(&b'\r') && !line.contains(&b'\n'));
            }
        }
    }
}
