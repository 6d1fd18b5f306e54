//! The programs' status stream: one JSON object a line, schema [`SCHEMA`], documented with
//! every field in `firmware/hostio/STATUS-JSON.md`.
//!
//! A program given `--status-json PATH` opens a [`StatusWriter`] on it (`-` is stdout), writes
//! a [`Kind::Start`] line, a [`Kind::Status`] line every status period and a [`Kind::Stop`]
//! line as it ends. Each line is written whole, in one `write` call on an unbuffered file, so
//! a reader may follow the file while the program runs and a program killed at any instant
//! leaves only complete lines behind.
//!
//! Log lines show the same values: [`fields`] renders a status body as the `key=value` text
//! of a log line, so the log and the file are made from one value and cannot drift.
//!
//! A reader parses each line as a [`Line`], which refuses any other schema.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

/// The schema every line names: a reader must check it. Adding a field keeps `/1`; renaming
/// or removing one, or changing its meaning or unit, makes it `/2`.
pub const SCHEMA: &str = "c2-status/1";

/// What a line reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// The first line: program version, process id and the options that matter.
    Start,
    /// The counters now, once every status period.
    Status,
    /// Something happened, written when it did: `event` names it, the other fields are the
    /// event's (a router's link announcement: `link_notice`).
    Event,
    /// The last line: how the program ends, and its final counters if it got running.
    Stop,
    /// A kind added since this reader was written: readers pass over it (never written).
    #[serde(other, skip_serializing)]
    Other,
}

/// The status file could not be opened or written.
#[derive(Debug, thiserror::Error)]
pub enum StatusError {
    /// The file could not be created (a missing folder, no permission).
    #[error("status file {}: cannot create: {error}", path.display())]
    Create {
        /// The path given.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// A line could not be written (disk full, a closed stdout).
    #[error("status file {}: cannot write: {error}", path.display())]
    Write {
        /// The path given.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// A body is not a JSON object (a program's bug: every body is a struct or a map).
    #[error("status line body: {0}")]
    Body(#[from] serde_json::Error),
}

/// Where the lines go.
#[derive(Debug)]
enum Out {
    File(File),
    Stdout,
}

/// Writes a program's status lines to a file (`-`: stdout), each line flushed as it is
/// written.
#[derive(Debug)]
pub struct StatusWriter {
    out: Out,
    path: PathBuf,
    program: &'static str,
    started: Instant,
    /// The last [`write_periodic`](Self::write_periodic) failed.
    failing: bool,
}

/// The fields every line starts with.
#[derive(Serialize)]
struct Envelope<'a, T: ?Sized> {
    schema: &'static str,
    program: &'a str,
    kind: Kind,
    t_s: f64,
    mono_s: f64,
    #[serde(flatten)]
    body: &'a T,
}

/// The body of an event line.
#[derive(Serialize)]
struct Event<'a, T: ?Sized> {
    event: &'a str,
    #[serde(flatten)]
    fields: &'a T,
}

/// The body of a start line.
#[derive(Serialize)]
struct Start<'a, O: ?Sized> {
    version: &'a str,
    pid: u32,
    options: &'a O,
}

/// The body of a stop line: the final status flattened in, when there is one.
#[derive(Serialize)]
struct Stop<'a, S: ?Sized> {
    exit_code: u8,
    error: Option<&'a str>,
    #[serde(flatten)]
    status: Option<&'a S>,
}

impl StatusWriter {
    /// Creates (or truncates) `path` for `program`'s lines; `-` writes to stdout.
    pub fn create(path: &Path, program: &'static str) -> Result<Self, StatusError> {
        let out = if path == Path::new("-") {
            Out::Stdout
        } else {
            Out::File(File::create(path).map_err(|error| StatusError::Create {
                path: path.to_owned(),
                error,
            })?)
        };
        Ok(Self {
            out,
            path: path.to_owned(),
            program,
            started: Instant::now(),
            failing: false,
        })
    }

    /// The path it writes to.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes one line of `kind` whose fields after the envelope are `body`'s (a struct or a
    /// map whose keys are not the envelope's).
    pub fn write<T: Serialize + ?Sized>(
        &mut self,
        kind: Kind,
        body: &T,
    ) -> Result<(), StatusError> {
        let mut line = serde_json::to_vec(&Envelope {
            schema: SCHEMA,
            program: self.program,
            kind,
            t_s: round_us(self.started.elapsed()),
            mono_s: round_us(monotonic()),
            body,
        })?;
        line.push(b'\n');
        // One write of the whole line (an unbuffered file, or stdout's line buffer, which
        // passes a line ending in a newline straight through): a reader never sees half a
        // line, not even from a program killed mid-run. `write_all` loops only on a short
        // write, which a regular file gives only when the disk is full.
        let written = match &mut self.out {
            Out::File(f) => f.write_all(&line),
            Out::Stdout => {
                let mut out = std::io::stdout().lock();
                out.write_all(&line).and_then(|()| out.flush())
            }
        };
        written.map_err(|error| StatusError::Write {
            path: self.path.clone(),
            error,
        })
    }

