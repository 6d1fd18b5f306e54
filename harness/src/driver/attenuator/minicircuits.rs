//! Mini-Circuits RUDAT/RCDAT programmable attenuators over Ethernet.
//!
//! The command set, as the public drivers that follow Mini-Circuits' programming manual
//! for the programmable attenuators use it (Google's mobly and Android's ACTS Telnet
//! drivers, Fuchsia's HTTP driver, QCoDeS):
//!
//! | command            | answer                                   |
//! |--------------------|------------------------------------------|
//! | `:MN?`             | `MN=RCDAT-6000-90`                       |
//! | `:SN?`             | `SN=11907250023`                         |
//! | `:FIRMWARE?`       | the version, e.g. `C9` (`FIRMWARE=C9` also taken) |
//! | `:ATT?`            | the attenuation in dB, e.g. `30.25`      |
//! | `:SETATT=30.25`    | `1` done, `0` failed, `2` out of range   |
//!
//! Over Telnet (port 23) each command is a CR LF line and each answer a line back; over
//! HTTP (port 80) each is a GET of `/<command>` with the answer as the body. The model
//! name carries the range (`RCDAT-6000-90`: 0 to 90 dB); the step comes from
//! [`MODELS`], or from the rig file for a model the table does not know.

use std::net::{SocketAddr, ToSocketAddrs};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use super::http::HttpLink;
use super::telnet::TelnetLink;
use super::{
    Attenuator, AttenuatorError, Bytes, DbRange, DeviceName, Identity, Setting, round_to_step,
};

/// How long one exchange may take before the device counts as not answering. The units
/// answer on a LAN in milliseconds; two seconds rides out a busy switch or host.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(2);

/// The wait after a confirmed setting before the path counts as at its new value.
/// Mini-Circuits give typical RF switching times of 100 to 900 ns for these models
/// (application note AN-49-005, "Attenuator Switching Time"); 1 ms is over a thousand
/// times that and still small against a radio's packet time.
pub const DEFAULT_SETTLE: Duration = Duration::from_millis(1);

/// What the rig knows of a model: its range and step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelSpec {
    /// Settable range.
    pub range: DbRange,
    /// Smallest step, dB.
    pub step_db: f64,
}

/// Single-channel RUDAT (USB + Ethernet) and RCDAT (Ethernet) models: name, top of the
/// range (the name's last field), step as the datasheets give it (0.25 dB across these
/// families). Check a model's datasheet before adding it; a model missing here needs
/// `range_db` and `step_db` in the rig file.
pub const MODELS: &[(&str, f64, f64)] = &[
    ("RUDAT-6000-30", 30.0, 0.25),
    ("RUDAT-6000-60", 60.0, 0.25),
    ("RUDAT-6000-90", 90.0, 0.25),
    ("RUDAT-6000-110", 110.0, 0.25),
    ("RUDAT-8000-30", 30.0, 0.25),
    ("RUDAT-8000-60", 60.0, 0.25),
    ("RUDAT-8000-90", 90.0, 0.25),
    ("RCDAT-4000-120", 120.0, 0.25),
    ("RCDAT-6000-30", 30.0, 0.25),
    ("RCDAT-6000-60", 60.0, 0.25),
    ("RCDAT-6000-90", 90.0, 0.25),
    ("RCDAT-6000-110", 110.0, 0.25),
    ("RCDAT-8000-30", 30.0, 0.25),
    ("RCDAT-8000-60", 60.0, 0.25),
    ("RCDAT-8000-90", 90.0, 0.25),
];

/// The table's entry for `model` (a trailing `+`, Mini-Circuits' RoHS mark, ignored).
pub fn model_spec(model: &str) -> Option<ModelSpec> {
    let model = model.trim().trim_end_matches('+');
    MODELS
        .iter()
        .find(|(name, ..)| name.eq_ignore_ascii_case(model))
        .map(|&(_, max, step_db)| ModelSpec {
            range: DbRange { min: 0.0, max },
            step_db,
        })
}

/// How the rig talks to the unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Transport {
    /// A Telnet session, TCP port 23.
    #[default]
    Telnet,
    /// One HTTP GET per command, TCP port 80.
    Http,
}

impl Transport {
    /// The unit's port for this transport.
    pub fn default_port(self) -> u16 {
        match self {
            Transport::Telnet => 23,
            Transport::Http => 80,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Transport::Telnet => "telnet",
            Transport::Http => "http",
        }
    }
}

