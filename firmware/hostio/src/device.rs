//! Which device a serial port name leads to, so a program that reopens a port after it
//! vanished (a USB adapter replugged, a pty closed) never attaches to a *different* device
//! that happens to get the same name: USB renumbering can swap `/dev/ttyUSB0` and
//! `/dev/ttyUSB1`, and a new pty can reuse a closed one's `/dev/pts/N`.
//!
//! A port is named one of three ways ([`PortName`]):
//! - `usb-serial:SERIAL`: the USB serial adapter with that serial number, looked up anew at
//!   each open (through udev, as `serialport::available_ports` does), wherever it enumerates;
//! - a stable name: a symlink such as `/dev/serial/by-id/...` or one a rig made, which is
//!   followed anew at each open (udev moves the link with the device);
//! - a bare device node (`/dev/ttyUSB0`, `/dev/pts/7`): its [`Identity`] (device number, USB
//!   serial number where it has one) is recorded at the first open and must match at every
//!   reopen. A pty has no serial number and its number is reused, so a bare pty node is never
//!   reopened once it went away ([`Reopen::Never`]).

use std::fmt;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// Prefix of a port named by its USB serial number.
pub const USB_SERIAL_PREFIX: &str = "usb-serial:";

/// How a port was named on the command line or in a config file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PortName {
    /// `usb-serial:SERIAL`.
    UsbSerial(String),
    /// A path: a symlink (stable name) or a device node.
    Path(PathBuf),
}

impl PortName {
    /// Parses a port name as given by a user.
    pub fn parse(name: &str) -> Result<Self, DeviceError> {
        match name.strip_prefix(USB_SERIAL_PREFIX) {
            Some("") => Err(DeviceError::EmptySerial(name.to_string())),
            Some(serial) => Ok(Self::UsbSerial(serial.to_string())),
            None if name.is_empty() => Err(DeviceError::EmptySerial(name.to_string())),
            None => Ok(Self::Path(PathBuf::from(name))),
        }
    }

    /// The device node to open now: the adapter with the serial number, wherever it is, or
    /// the path itself (the OS follows a symlink on open).
    pub fn resolve(&self) -> Result<PathBuf, DeviceError> {
        match self {
            Self::UsbSerial(serial) => usb_port_with_serial(serial),
            Self::Path(path) => Ok(path.clone()),
        }
    }

    /// Whether the name itself follows the device (a serial number or a symlink), so that
    /// what it leads to may change between opens.
    pub fn is_stable(&self) -> bool {
        match self {
            Self::UsbSerial(_) => true,
            Self::Path(path) => path
                .symlink_metadata()
                .is_ok_and(|m| m.file_type().is_symlink()),
        }
    }
}

impl fmt::Display for PortName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UsbSerial(serial) => write!(f, "{USB_SERIAL_PREFIX}{serial}"),
            Self::Path(path) => write!(f, "{}", path.display()),
        }
    }
}

/// What a device node is: its device number and, for a USB adapter, its serial number.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity {
    /// `st_rdev` of the node.
    pub rdev: u64,
    /// The USB serial number udev reports for it, if any.
    pub usb_serial: Option<String>,
    /// The node is a pseudo-terminal (`/dev/pts/N`): numbers are reused by unrelated ptys.
    pub pty: bool,
}

impl Identity {
    /// The identity of the device `path` leads to now.
    pub fn of(path: &Path) -> Result<Self, DeviceError> {
        let meta = std::fs::metadata(path).map_err(|source| DeviceError::Stat {
            path: path.to_path_buf(),
            source,
        })?;
        let node = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        Ok(Self {
            rdev: meta.rdev(),
            usb_serial: usb_serial_of(&node),
            pty: node.starts_with("/dev/pts"),
        })
    }
}

impl fmt::Display for Identity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (major, minor) = (dev_major(self.rdev), dev_minor(self.rdev));
        write!(f, "device {major}:{minor}")?;
        match &self.usb_serial {
            Some(serial) => write!(f, ", USB serial {serial}"),
            None if self.pty => write!(f, ", a pty"),
            None => write!(f, ", no USB serial number"),
        }
    }
}

