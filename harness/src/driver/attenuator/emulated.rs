//! An emulated Mini-Circuits attenuator for CI: a TCP server on 127.0.0.1 (an ephemeral
//! port, so parallel tests do not collide) that answers the unit's commands over Telnet
//! lines and HTTP GETs alike, and calls a setter with each attenuation it takes (the rig
//! wires that to the radio emulator's path loss). [`Hostile`] modes misbehave as a unit
//! on a bad day can: refusals, out-of-range answers, a dropped connection, garbage, no
//! answer, a readback that differs. One client at a time, as a unit's Telnet server; the
//! thread stops when the emulator drops.

use std::io::{self, ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use super::minicircuits::{format_db, model_spec};
use super::round_to_step;

/// How often the idle server looks at its stop flag.
const POLL: Duration = Duration::from_millis(5);

/// The bytes [`Hostile::GarbageAfter`] answers with: not ASCII, not a number.
pub const GARBAGE: &[u8] = b"\x80\xfe?ATT\x01\r\n";

/// Called with each attenuation the emulated unit takes, dB.
pub type Setter = Box<dyn FnMut(f64) + Send>;

/// How the emulated unit misbehaves. Counts are of commands since start, over all
/// connections (`:MN?`, `:SN?` and `:FIRMWARE?` on connect count).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Hostile {
    /// Behaves.
    #[default]
    Honest,
    /// Answers `0` to a setting above this many dB.
    RefuseAbove(f64),
    /// Answers `2` to a setting above this many dB and goes to that value, as if its
    /// range ended there.
    OutOfRangeAbove(f64),
    /// Closes the connection on the command after this many, and every connection after.
    DisconnectAfter(usize),
    /// Answers [`GARBAGE`] to every command after this many.
    GarbageAfter(usize),
    /// Never answers a command after this many (the connection stays open).
    StallAfter(usize),
    /// `:ATT?` reports the setting plus this many dB.
    ReadbackOffset(f64),
}

/// Who the emulated unit says it is.
#[derive(Debug, Clone, PartialEq)]
pub struct EmulatedSpec {
    /// Its model name; its range and step are the model table's (a model the table does
    /// not know gets 0 to 90 dB in 0.25 dB steps).
    pub model: String,
    pub serial: String,
    pub firmware: String,
    /// The attenuation at start, dB.
    pub start_db: f64,
    /// Sends each Telnet command line back before its answer (echo mode).
    pub echo: bool,
    pub hostile: Hostile,
}

impl Default for EmulatedSpec {
    fn default() -> Self {
        EmulatedSpec {
            model: "RCDAT-6000-90".into(),
            serial: "EMULATED-0001".into(),
            firmware: "EMU1".into(),
            start_db: 0.0,
            echo: false,
            hostile: Hostile::Honest,
        }
    }
}

struct State {
    db: f64,
    setter: Setter,
    /// Every command received, in order, as sent.
    commands: Vec<String>,
}

struct Shared {
    state: Mutex<State>,
    stop: AtomicBool,
}

impl Shared {
    fn state(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A running emulated unit.
pub struct EmulatedMiniCircuits {
    addr: SocketAddr,
    shared: Arc<Shared>,
    worker: Option<JoinHandle<()>>,
}

impl EmulatedMiniCircuits {
    /// Starts the server on 127.0.0.1 at an ephemeral port.
    pub fn start(spec: EmulatedSpec, setter: Setter) -> io::Result<Self> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                db: spec.start_db,
                setter,
                commands: Vec::new(),
            }),
            stop: AtomicBool::new(false),
        });
        let worker = {
            let shared = Arc::clone(&shared);
            std::thread::Builder::new()
                .name("emulated-attenuator".into())
                .spawn(move || serve(&listener, &spec, &shared))?
        };
        Ok(EmulatedMiniCircuits {
            addr,
            shared,
            worker: Some(worker),
        })
    }

    /// Where it listens.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Its attenuation now, dB.
    pub fn db(&self) -> f64 {
        self.shared.state().db
    }

    /// The commands it received, in order.
    pub fn commands(&self) -> Vec<String> {
        self.shared.state().commands.clone()
    }
}

impl Drop for EmulatedMiniCircuits {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(worker) = self.worker.take() {
            let _ = worker.join();
        }
    }
}

fn serve(listener: &TcpListener, spec: &EmulatedSpec, shared: &Shared) {
    let mut count = 0usize;
    while !shared.stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((stream, _)) => {
                if let Err(e) = session(stream, spec, shared, &mut count) {
                    tracing::debug!(error = %e, "emulated attenuator: session ended");
                }
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => std::thread::sleep(POLL),
            Err(e) => {
                tracing::warn!(error = %e, "emulated attenuator: accept failed");
                std::thread::sleep(POLL);
            }
        }
    }
}

