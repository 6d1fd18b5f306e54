//! Real autopilots as rig resources: what plays the flight controller behind a companion
//! computer. Each kind starts (or opens) the autopilot, hands back the serial port its
//! telemetry link is on (what the bridge opens) and, where the autopilot has one, a second
//! MAVLink connection that tells the truth: what the vehicle really holds, where it is and
//! what mode it is in, unfiltered by the link under test.
//!
//! - [`AutopilotSpec::ArdupilotSitl`]: ArduPilot's software-in-the-loop build
//!   ([`ardupilot_sitl`]), SERIAL1 on a pty, SERIAL0 (TCP) as truth;
//! - [`AutopilotSpec::Px4Sitl`]: PX4's SITL with its built-in SIH physics ([`px4_sitl`]), an
//!   extra MAVLink instance on a pty, its UDP ground-station link as truth;
//! - [`AutopilotSpec::Serial`]: a real flight controller on a bench port, truth only if wired.
//!
//! Several SITL instances may run at once: each takes an instance number whose ports are
//! free ([`Instances`]) and a working folder of its own.

pub mod ardupilot_sitl;
pub mod px4_sitl;

use std::fmt;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitStatus;
use std::time::Duration;

use crate::driver::process::Process;
use crate::driver::pty::PtyCable;
pub use ardupilot_sitl::ArdupilotSitl;
pub use px4_sitl::Px4Sitl;

/// Baud rate of the flight controller's telemetry port unless the rig file says: the SiK
/// radios' and ArduPilot's default for SERIAL1. A pty does not pace bytes; the autopilot's
/// own rate setting for the port does.
pub const DEFAULT_FC_BAUD: u32 = 57_600;

/// One `[autopilots.NAME]` of a rig file, checked.
#[derive(Debug, Clone, PartialEq)]
pub enum AutopilotSpec {
    ArdupilotSitl(ArdupilotSitl),
    Px4Sitl(Px4Sitl),
    /// A flight controller on a serial port of the bench.
    Serial {
        port: PathBuf,
        baud: u32,
        /// Its second MAVLink connection, when wired (e.g. a TCP bridge on its USB port).
        truth: Option<TruthPort>,
    },
}

/// Where the autopilot's own word is read, beside the link under test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TruthPort {
    /// A TCP server of the autopilot (ArduPilot SITL's SERIAL0).
    Tcp(SocketAddr),
    /// A UDP port of the autopilot that answers whoever sends to it (PX4's GCS link).
    Udp(SocketAddr),
}

impl TruthPort {
    /// The truth fixture's (`fixtures/sitl_truth.py`) arguments to connect to it.
    pub fn fixture_args(&self) -> [String; 2] {
        match self {
            TruthPort::Tcp(a) => ["--tcp".into(), a.to_string()],
            TruthPort::Udp(a) => ["--udp-out".into(), a.to_string()],
        }
    }
}

impl fmt::Display for TruthPort {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TruthPort::Tcp(a) => write!(f, "tcp:{a}"),
            TruthPort::Udp(a) => write!(f, "udp:{a}"),
        }
    }
}

/// Why an autopilot could not be used.
#[derive(Debug, thiserror::Error)]
pub enum AutopilotError {
    /// Its program (or a file it needs) is not there: the phases that need it do not run.
    #[error("{what} not found at {}: {how}", path.display())]
    Missing {
        what: String,
        path: PathBuf,
        /// How to get one.
        how: &'static str,
    },
    /// It could not be started (the message names it and its log).
    #[error("{name}: {source:#}")]
    Start { name: String, source: anyhow::Error },
    /// It died while a phase used it.
    #[error("{name} died ({status}); last lines of {}:\n{tail}", log.display())]
    Died {
        name: String,
        status: ExitStatus,
        log: PathBuf,
        tail: String,
    },
    /// No instance number with free ports was found.
    #[error("no free SITL instance: ports of instances {first}..{last} are all taken")]
    NoInstance { first: u16, last: u16 },
}

impl AutopilotSpec {
    /// The kind, as the rig file writes it.
    pub fn kind(&self) -> &'static str {
        match self {
            AutopilotSpec::ArdupilotSitl(_) => "ardupilot-sitl",
            AutopilotSpec::Px4Sitl(_) => "px4-sitl",
            AutopilotSpec::Serial { .. } => "serial",
        }
    }

    /// Whether everything it needs is there; the error says how to get what is not.
    pub fn available(&self) -> Result<(), AutopilotError> {
        match self {
            AutopilotSpec::ArdupilotSitl(a) => a.available(),
            AutopilotSpec::Px4Sitl(p) => p.available(),
            AutopilotSpec::Serial { port, .. } => {
                if port.exists() {
                    Ok(())
                } else {
                    Err(AutopilotError::Missing {
                        what: "the flight controller's port".into(),
                        path: port.clone(),
                        how: "plug the flight controller's telemetry adapter in, or fix \
                              [autopilots.NAME].port",
                    })
                }
            }
        }
    }

    /// Starts it (a SITL in a working folder below `dir`, its log there too) and returns it
    /// running, its telemetry port ready for the bridge to open. `name` is its rig-file name.
    pub fn start(&self, name: &str, dir: &Path) -> Result<Autopilot, AutopilotError> {
        self.available()?;
        // A SITL runs in a folder of its own: every path it is given must not depend on
        // where the rig runs (`rig run --out target/rig-report`).
        let dir = &std::path::absolute(dir).map_err(|e| AutopilotError::Start {
            name: name.to_string(),
            source: anyhow::anyhow!("cannot make {} absolute: {e}", dir.display()),
        })?;
        match self {
            AutopilotSpec::ArdupilotSitl(a) => a.start(name, dir),
            AutopilotSpec::Px4Sitl(p) => p.start(name, dir),
            AutopilotSpec::Serial { port, truth, .. } => Ok(Autopilot {
                name: name.to_string(),
                sysid: 1,
                fc_port: port.display().to_string(),
                truth: *truth,
                process: None,
                cable: None,
                leftovers: Vec::new(),
            }),
        }
    }

    /// The baud rate of its telemetry port (what the bridge opens it at).
    pub fn fc_baud(&self) -> u32 {
        match self {
            AutopilotSpec::ArdupilotSitl(a) => a.fc_baud,
            AutopilotSpec::Px4Sitl(p) => p.fc_baud,
            AutopilotSpec::Serial { baud, .. } => *baud,
        }
    }
}

