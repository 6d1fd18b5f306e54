//! PX4 SITL with its built-in SIH physics (no Gazebo): `bin/px4 -d etc -w WORK -i N` with
//! `PX4_SIM_MODEL`/`PX4_SIMULATOR` set, and an extra MAVLink instance (Normal mode) on the pty
//! the bridge opens (`PX4_MAVLINK_SERIAL`, started by the airframe's `.post` hook that
//! `../shared/px4-sitl` carries; a user's build needs the same two lines, see its README).
//! Its ground-station link (UDP, local port 18570 + N) answers whoever sends to it: the truth.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::Context;

use super::{Autopilot, AutopilotError, DEFAULT_FC_BAUD, Instances, TruthPort, udp_free};
use crate::driver::process::Process;
use crate::driver::pty::PtyCable;

/// What a user who has no PX4 SITL build is told.
pub const HOW_TO_GET: &str = "build PX4 SITL (git clone --recurse-submodules \
    https://github.com/PX4/PX4-Autopilot; make px4_sitl_default), add the PX4_MAVLINK_SERIAL \
    hook to the SIH airframe and point [autopilots.NAME].root at the folder holding bin/px4 and \
    etc/, as ../shared/px4-sitl/README.md says";

/// The GCS link's local UDP port of instance 0 (`px4-rc.mavlink`).
const GCS_PORT_BASE: u16 = 18570;
/// The offboard link's local port of instance 0.
const OFFBOARD_PORT_BASE: u16 = 14580;

/// The socket instance `n`'s client commands reach its server through: PX4 replaces a stale
/// one at start, but leaves it behind when stopped.
fn server_socket(n: u16) -> PathBuf {
    PathBuf::from(format!("/tmp/px4-sock-{n}"))
}

/// PX4 shares one remote offboard port above instance 9; the rig stays below it.
static INSTANCES: Instances = Instances::new(5, 9);

/// `kind = "px4-sitl"`.
#[derive(Debug, Clone, PartialEq)]
pub struct Px4Sitl {
    /// Folder holding `bin/px4` (with its `px4-*` links) and `etc/` (the ROMFS).
    pub root: PathBuf,
    /// `PX4_SIM_MODEL`: an SIH airframe.
    pub model: String,
    /// `lat,lon,alt_m` (`PX4_HOME_LAT`/`_LON`/`_ALT`): by default ArduPilot autotest's home,
    /// so both autopilots fly the same plans.
    pub home: String,
    pub fc_baud: u32,
}

impl Px4Sitl {
    pub fn new(root: PathBuf) -> Px4Sitl {
        Px4Sitl {
            root,
            model: "sihsim_quadx".into(),
            home: "-35.363261,149.165230,584".into(),
            fc_baud: DEFAULT_FC_BAUD,
        }
    }

    fn program(&self) -> PathBuf {
        self.root.join("bin/px4")
    }

    pub(super) fn available(&self) -> Result<(), AutopilotError> {
        for (what, path) in [
            ("PX4 SITL", self.program()),
            (
                "PX4 SITL's ROMFS (etc/init.d-posix/rcS)",
                self.root.join("etc/init.d-posix/rcS"),
            ),
        ] {
            if !path.is_file() {
                return Err(AutopilotError::Missing {
                    what: what.into(),
                    path,
                    how: HOW_TO_GET,
                });
            }
        }
        Ok(())
    }

    pub(super) fn start(&self, name: &str, dir: &Path) -> Result<Autopilot, AutopilotError> {
        let start_err = |source: anyhow::Error| AutopilotError::Start {
            name: name.to_string(),
            source,
        };
        let instance =
            INSTANCES.take(|n| udp_free(GCS_PORT_BASE + n) && udp_free(OFFBOARD_PORT_BASE + n))?;
        let work = dir.join(format!("{name}-sitl"));
        std::fs::create_dir_all(&work)
            .with_context(|| format!("cannot create {}", work.display()))
            .map_err(start_err)?;
        let cable = PtyCable::new(name).map_err(start_err)?;
        let bin =
            client_links(&self.program(), &self.root.join("bin"), &work).map_err(start_err)?;
        let path = match std::env::var_os("PATH") {
            Some(p) => {
                let mut dirs = vec![bin.clone()];
                dirs.extend(std::env::split_paths(&p));
                std::env::join_paths(dirs)
                    .context("PATH")
                    .map_err(start_err)?
            }
            None => bin.into_os_string(),
        };
        let home: Vec<&str> = self.home.split(',').collect();
        let mut command = Command::new(self.program());
        for (var, value) in ["PX4_HOME_LAT", "PX4_HOME_LON", "PX4_HOME_ALT"]
            .iter()
            .zip(&home)
        {
            command.env(var, value.trim());
        }
        command
            .current_dir(&work)
            .env("PATH", path)
            .env("PX4_SIM_MODEL", &self.model)
            .env("PX4_SIMULATOR", "sihsim")
            .env("PX4_MAVLINK_SERIAL", cable.path(0))
            .env("PX4_MAVLINK_BAUD", self.fc_baud.to_string())
            .arg("-d")
            .arg(self.root.join("etc"))
            .arg("-w")
            .arg(&work)
            .args(["-i", &instance.to_string()]);
        let log = dir.join(format!("{name}-sitl.log"));
        let process = Process::spawn_logged(name, command, &log).map_err(start_err)?;
        tracing::info!(name, instance, fc = cable.path(1), "PX4 SITL started");
        Ok(Autopilot {
            name: name.to_string(),
            // PX4 SITL sets MAV_SYS_ID to its instance + 1.
            sysid: u8::try_from(instance + 1).expect("instances stay below 10"),
            fc_port: cable.path(1).to_string(),
            truth: Some(TruthPort::Udp(SocketAddr::from((
                [127, 0, 0, 1],
                GCS_PORT_BASE + instance,
            )))),
            process: Some(process),
            cable: Some(cable),
            leftovers: vec![server_socket(instance)],
        })
    }
}

/// PX4's start-up script runs its modules' client commands (`px4-param`, `px4-mavlink`...),
/// each a link to `px4` named for its command, found on `PATH`. Links do not survive every
/// copy (they become small files holding the target's name), so the rig makes them afresh
/// in the working folder's `bin/`, one per `px4-*` name in the build's `bin/`, beside the
/// alias script; returns that folder.
fn client_links(program: &Path, build_bin: &Path, work: &Path) -> anyhow::Result<PathBuf> {
    let bin = work.join("bin");
    std::fs::create_dir_all(&bin).with_context(|| format!("cannot create {}", bin.display()))?;
    let entries = std::fs::read_dir(build_bin)
        .with_context(|| format!("cannot list {}", build_bin.display()))?;
    for entry in entries {
        let name = entry?.file_name();
        let Some(name) = name.to_str() else { continue };
        if !name.starts_with("px4-") {
            continue;
        }
        let target = if name.ends_with(".sh") {
            build_bin.join(name)
        } else {
            program.to_path_buf()
        };
        let link = bin.join(name);
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(&target, &link)
            .with_context(|| format!("cannot link {} to {}", link.display(), target.display()))?;
    }
    Ok(bin)
}