/// Where and how to reach a unit (the resource).
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Host name or IP address.
    pub host: String,
    /// TCP port; `None` for the transport's.
    pub port: Option<u16>,
    pub transport: Transport,
    /// Longest wait for one answer.
    pub timeout: Duration,
    /// Wait after each confirmed setting.
    pub settle: Duration,
    /// Range and step for a model [`MODELS`] does not know (both or neither); they also
    /// override the table for one it knows.
    pub range_step: Option<ModelSpec>,
}

impl Options {
    /// Telnet to `host` on port 23 with the default timeout and settle.
    pub fn new(host: impl Into<String>) -> Self {
        Options {
            host: host.into(),
            port: None,
            transport: Transport::Telnet,
            timeout: DEFAULT_TIMEOUT,
            settle: DEFAULT_SETTLE,
            range_step: None,
        }
    }
}

/// The answer codes of `:SETATT=`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetStatus {
    /// `1`: set.
    Done,
    /// `0`: the command failed.
    Failed,
    /// `2`: the value is above the unit's range.
    OutOfRange,
}

/// Answer text: printable ASCII without surrounding blanks, not empty.
fn text(line: &[u8]) -> Option<&str> {
    let s = std::str::from_utf8(line).ok()?;
    let s = s.trim();
    (!s.is_empty() && s.bytes().all(|b| (0x20..0x7f).contains(&b))).then_some(s)
}

/// Parses a `:SETATT=` answer.
pub fn parse_status(line: &[u8]) -> Option<SetStatus> {
    match text(line)? {
        "1" => Some(SetStatus::Done),
        "0" => Some(SetStatus::Failed),
        "2" => Some(SetStatus::OutOfRange),
        _ => None,
    }
}

/// Parses an `:ATT?` answer: a plain decimal number of dB.
pub fn parse_db(line: &[u8]) -> Option<f64> {
    let s = text(line)?;
    if !s
        .bytes()
        .all(|b| b.is_ascii_digit() || b == b'.' || b == b'-' || b == b'+')
    {
        return None;
    }
    s.parse::<f64>().ok().filter(|db| db.is_finite())
}

/// Parses a `TAG=value` answer (`MN=`, `SN=`): the value, one word.
pub fn parse_tagged(line: &[u8], tag: &str) -> Option<String> {
    let s = text(line)?;
    let (t, value) = s.split_once('=')?;
    let value = value.trim();
    (t.trim().eq_ignore_ascii_case(tag) && !value.is_empty() && !value.contains(' '))
        .then(|| value.to_string())
}

/// Parses a `:FIRMWARE?` answer, with or without a `FIRMWARE=` tag.
pub fn parse_firmware(line: &[u8]) -> Option<String> {
    parse_tagged(line, "FIRMWARE").or_else(|| {
        let s = text(line)?;
        // `0` is the protocol's "failed", not a version.
        (s != "0" && !s.contains([' ', '='])).then(|| s.to_string())
    })
}