/// A started (or opened) autopilot.
pub struct Autopilot {
    /// Its rig-file name.
    pub name: String,
    /// Its MAVLink system id (PX4 SITL instance N is system N + 1).
    pub sysid: u8,
    fc_port: String,
    truth: Option<TruthPort>,
    process: Option<Process>,
    /// The pty pair between a SITL and the bridge, alive as long as the autopilot.
    cable: Option<PtyCable>,
    /// Files a SITL leaves outside its working folder, removed once it is stopped.
    leftovers: Vec<PathBuf>,
}

impl Autopilot {
    /// The serial port the bridge opens: the autopilot's telemetry link.
    pub fn fc_port(&self) -> &str {
        &self.fc_port
    }

    /// Its truth connection, if it has one.
    pub fn truth(&self) -> Option<TruthPort> {
        self.truth
    }

    /// The started SITL's process id.
    pub fn pid(&self) -> Option<u32> {
        self.process.as_ref().map(Process::id)
    }

    /// The SITL's log (its stdout and stderr), if the rig started one.
    pub fn log_path(&self) -> Option<&Path> {
        self.process.as_ref().map(Process::log_path)
    }

    /// An error naming it, with its log's last lines, if it is no longer running.
    pub fn check_running(&mut self) -> Result<(), AutopilotError> {
        let Some(p) = self.process.as_mut() else {
            return Ok(());
        };
        match p.wait_timeout(Duration::ZERO) {
            Ok(Some(status)) => Err(AutopilotError::Died {
                name: self.name.clone(),
                status,
                log: p.log_path().to_path_buf(),
                tail: tail(p.log_path(), 8),
            }),
            _ => Ok(()),
        }
    }

    /// Stops a started SITL (SIGTERM, then SIGKILL after `grace`); whether it had died
    /// before is [`Autopilot::check_running`]'s to say.
    pub fn stop(&mut self, grace: Duration) {
        if let Some(p) = self.process.as_mut() {
            p.stop(grace);
            for f in self.leftovers.drain(..) {
                let _ = std::fs::remove_file(f);
            }
        }
        self.cable = None;
    }
}

/// The last `n` lines of a log, for an error message.
fn tail(log: &Path, n: usize) -> String {
    let text = std::fs::read_to_string(log).unwrap_or_default();
    let lines: Vec<&str> = text.lines().rev().take(n).collect();
    lines.into_iter().rev().collect::<Vec<_>>().join("\n")
}

/// Hands out SITL instance numbers whose ports are free now, never the same twice in one
/// rig process (two sessions side by side must not share ports, and a port another program
/// holds is passed over).
pub struct Instances {
    next: std::sync::Mutex<u16>,
    first: u16,
    last: u16,
}

impl Instances {
    pub const fn new(first: u16, last: u16) -> Instances {
        Instances {
            next: std::sync::Mutex::new(first),
            first,
            last,
        }
    }

    /// The next instance for which `free(instance)` holds.
    pub fn take(&self, free: impl Fn(u16) -> bool) -> Result<u16, AutopilotError> {
        let mut next = self.next.lock().unwrap_or_else(|e| e.into_inner());
        let span = self.last - self.first + 1;
        for _ in 0..span {
            let n = *next;
            *next = if n >= self.last { self.first } else { n + 1 };
            if free(n) {
                return Ok(n);
            }
        }
        Err(AutopilotError::NoInstance {
            first: self.first,
            last: self.last,
        })
    }
}

/// Whether a TCP port on loopback can be bound now.
pub(crate) fn tcp_free(port: u16) -> bool {
    std::net::TcpListener::bind(("127.0.0.1", port)).is_ok()
        && std::net::TcpListener::bind(("0.0.0.0", port)).is_ok()
}

/// Whether a UDP port on loopback can be bound now.
pub(crate) fn udp_free(port: u16) -> bool {
    std::net::UdpSocket::bind(("0.0.0.0", port)).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn instances_skip_taken_ports_and_never_repeat_while_free_ones_remain() {
        let instances = Instances::new(3, 6);
        let taken = [4u16];
        let got: Vec<u16> = (0..3)
            .map(|_| instances.take(|n| !taken.contains(&n)).unwrap())
            .collect();
        assert_eq!(got, [3, 5, 6]);
        let err = instances.take(|_| false).err().unwrap();
        assert!(err.to_string().contains("3..6"), "{err}");
    }

    #[test]
    fn a_missing_sitl_says_how_to_get_one() {
        let spec =
            AutopilotSpec::ArdupilotSitl(ArdupilotSitl::new(PathBuf::from("/nowhere/arducopter")));
        let err = spec.available().err().unwrap().to_string();
        assert!(err.contains("/nowhere/arducopter"), "{err}");
        assert!(err.contains("waf"), "{err}");
    }
}