    /// Writes a line that the next period will follow (a status line): a failure is not
    /// returned but logged, once when writes start failing and once when they work again, so
    /// a full disk never stops the program nor floods its log.
    pub fn write_periodic<T: Serialize + ?Sized>(&mut self, kind: Kind, body: &T) {
        match self.write(kind, body) {
            Err(e) if !self.failing => {
                tracing::warn!(error = %e, "status line not written; retrying each period");
                self.failing = true;
            }
            Ok(()) if self.failing => {
                tracing::info!(path = %self.path.display(), "status lines written again");
                self.failing = false;
            }
            _ => {}
        }
    }

    /// Writes an event line: `event` names what happened, `fields` (a struct or map) say the
    /// rest. A failure is logged, as a status line's is.
    pub fn event<T: Serialize + ?Sized>(&mut self, event: &str, fields: &T) {
        self.write_periodic(Kind::Event, &Event { event, fields });
    }

    /// Writes the start line: `version`, this process's id and `options` (a struct or map).
    pub fn start<O: Serialize + ?Sized>(
        &mut self,
        version: &str,
        options: &O,
    ) -> Result<(), StatusError> {
        self.write(
            Kind::Start,
            &Start {
                version,
                pid: std::process::id(),
                options,
            },
        )
    }

    /// Writes the stop line: the exit status the program ends with, why (`result`'s error, if
    /// any) and its final `status` (if it got running), whose fields are flattened in as on a
    /// status line. A failure is logged: the program ends all the same.
    pub fn stop<S: Serialize + ?Sized, E: std::fmt::Display>(
        &mut self,
        exit_code: u8,
        result: &Result<(), E>,
        status: Option<&S>,
    ) {
        let error = result.as_ref().err().map(|e| format!("{e:#}"));
        let body = Stop {
            exit_code,
            error: error.as_deref(),
            status,
        };
        if let Err(e) = self.write(Kind::Stop, &body) {
            tracing::error!(error = %e, "no stop line");
        }
    }
}

/// Seconds, to the microsecond (what a line's reader can use, in fewer characters).
fn round_us(d: Duration) -> f64 {
    (d.as_micros() as f64) / 1e6
}

/// CLOCK_MONOTONIC now: the clock the rig and its fixtures stamp events with.
fn monotonic() -> Duration {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::Monotonic);
    Duration::new(t.tv_sec as u64, t.tv_nsec as u32)
}

/// A status body as the `key=value` fields of a log line (`signing=on fc_rx=120 ...`), in the
/// body's own order: nested objects (`counters`, `gauges`) are flattened into their fields,
/// strings are written bare, `null` as `None`. Keys are the JSON keys, so a log line and a
/// JSON line name a value alike.
pub fn fields<T: Serialize + ?Sized>(body: &T) -> Result<String, serde_json::Error> {
    use serde::de::DeserializeSeed as _;
    // Read back from its JSON text: a `serde_json::Value` would sort the keys.
    let text = serde_json::to_string(body)?;
    let mut out = String::new();
    Flatten {
        out: &mut out,
        key: "",
    }
    .deserialize(&mut serde_json::Deserializer::from_str(&text))?;
    Ok(out)
}

/// Appends the value it reads to `out` as `key=value`, an object as its fields.
struct Flatten<'a> {
    out: &'a mut String,
    key: &'a str,
}

impl Flatten<'_> {
    fn push(self, value: &dyn std::fmt::Display) {
        if !self.out.is_empty() {
            self.out.push(' ');
        }
        self.out.push_str(self.key);
        self.out.push('=');
        self.out.push_str(&value.to_string());
    }
}

impl<'de> serde::de::DeserializeSeed<'de> for Flatten<'_> {
    type Value = ();

    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

/// `visit_*` methods that write the value as it displays.
macro_rules! scalars {
    ($($visit:ident: $t:ty),*) => {
        $(
            fn $visit<E>(self, v: $t) -> Result<(), E> {
                self.push(&v);
                Ok(())
            }
        )*
    };
}