/// A dB value as the command takes it: no trailing zeros (`30`, `30.25`).
pub fn format_db(db: f64) -> String {
    let s = format!("{db:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

/// Transport failures, before the driver names the device.
#[derive(Debug)]
pub(crate) enum LinkError {
    Timeout,
    Lost(std::io::Error),
    Garbage(Vec<u8>),
}

enum Link {
    Telnet(TelnetLink),
    Http(HttpLink),
}

/// A connected Mini-Circuits unit (the driver).
pub struct MiniCircuits {
    identity: Identity,
    spec: ModelSpec,
    settle: Duration,
    timeout: Duration,
    link: Link,
}

impl MiniCircuits {
    /// Connects, asks the unit who it is (`:MN?`, `:SN?`, `:FIRMWARE?`) and looks its
    /// model up.
    pub fn connect(options: &Options) -> Result<Self, AttenuatorError> {
        let port = options.port.unwrap_or(options.transport.default_port());
        let address = format!("{}:{port} ({})", options.host, options.transport.name());
        let mut device = DeviceName::at(&address);
        let addr: SocketAddr = (options.host.as_str(), port)
            .to_socket_addrs()
            .and_then(|mut a| {
                a.next()
                    .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "no address"))
            })
            .map_err(|source| AttenuatorError::ConnectionLost {
                device: device.clone(),
                command: "connect".into(),
                source,
            })?;
        let link = match options.transport {
            Transport::Telnet => Link::Telnet(
                TelnetLink::connect(addr, options.timeout)
                    .map_err(|e| named(e, &device, "connect", options.timeout))?,
            ),
            Transport::Http => {
                Link::Http(HttpLink::new(addr, options.host.clone(), options.timeout))
            }
        };
        let mut me = MiniCircuits {
            identity: Identity {
                vendor: "Mini-Circuits".into(),
                address,
                model: String::new(),
                serial: String::new(),
                firmware: None,
            },
            spec: ModelSpec {
                range: DbRange { min: 0.0, max: 0.0 },
                step_db: 1.0,
            },
            settle: options.settle,
            timeout: options.timeout,
            link,
        };
        let model = me.ask(&device, ":MN?", |l| parse_tagged(l, "MN"))?;
        device.model = Some(model.clone());
        let serial = me.ask(&device, ":SN?", |l| parse_tagged(l, "SN"))?;
        device.serial = Some(serial.clone());
        me.identity.model = model;
        me.identity.serial = serial;
        // Some firmware may not know the query: identity without it is still identity.
        let line = me.exchange_as(&device, ":FIRMWARE?")?;
        me.identity.firmware = parse_firmware(&line);
        if me.identity.firmware.is_none() {
            tracing::debug!(answer = %line.escape_ascii(), "attenuator: no firmware version");
        }
        me.spec = match options
            .range_step
            .or_else(|| model_spec(&me.identity.model))
        {
            Some(spec) => spec,
            None => {
                return Err(AttenuatorError::UnknownModel {
                    device,
                    model: me.identity.model.clone(),
                });
            }
        };
        tracing::info!(
            address = %me.identity.address, model = %me.identity.model, serial = %me.identity.serial,
            firmware = ?me.identity.firmware, "attenuator connected"
        );
        Ok(me)
    }

    fn device(&self) -> DeviceName {
        DeviceName::from(&self.identity)
    }

    fn exchange_as(
        &mut self,
        device: &DeviceName,
        command: &str,
    ) -> Result<Vec<u8>, AttenuatorError> {
        let result = match &mut self.link {
            Link::Telnet(t) => t.exchange(command),
            Link::Http(h) => h.exchange(command),
        };
        tracing::trace!(command, answer = ?result.as_ref().map(|l| l.escape_ascii().to_string()), "attenuator");
        result.map_err(|e| named(e, device, command, self.timeout))
    }

    fn ask<T>(
        &mut self,
        device: &DeviceName,
        command: &str,
        parse: impl FnOnce(&[u8]) -> Option<T>,
    ) -> Result<T, AttenuatorError> {
        let line = self.exchange_as(device, command)?;
        parse(&line).ok_or_else(|| AttenuatorError::Garbage {
            device: device.clone(),
            command: command.into(),
            bytes: Bytes(line),
        })
    }
}

/// Names the device and the command in a transport failure.
fn named(e: LinkError, device: &DeviceName, command: &str, timeout: Duration) -> AttenuatorError {
    let device = device.clone();
    let command = command.to_string();
    match e {
        LinkError::Timeout => AttenuatorError::Timeout {
            device,
            command,
            timeout,
        },
        LinkError::Lost(source) => AttenuatorError::ConnectionLost {
            device,
            command,
            source,
        },
        LinkError::Garbage(bytes) => AttenuatorError::Garbage {
            device,
            command,
            bytes: Bytes(bytes),
        },
    }
}

impl Attenuator for MiniCircuits {
    fn identity(&self) -> &Identity {
        &self.identity
    }

    fn range(&self) -> DbRange {
        self.spec.range
    }

    fn step_db(&self) -> f64 {
        self.spec.step_db
    }

    fn settle(&self) -> Duration {
        self.settle
    }

