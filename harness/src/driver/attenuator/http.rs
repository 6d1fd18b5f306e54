//! The HTTP link to a Mini-Circuits unit: each command is a GET of `/<command>` (e.g.
//! `http://192.168.1.10/:SETATT=30.25`), the answer is the body's text. Hand-written on
//! std's TcpStream: one HTTP/1.0 request per command needs no client crate.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use super::minicircuits::LinkError;

/// The largest response taken; the answers are a few bytes.
const MAX_RESPONSE: usize = 16 * 1024;

pub(crate) struct HttpLink {
    addr: SocketAddr,
    host: String,
    timeout: Duration,
}

impl HttpLink {
    pub(crate) fn new(addr: SocketAddr, host: String, timeout: Duration) -> Self {
        HttpLink {
            addr,
            host,
            timeout,
        }
    }

    /// GETs `/<command>` and returns the body's first non-empty line.
    pub(crate) fn exchange(&mut self, command: &str) -> Result<Vec<u8>, LinkError> {
        let deadline = Instant::now() + self.timeout;
        let mut stream =
            TcpStream::connect_timeout(&self.addr, self.timeout).map_err(|e| match e.kind() {
                ErrorKind::TimedOut | ErrorKind::WouldBlock => LinkError::Timeout,
                _ => LinkError::Lost(e),
            })?;
        let request = format!(
            "GET /{command} HTTP/1.0\r\nHost: {}\r\nConnection: close\r\n\r\n",
            self.host
        );
        stream
            .write_all(request.as_bytes())
            .map_err(LinkError::Lost)?;
        let mut response = Vec::new();
        let mut buf = [0u8; 1024];
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(LinkError::Timeout);
            }
            stream
                .set_read_timeout(Some(left.max(Duration::from_millis(1))))
                .map_err(LinkError::Lost)?;
            match stream.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => {
                    response.extend_from_slice(&buf[..n]);
                    if response.len() > MAX_RESPONSE {
                        return Err(LinkError::Garbage(response));
                    }
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(LinkError::Lost(e)),
            }
        }
        body_line(&response).ok_or(LinkError::Garbage(response))
    }
}

/// The first non-empty body line of a `200` response; `None` for anything else.
pub(crate) fn body_line(response: &[u8]) -> Option<Vec<u8>> {
    let split = response.windows(4).position(|w| w == b"\r\n\r\n")?;
    let (head, body) = (&response[..split], &response[split + 4..]);
    let status = head.split(|&b| b == b'\n').next()?;
    let mut words = status.split(|&b| b == b' ');
    let version = words.next()?;
    let code = words.next()?;
    if !version.starts_with(b"HTTP/1.") || code != b"200" {
        return None;
    }
    body.split(|&b| b == b'\r' || b == b'\n')
        .find(|l| !l.is_empty())
        .map(<[u8]>::to_vec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn takes_the_body_of_a_200() {
        let r = b"HTTP/1.0 200 OK\r\nContent-Type: text/plain\r\n\r\n30.25\r\n";
        assert_eq!(body_line(r), Some(b"30.25".to_vec()));
    }

    #[test]
    fn refuses_other_statuses_and_headless_bytes() {
        assert_eq!(body_line(b"HTTP/1.1 404 Not Found\r\n\r\n1"), None);
        assert_eq!(body_line(b"1\r\n"), None);
        assert_eq!(body_line(b"HTTP/1.1 200 OK\r\n\r\n\r\n"), None);
    }

    proptest::proptest! {
        #[test]
        fn body_line_takes_any_bytes(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..256)) {
            if let Some(line) = body_line(&bytes) {
                proptest::prop_assert!(!line.is_empty());
            }
        }
    }
}