impl<'de> serde::de::Visitor<'de> for Flatten<'_> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(key) = map.next_key::<String>()? {
            map.next_value_seed(Flatten {
                out: &mut *self.out,
                key: &key,
            })?;
        }
        Ok(())
    }

    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut items = Vec::new();
        while let Some(v) = seq.next_element::<Value>()? {
            items.push(v);
        }
        self.push(&Value::Array(items));
        Ok(())
    }

    fn visit_str<E>(self, v: &str) -> Result<(), E> {
        self.push(&v);
        Ok(())
    }

    scalars!(visit_bool: bool, visit_u64: u64, visit_i64: i64, visit_f64: f64);

    fn visit_unit<E>(self) -> Result<(), E> {
        self.push(&"None");
        Ok(())
    }
}

/// One line of a status file, as a reader sees it. Every field of every kind, known or added
/// since, is kept in `rest` (`version`, `options`, `signing`, `exit_code`, ...).
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct Line {
    /// Always [`SCHEMA`]: [`Line::parse`] refuses any other.
    pub schema: String,
    /// The program that wrote it.
    pub program: String,
    /// What it reports.
    pub kind: Kind,
    /// Seconds since the start line.
    pub t_s: f64,
    /// CLOCK_MONOTONIC seconds when it was written.
    pub mono_s: f64,
    /// On status lines, and on the stop line of a program that got running: totals and
    /// maxima since the start, none ever smaller than on an earlier line.
    #[serde(default)]
    pub counters: Option<Map<String, Value>>,
    /// With `counters`: levels now, which go up and down.
    #[serde(default)]
    pub gauges: Option<Map<String, Value>>,
    /// The kind's other fields.
    #[serde(flatten)]
    pub rest: Map<String, Value>,
}

/// A line that is not a status line of this schema.
#[derive(Debug, thiserror::Error)]
pub enum LineError {
    /// Not JSON, or without the envelope's fields.
    #[error("not a status line: {0}")]
    Json(#[from] serde_json::Error),
    /// Another schema (or version) than [`SCHEMA`].
    #[error("schema {found:?}, this reader knows {SCHEMA:?}")]
    Schema {
        /// The schema the line names.
        found: String,
    },
}

impl Line {
    /// Parses one line (without its newline) and checks its schema.
    pub fn parse(text: &str) -> Result<Self, LineError> {
        let line: Self = serde_json::from_str(text)?;
        if line.schema != SCHEMA {
            return Err(LineError::Schema { found: line.schema });
        }
        Ok(line)
    }

    /// A counter as a number, `None` if this line has no such counter.
    pub fn counter(&self, name: &str) -> Option<f64> {
        self.counters.as_ref()?.get(name)?.as_f64()
    }