    fn set_db(&mut self, requested_db: f64) -> Result<Setting, AttenuatorError> {
        let device = self.device();
        let range = self.spec.range;
        let Some(db) = round_to_step(requested_db, range, self.spec.step_db) else {
            return Err(AttenuatorError::OutOfRange {
                device,
                db: requested_db,
                range,
            });
        };
        let command = format!(":SETATT={}", format_db(db));
        let line = self.exchange_as(&device, &command)?;
        let meaning = match parse_status(&line) {
            Some(SetStatus::Done) => None,
            Some(SetStatus::Failed) => Some("command failed"),
            Some(SetStatus::OutOfRange) => {
                Some("out of the unit's range; it may now be at its maximum")
            }
            None => {
                return Err(AttenuatorError::Garbage {
                    device,
                    command,
                    bytes: Bytes(line),
                });
            }
        };
        if let Some(meaning) = meaning {
            let answer = String::from_utf8_lossy(&line).trim().to_string();
            return Err(AttenuatorError::Refused {
                device,
                db,
                answer,
                meaning,
            });
        }
        let read_db = self.db()?;
        // The unit prints its setting in its own decimals; anything beyond a hundredth of
        // a step is another setting.
        if (read_db - db).abs() > self.spec.step_db / 100.0 {
            return Err(AttenuatorError::Readback {
                device,
                set_db: db,
                read_db,
            });
        }
        std::thread::sleep(self.settle);
        tracing::debug!(requested_db, db, "attenuator set");
        Ok(Setting {
            requested_db,
            db,
            settled_at: Instant::now(),
        })
    }

    fn db(&mut self) -> Result<f64, AttenuatorError> {
        let device = self.device();
        self.ask(&device, ":ATT?", parse_db)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_answers() {
        assert_eq!(parse_status(b"1"), Some(SetStatus::Done));
        assert_eq!(parse_status(b" 0 "), Some(SetStatus::Failed));
        assert_eq!(parse_status(b"2"), Some(SetStatus::OutOfRange));
        assert_eq!(parse_status(b"3"), None);
        assert_eq!(parse_status(b"1\x00"), None);
        assert_eq!(parse_db(b"30.25"), Some(30.25));
        assert_eq!(parse_db(b"0"), Some(0.0));
        assert_eq!(parse_db(b"inf"), None);
        assert_eq!(parse_db(b"NaN"), None);
        assert_eq!(parse_db(b"3O.25"), None);
        assert_eq!(
            parse_tagged(b"MN=RCDAT-6000-90", "MN"),
            Some("RCDAT-6000-90".into())
        );
        assert_eq!(parse_tagged(b"SN=11907250023", "MN"), None);
        assert_eq!(parse_tagged(b"MN=", "MN"), None);
        assert_eq!(parse_tagged(b"RCDAT-6000-90", "MN"), None);
        assert_eq!(parse_firmware(b"C9"), Some("C9".into()));
        assert_eq!(parse_firmware(b"FIRMWARE=C9"), Some("C9".into()));
        assert_eq!(parse_firmware(b"\xfe\x81"), None);
        assert_eq!(parse_firmware(b"0"), None);
    }

    #[test]
    fn formats_values_as_the_unit_takes_them() {
        assert_eq!(format_db(30.0), "30");
        assert_eq!(format_db(30.25), "30.25");
        assert_eq!(format_db(0.5), "0.5");
        assert_eq!(format_db(0.0), "0");
        assert_eq!(format_db(89.75), "89.75");
    }

    #[test]
    fn the_model_table_knows_the_families() {
        let s = model_spec("RCDAT-6000-90").expect("known");
        assert_eq!(
            s.range,
            DbRange {
                min: 0.0,
                max: 90.0
            }
        );
        assert_eq!(s.step_db, 0.25);
        assert_eq!(model_spec("RUDAT-6000-30+").expect("known").range.max, 30.0);
        assert!(model_spec("RCDAT-18G-63").is_none());
        // Each entry's top is its name's last field: a typo in the table fails here.
        for (name, max, step) in MODELS {
            let named: f64 = name.rsplit('-').next().unwrap().parse().unwrap();
            assert_eq!(named, *max, "{name}");
            assert!(*step > 0.0);
        }
    }

    proptest::proptest! {
        /// Reply parsing takes any bytes without panicking, and what it accepts is sane.
        #[test]
        fn parsers_take_any_bytes(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..64)) {
            let _ = parse_status(&bytes);
            if let Some(db) = parse_db(&bytes) {
                proptest::prop_assert!(db.is_finite());
            }
            if let Some(v) = parse_tagged(&bytes, "MN") {
                proptest::prop_assert!(!v.is_empty() && v.bytes().all(|b| (0x21..0x7f).contains(&b)));
            }
            if let Some(v) = parse_firmware(&bytes) {
                proptest::prop_assert!(!v.is_empty());
            }
        }
    }
}