/// Linux `major()`/`minor()` of a `dev_t`.
fn dev_major(dev: u64) -> u64 {
    ((dev >> 32) & 0xffff_f000) | ((dev >> 8) & 0x0000_0fff)
}

fn dev_minor(dev: u64) -> u64 {
    ((dev >> 12) & 0xffff_ff00) | (dev & 0x0000_00ff)
}

/// May a port that closed be opened again, and on which condition.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reopen {
    /// Whatever the name leads to (a serial number or a stable symlink).
    Any,
    /// Only the device recorded at the first open.
    Same(Identity),
    /// Never: a bare pty node that went away (its number now belongs to someone else).
    Never(Identity),
}

impl Reopen {
    /// The rule for a port named `name` whose first open found `first`.
    pub fn after_first_open(name: &PortName, first: Identity) -> Self {
        if name.is_stable() {
            Self::Any
        } else if first.pty {
            Self::Never(first)
        } else {
            Self::Same(first)
        }
    }

    /// Checks the device `path` leads to now before it is reopened. `vanished`: the port
    /// closed because the device went away (hang-up, end of file, I/O error), not because a
    /// write stalled with the device still there.
    pub fn check(&self, path: &Path, vanished: bool) -> Result<(), DeviceError> {
        match self {
            Self::Any => Ok(()),
            Self::Never(was) if vanished => Err(DeviceError::PtyGone {
                path: path.to_path_buf(),
                was: was.clone(),
            }),
            Self::Never(was) | Self::Same(was) => {
                let now = Identity::of(path)?;
                if now.rdev == was.rdev && now.usb_serial == was.usb_serial {
                    Ok(())
                } else {
                    Err(DeviceError::Different {
                        path: path.to_path_buf(),
                        was: was.clone(),
                        now,
                    })
                }
            }
        }
    }
}

/// Why a port cannot be (re)opened.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    /// `usb-serial:` with nothing after it, or an empty name.
    #[error("port name `{0}` names no device")]
    EmptySerial(String),
    /// No USB serial adapter with that serial number is plugged in.
    #[error("no USB serial port with serial number `{serial}` (present: {present})")]
    NoSuchSerial {
        /// The serial number asked for.
        serial: String,
        /// What is there, for the message.
        present: String,
    },
    /// The ports could not be listed.
    #[error("cannot list serial ports: {0}")]
    List(String),
    /// The path leads nowhere.
    #[error("{}: {source}", path.display())]
    Stat {
        /// The port's path.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The name now leads to another device than the one first opened.
    #[error(
        "{} now leads to another device ({now}) than the one first opened ({was}); not \
         attaching to it. Name the port by /dev/serial/by-id/... or usb-serial:SERIAL to follow \
         the device", path.display()
    )]
    Different {
        /// The port's path.
        path: PathBuf,
        /// What was opened first.
        was: Identity,
        /// What the path leads to now.
        now: Identity,
    },
    /// A bare pty node went away: whatever gets its number next is another program's.
    #[error(
        "{} ({was}) went away; a pty's number is reused by unrelated programs, so it is not \
         reopened. Name it by a symlink that whoever recreates it also recreates",
        path.display()
    )]
    PtyGone {
        /// The port's path.
        path: PathBuf,
        /// What was opened first.
        was: Identity,
    },
}

/// The USB serial number of the device node `node`, if it is a USB serial adapter.
fn usb_serial_of(node: &Path) -> Option<String> {
    #[cfg(feature = "serial")]
    {
        let ports = serialport::available_ports().ok()?;
        ports.into_iter().find_map(|p| match p.port_type {
            serialport::SerialPortType::UsbPort(usb) if Path::new(&p.port_name) == node => {
                usb.serial_number
            }
            _ => None,
        })
    }
    #[cfg(not(feature = "serial"))]
    {
        let _ = node;
        None
    }
}

