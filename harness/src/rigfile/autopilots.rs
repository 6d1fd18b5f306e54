//! `[autopilots]`: what can play the flight controller behind a companion computer, by name
//! (real autopilots: [`crate::driver::autopilot`]). Device sections refer to them by name.
//!
//! ```toml
//! [autopilots.arducopter]
//! kind = "ardupilot-sitl"
//! program = "../../shared/ardupilot-sitl/arducopter"
//! defaults = "../../shared/ardupilot-sitl/copter.parm"  # optional
//! # model = "quad", home = "-35.363261,149.165230,584,353", speedup = 1.0,
//! # fc_mavlink = 2 (or 1: SERIAL1_PROTOCOL=1), fc_baud = 57600
//!
//! [autopilots.px4]
//! kind = "px4-sitl"
//! root = "../../shared/px4-sitl"                         # holds bin/px4 and etc/
//! # model = "sihsim_quadx", home = "-35.363261,149.165230,584", fc_baud = 57600
//!
//! [autopilots.bench-fc]
//! kind = "serial"
//! port = "/dev/ttyUSB2"
//! baud = 57600
//! # truth = "tcp:192.168.1.20:5760"                     # its second MAVLink link, if wired
//! ```
//!
//! A program that is not there is not an error here: the phases that need it are reported
//! as not run, with how to get one.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::PathBuf;

use serde::Deserialize;

use super::{Checker, RigFileError};
use crate::driver::autopilot::{ArdupilotSitl, AutopilotSpec, DEFAULT_FC_BAUD, Px4Sitl, TruthPort};

/// One `[autopilots.NAME]` as written.
#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub(crate) enum RawAutopilot {
    ArdupilotSitl {
        program: String,
        defaults: Option<PathBuf>,
        model: Option<String>,
        home: Option<String>,
        speedup: Option<f64>,
        fc_mavlink: Option<u8>,
        fc_baud: Option<u32>,
    },
    Px4Sitl {
        root: PathBuf,
        model: Option<String>,
        home: Option<String>,
        fc_baud: Option<u32>,
    },
    Serial {
        port: PathBuf,
        baud: u32,
        truth: Option<String>,
    },
}

impl Checker<'_> {
    /// Checks `[autopilots]`: values in range, paths made absolute.
    pub(crate) fn autopilots(
        &self,
        raw: BTreeMap<String, RawAutopilot>,
    ) -> Result<BTreeMap<String, AutopilotSpec>, RigFileError> {
        let mut out = BTreeMap::new();
        for (name, raw) in raw {
            let at = |key: &'static str| ["autopilots", name.as_str(), key];
            let baud = |key, b: Option<u32>| match b {
                Some(0) => Err(self.invalid(&at(key), "0 baud; e.g. 57600")),
                b => Ok(b.unwrap_or(DEFAULT_FC_BAUD)),
            };
            let spec = match raw {
                RawAutopilot::ArdupilotSitl {
                    program,
                    defaults,
                    model,
                    home,
                    speedup,
                    fc_mavlink,
                    fc_baud,
                } => {
                    if program.is_empty() {
                        return Err(self.invalid(&at("program"), "empty; the SITL binary's path"));
                    }
                    let mut a = ArdupilotSitl::new(self.resolve_program(&program));
                    a.defaults = defaults.map(|d| self.resolve(&d));
                    if let Some(m) = model {
                        a.model = m;
                    }
                    if let Some(h) = home {
                        let parts: Vec<&str> = h.split(',').collect();
                        if parts.len() != 4
                            || parts.iter().any(|p| p.trim().parse::<f64>().is_err())
                        {
                            return Err(self.invalid(
                                &at("home"),
                                format!("\"{h}\" is not lat,lon,alt_m,heading_deg"),
                            ));
                        }
                        a.home = h;
                    }
                    if let Some(s) = speedup {
                        if !(s > 0.0 && s <= 100.0) {
                            return Err(self.invalid(
                                &at("speedup"),
                                format!("{s} is out of range (0, 100]; 1 is real time"),
                            ));
                        }
                        a.speedup = s;
                    }
                    match fc_mavlink {
                        None | Some(1 | 2) => a.fc_mavlink = fc_mavlink.unwrap_or(2),
                        Some(v) => {
                            return Err(self.invalid(
                                &at("fc_mavlink"),
                                format!("{v}: the telemetry port speaks MAVLink 1 or 2"),
                            ));
                        }
                    }
                    a.fc_baud = baud("fc_baud", fc_baud)?;
                    AutopilotSpec::ArdupilotSitl(a)
                }
                RawAutopilot::Px4Sitl {
                    root,
                    model,
                    home,
                    fc_baud,
                } => {
                    let mut p = Px4Sitl::new(self.resolve(&root));
                    if let Some(m) = model {
                        p.model = m;
                    }
                    if let Some(h) = home {
                        if !is_position(&h, 3) {
                            return Err(
                                self.invalid(&at("home"), format!("\"{h}\" is not lat,lon,alt_m"))
                            );
                        }
                        p.home = h;
                    }
                    p.fc_baud = baud("fc_baud", fc_baud)?;
                    AutopilotSpec::Px4Sitl(p)
                }
                RawAutopilot::Serial {
                    port,
                    baud: b,
                    truth,
                } => AutopilotSpec::Serial {
                    port: self.resolve(&port),
                    baud: baud("baud", Some(b))?,
                    truth: truth
                        .map(|t| parse_truth(&t).map_err(|e| self.invalid(&at("truth"), e)))
                        .transpose()?,
                },
            };
            out.insert(name, spec);
        }
        Ok(out)
    }
}

/// Whether `s` is `n` numbers separated by commas.
fn is_position(s: &str, n: usize) -> bool {
    let parts: Vec<&str> = s.split(',').collect();
    parts.len() == n && parts.iter().all(|p| p.trim().parse::<f64>().is_ok())
}

/// `tcp:HOST:PORT` or `udp:HOST:PORT`.
fn parse_truth(s: &str) -> Result<TruthPort, String> {
    let bad = || format!("\"{s}\" is not tcp:ADDRESS:PORT or udp:ADDRESS:PORT");
    let (kind, addr) = s.split_once(':').ok_or_else(bad)?;
    let addr: SocketAddr = addr.parse().map_err(|_| bad())?;
    match kind {
        "tcp" => Ok(TruthPort::Tcp(addr)),
        "udp" => Ok(TruthPort::Udp(addr)),
        _ => Err(bad()),
    }
}