    /// A gauge as a number, `None` if this line has no such gauge.
    pub fn gauge(&self, name: &str) -> Option<f64> {
        self.gauges.as_ref()?.get(name)?.as_f64()
    }
}

/// A line of a status file that is not a status line of this schema.
#[derive(Debug, thiserror::Error)]
#[error("line {line}: {error}")]
pub struct FileError {
    /// Its number, from 1.
    pub line: usize,
    /// What is wrong with it.
    #[source]
    pub error: LineError,
}

/// Every line of `text` (a whole status file), in order. Only a torn last line (a program
/// killed mid-write: no newline after it) is passed over; any other line that is not a status
/// line of this schema is an error naming it.
pub fn lines(text: &str) -> Result<Vec<Line>, FileError> {
    let torn = !text.is_empty() && !text.ends_with('\n');
    let raw: Vec<&str> = text.lines().collect();
    let mut out = Vec::with_capacity(raw.len());
    for (i, l) in raw.iter().enumerate() {
        match Line::parse(l) {
            Ok(line) => out.push(line),
            Err(_) if torn && i + 1 == raw.len() => {}
            Err(error) => return Err(FileError { line: i + 1, error }),
        }
    }
    Ok(out)
}

/// The last line of `text` (a whole status file) that carries counters: the stop line of a
/// program that ended after running, else its latest status line (a program still running,
/// or killed); `None` if it has none. Errors as [`lines`].
pub fn last_counters(text: &str) -> Result<Option<Line>, FileError> {
    Ok(lines(text)?
        .into_iter()
        .rev()
        .find(|l| l.counters.is_some()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("hostio-status-{name}-{}", std::process::id()))
    }

    #[derive(Serialize)]
    struct Body {
        signing: &'static str,
        peer_loss: Option<f64>,
        counters: Counters,
        gauges: Gauges,
    }

    #[derive(Serialize)]
    struct Counters {
        frames: u64,
    }

    #[derive(Serialize)]
    struct Gauges {
        queued_bytes: u64,
    }

    #[test]
    fn lines_carry_the_envelope_and_round_trip_through_the_reader() {
        let path = temp("round-trip");
        let mut w = StatusWriter::create(&path, "test-program").unwrap();
        w.start("1.2.3", &serde_json::json!({ "rate": 683 }))
            .unwrap();
        let body = Body {
            signing: "on",
            peer_loss: None,
            counters: Counters { frames: 7 },
            gauges: Gauges { queued_bytes: 3 },
        };
        w.write(Kind::Status, &body).unwrap();
        w.stop(0, &Ok::<(), String>(()), Some(&body));
        let text = std::fs::read_to_string(&path).unwrap();
        let _ = std::fs::remove_file(&path);
        assert!(text.ends_with('\n'), "{text}");
        let lines: Vec<Line> = text.lines().map(|l| Line::parse(l).unwrap()).collect();
        assert_eq!(
            lines.iter().map(|l| l.kind).collect::<Vec<_>>(),
            [Kind::Start, Kind::Status, Kind::Stop]
        );
        assert!(lines.iter().all(|l| l.program == "test-program"));
        assert_eq!(lines[0].rest["version"], "1.2.3");
        assert_eq!(lines[0].rest["pid"], std::process::id());
        assert_eq!(lines[0].rest["options"]["rate"], 683);
        assert_eq!(lines[1].counter("frames"), Some(7.0));
        assert_eq!(lines[1].gauge("queued_bytes"), Some(3.0));
        assert_eq!(lines[1].rest["peer_loss"], Value::Null);
        assert_eq!(lines[2].rest["exit_code"], 0);
        assert_eq!(lines[2].rest["error"], Value::Null);
        assert_eq!(lines[2].counter("frames"), Some(7.0));
        assert!(lines[0].mono_s > 0.0 && lines[2].t_s >= lines[0].t_s);
        assert_eq!(last_counters(&text).unwrap().unwrap().kind, Kind::Stop);
    }

    #[test]
    fn a_stop_before_running_has_the_error_and_no_counters() {
        let path = temp("failed");
        let mut w = StatusWriter::create(&path, "p").unwrap();
        w.start("0", &serde_json::json!({})).unwrap();
        w.stop::<Body, _>(1, &Err("radio port: no such device"), None);
        let text = std::fs::read_to_string(&path).unwrap();
        let _ = std::fs::remove_file(&path);
        let stop = Line::parse(text.lines().last().unwrap()).unwrap();
        assert_eq!(stop.kind, Kind::Stop);
        assert_eq!(stop.rest["exit_code"], 1);
        assert_eq!(stop.rest["error"], "radio port: no such device");
        assert!(stop.counters.is_none());
        assert!(last_counters(&text).unwrap().is_none());
    }

    #[test]
    fn the_last_counters_skip_a_torn_last_line() {
        let status = r#"{"schema":"c2-status/1","program":"p","kind":"status","t_s":1.0,"mono_s":9.0,"counters":{"n":4},"gauges":{}}"#;
        let text = format!("{status}\n{{\"schema\":\"c2-sta");
        assert_eq!(
            last_counters(&text).unwrap().unwrap().counter("n"),
            Some(4.0)
        );
        // The same bytes inside the file are not a torn line but a bad one.
        let e = last_counters(&format!("{status}\n{{\"schema\":\"c2-sta\n{status}\n")).unwrap_err();
        assert_eq!(e.line, 2);
        let other = status.replace("c2-status/1", "c2-status/2");
        let e = last_counters(&format!("{status}\n{other}\n")).unwrap_err();
        assert!(matches!(e.error, LineError::Schema { .. }), "{e}");
    }

    #[test]
    fn another_schema_is_refused() {
        let line =
            r#"{"schema":"c2-status/2","program":"p","kind":"status","t_s":1.0,"mono_s":9.0}"#;
        assert!(
            matches!(Line::parse(line), Err(LineError::Schema { found }) if found == "c2-status/2")
        );
    }

    #[test]
    fn a_missing_folder_is_an_error_naming_the_path() {
        let path = temp("no-such-folder").join("status.jsonl");
        let e = StatusWriter::create(&path, "p").unwrap_err();
        assert!(e.to_string().contains(&path.display().to_string()), "{e}");
    }

    #[test]
    fn log_fields_flatten_the_body_with_the_json_keys() {
        let body = Body {
            signing: "OFF",
            peer_loss: Some(0.25),
            counters: Counters { frames: 7 },
            gauges: Gauges { queued_bytes: 0 },
        };
        assert_eq!(
            fields(&body).unwrap(),
            "signing=OFF peer_loss=0.25 frames=7 queued_bytes=0"
        );
        let unknown = Body {
            peer_loss: None,
            ..body
        };
        assert!(fields(&unknown).unwrap().contains("peer_loss=None"));
    }
}