fn usb_port_with_serial(serial: &str) -> Result<PathBuf, DeviceError> {
    #[cfg(feature = "serial")]
    {
        let ports = serialport::available_ports().map_err(|e| DeviceError::List(e.to_string()))?;
        let mut present = Vec::new();
        for p in ports {
            if let serialport::SerialPortType::UsbPort(usb) = &p.port_type {
                match &usb.serial_number {
                    Some(s) if s == serial => return Ok(PathBuf::from(p.port_name)),
                    Some(s) => present.push(format!("{} = {s}", p.port_name)),
                    None => present.push(format!("{} (no serial)", p.port_name)),
                }
            }
        }
        Err(DeviceError::NoSuchSerial {
            serial: serial.to_string(),
            present: if present.is_empty() {
                "no USB serial ports".to_string()
            } else {
                present.join(", ")
            },
        })
    }
    #[cfg(not(feature = "serial"))]
    {
        Err(DeviceError::List(format!(
            "usb-serial:{serial} needs hostio's `serial` feature"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn port_names_parse() {
        assert_eq!(
            PortName::parse("usb-serial:A10K3Z").unwrap(),
            PortName::UsbSerial("A10K3Z".into())
        );
        assert_eq!(
            PortName::parse("/dev/ttyUSB0").unwrap(),
            PortName::Path("/dev/ttyUSB0".into())
        );
        assert!(PortName::parse("usb-serial:").is_err());
        assert!(PortName::parse("").is_err());
        assert_eq!(
            PortName::parse("usb-serial:X").unwrap().to_string(),
            "usb-serial:X"
        );
    }

    #[test]
    fn a_missing_serial_number_is_named_in_the_error() {
        let err = PortName::UsbSerial("NOT-PLUGGED-IN-42".into())
            .resolve()
            .unwrap_err()
            .to_string();
        assert!(err.contains("NOT-PLUGGED-IN-42"), "{err}");
    }

    #[test]
    fn device_numbers_split_like_linux() {
        // /dev/pts/5: major 136, minor 5; a minor above 255 uses the high bits.
        let dev = (136u64 << 8) | 5;
        assert_eq!((dev_major(dev), dev_minor(dev)), (136, 5));
        let big = (136u64 << 8) | ((0x12345 & !0xff) << 12) | (0x12345 & 0xff);
        assert_eq!(dev_minor(big), 0x12345);
    }

    #[test]
    fn a_bare_node_is_reopened_only_while_it_is_the_same_device() {
        let dir = std::env::temp_dir().join(format!("hostio-device-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Two distinct character devices every Linux has.
        let null = Identity::of(Path::new("/dev/null")).unwrap();
        let rule = Reopen::after_first_open(&PortName::Path("/dev/null".into()), null.clone());
        assert_eq!(rule, Reopen::Same(null));
        assert!(rule.check(Path::new("/dev/null"), true).is_ok());
        let err = rule.check(Path::new("/dev/zero"), true).unwrap_err();
        assert!(matches!(err, DeviceError::Different { .. }), "{err}");
        // A symlink is a stable name: followed anew.
        let link = dir.join("radio");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink("/dev/null", &link).unwrap();
        let name = PortName::Path(link.clone());
        let rule = Reopen::after_first_open(&name, Identity::of(&link).unwrap());
        assert_eq!(rule, Reopen::Any);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_bare_pty_is_never_reopened_after_it_went_away_but_is_after_a_stall() {
        let was = Identity {
            rdev: (136 << 8) | 9,
            usb_serial: None,
            pty: true,
        };
        let rule = Reopen::after_first_open(&PortName::Path("/dev/pts/9".into()), was.clone());
        assert_eq!(rule, Reopen::Never(was));
        let err = rule.check(Path::new("/dev/pts/9"), true).unwrap_err();
        assert!(err.to_string().contains("not reopened"), "{err}");
    }
}