/// What to do with one command.
enum Answer {
    Line(Vec<u8>),
    Silence,
    Hang,
}

/// Serves one connection: Telnet lines until it closes, or one HTTP GET.
fn session(
    mut stream: TcpStream,
    spec: &EmulatedSpec,
    shared: &Shared,
    count: &mut usize,
) -> io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_read_timeout(Some(POLL))?;
    let mut pending: Vec<u8> = Vec::new();
    let mut buf = [0u8; 512];
    loop {
        if shared.stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        match stream.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => pending.extend_from_slice(&buf[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) =>
            {
                continue;
            }
            Err(e) => return Err(e),
        }
        if pending.starts_with(b"GET ") {
            // Read the whole request first: closing on unread bytes resets the
            // connection and the client may lose the answer.
            let Some(end) = pending.windows(4).position(|w| w == b"\r\n\r\n") else {
                continue;
            };
            let head = String::from_utf8_lossy(&pending[..end]).into_owned();
            let target = head
                .lines()
                .next()
                .unwrap_or("")
                .split(' ')
                .nth(1)
                .unwrap_or("");
            let command = target.strip_prefix('/').unwrap_or(target);
            return match answer(command, spec, shared, count) {
                Answer::Line(line) => {
                    let body = String::from_utf8_lossy(&line).into_owned();
                    let response = format!(
                        "HTTP/1.0 200 OK\r\nContent-Type: text/plain\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
                        body.len()
                    );
                    stream.write_all(response.as_bytes())
                }
                Answer::Silence => hang(&stream, shared),
                Answer::Hang => Ok(()),
            };
        }
        while let Some(end) = pending.iter().position(|&b| b == b'\r' || b == b'\n') {
            let line: Vec<u8> = pending.drain(..=end).collect();
            let command = String::from_utf8_lossy(&line[..line.len() - 1])
                .trim()
                .to_string();
            if command.is_empty() {
                continue;
            }
            if spec.echo {
                stream.write_all(format!("{command}\r\n").as_bytes())?;
            }
            match answer(&command, spec, shared, count) {
                Answer::Line(mut line) => {
                    line.extend_from_slice(b"\r\n");
                    stream.write_all(&line)?;
                }
                Answer::Silence => {}
                Answer::Hang => return Ok(()),
            }
        }
    }
}

/// Holds a connection open without answering until the emulator stops or the client
/// goes.
fn hang(mut stream: &TcpStream, shared: &Shared) -> io::Result<()> {
    let mut buf = [0u8; 64];
    while !shared.stop.load(Ordering::Relaxed) {
        match stream.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// The unit's answer to one command (without its line end).
fn answer(command: &str, spec: &EmulatedSpec, shared: &Shared, count: &mut usize) -> Answer {
    let mut state = shared.state();
    state.commands.push(command.to_string());
    *count += 1;
    let after = |n: usize| *count > n;
    match spec.hostile {
        Hostile::DisconnectAfter(n) if after(n) => return Answer::Hang,
        Hostile::GarbageAfter(n) if after(n) => {
            return Answer::Line(GARBAGE[..GARBAGE.len() - 2].to_vec());
        }
        Hostile::StallAfter(n) if after(n) => return Answer::Silence,
        _ => {}
    }
    let upper = command.trim().trim_start_matches(':').to_ascii_uppercase();
    let text = match upper.as_str() {
        "MN?" => format!("MN={}", spec.model),
        "SN?" => format!("SN={}", spec.serial),
        "FIRMWARE?" => spec.firmware.clone(),
        "ATT?" => {
            let offset = if let Hostile::ReadbackOffset(o) = spec.hostile {
                o
            } else {
                0.0
            };
            format_db(state.db + offset)
        }
        _ => match upper.strip_prefix("SETATT=").map(str::parse::<f64>) {
            Some(Ok(db)) => set(&mut state, db, spec).to_string(),
            // Not a command this emulation knows, or no number: "failed".
            _ => "0".to_string(),
        },
    };
    Answer::Line(text.into_bytes())
}

/// Applies a setting as the unit would; its status code.
fn set(state: &mut State, db: f64, spec: &EmulatedSpec) -> u8 {
    let (range, step) = model_spec(&spec.model)
        .map(|m| (m.range, m.step_db))
        .unwrap_or((
            super::DbRange {
                min: 0.0,
                max: 90.0,
            },
            0.25,
        ));
    let top = match spec.hostile {
        Hostile::RefuseAbove(limit) if db > limit => return 0,
        Hostile::OutOfRangeAbove(limit) => limit.min(range.max),
        _ => range.max,
    };
    if !db.is_finite() || db < range.min {
        return 0;
    }
    let (db, code) = if db > top {
        (top, 2)
    } else {
        (round_to_step(db, range, step).unwrap_or(top), 1)
    };
    state.db = db;
    (state.setter)(db);
    code
}
