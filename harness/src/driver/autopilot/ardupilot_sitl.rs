//! ArduPilot SITL (`arducopter`, `arduplane`...; built with `./waf configure --board sitl`):
//! started in its own working folder (it writes `eeprom.bin`, `logs/`, `terrain/` there),
//! parameters wiped (`-w`: a clean vehicle each start), SERIAL0 on TCP 5760 + 10·instance
//! (`tcp:0` listens without waiting for a client: the truth connection) and SERIAL1 on a pty
//! the bridge opens, MAVLink 2 or 1 (`SERIAL1_PROTOCOL`).

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::Context;

use super::{Autopilot, AutopilotError, DEFAULT_FC_BAUD, Instances, TruthPort, tcp_free};
use crate::driver::process::Process;
use crate::driver::pty::PtyCable;

/// What a user who has no SITL build is told.
pub const HOW_TO_GET: &str = "build ArduPilot SITL (git clone --recurse-submodules \
    https://github.com/ArduPilot/ardupilot; ./waf configure --board sitl --disable-scripting; \
    ./waf copter) and point [autopilots.NAME].program at build/sitl/bin/arducopter, as \
    ../shared/ardupilot-sitl/README.md says";

/// SERIAL0's TCP port of instance 0; each instance adds 10 to every port.
const TCP_BASE: u16 = 5760;

/// Instances the rig takes: above the ones a user's own SITL (0) and the fixtures' tests
/// (1..20) use.
static INSTANCES: Instances = Instances::new(20, 99);

/// `kind = "ardupilot-sitl"`.
#[derive(Debug, Clone, PartialEq)]
pub struct ArdupilotSitl {
    /// The SITL binary.
    pub program: PathBuf,
    /// Parameter defaults (`--defaults`): ArduPilot autotest's `copter.parm`.
    pub defaults: Option<PathBuf>,
    /// Built-in physics model (`--model`).
    pub model: String,
    /// `lat,lon,alt_m,heading_deg` (`--home`).
    pub home: String,
    /// Simulation speed (`--speedup`): 1 is real time, what a link test needs.
    pub speedup: f64,
    /// MAVLink version on the telemetry port: 2, or 1 (`SERIAL1_PROTOCOL=1`).
    pub fc_mavlink: u8,
    pub fc_baud: u32,
}

impl ArdupilotSitl {
    /// ArduPilot Copter with autotest's defaults at Canberra's model-flying field (where
    /// ArduPilot's autotest flies).
    pub fn new(program: PathBuf) -> ArdupilotSitl {
        ArdupilotSitl {
            program,
            defaults: None,
            model: "quad".into(),
            home: "-35.363261,149.165230,584,353".into(),
            speedup: 1.0,
            fc_mavlink: 2,
            fc_baud: DEFAULT_FC_BAUD,
        }
    }

    pub(super) fn available(&self) -> Result<(), AutopilotError> {
        if !self.program.is_file() {
            return Err(AutopilotError::Missing {
                what: "ArduPilot SITL".into(),
                path: self.program.clone(),
                how: HOW_TO_GET,
            });
        }
        if let Some(d) = &self.defaults
            && !d.is_file()
        {
            return Err(AutopilotError::Missing {
                what: "ArduPilot SITL's defaults file".into(),
                path: d.clone(),
                how: "copy Tools/autotest/default_params/copter.parm from the ArduPilot source \
                      tree, or remove [autopilots.NAME].defaults",
            });
        }
        Ok(())
    }

    pub(super) fn start(&self, name: &str, dir: &Path) -> Result<Autopilot, AutopilotError> {
        let start_err = |source: anyhow::Error| AutopilotError::Start {
            name: name.to_string(),
            source,
        };
        let instance = INSTANCES.take(|n| tcp_free(TCP_BASE + 10 * n))?;
        let work = dir.join(format!("{name}-sitl"));
        std::fs::create_dir_all(&work)
            .with_context(|| format!("cannot create {}", work.display()))
            .map_err(start_err)?;
        let cable = PtyCable::new(name).map_err(start_err)?;
        // What the rig sets beside the defaults: the telemetry port's MAVLink version.
        let rig_parm = work.join("rig.parm");
        std::fs::write(
            &rig_parm,
            format!(
                "# written by the rig\nSERIAL1_PROTOCOL {}\nSERIAL1_BAUD {}\n",
                self.fc_mavlink,
                self.fc_baud / 1000
            ),
        )
        .with_context(|| format!("cannot write {}", rig_parm.display()))
        .map_err(start_err)?;
        let defaults = match &self.defaults {
            Some(d) => format!("{},{}", d.display(), rig_parm.display()),
            None => rig_parm.display().to_string(),
        };
        let mut command = Command::new(&self.program);
        command
            .current_dir(&work)
            .args(["-w", "--model", &self.model])
            .args(["--speedup", &self.speedup.to_string()])
            .args(["--defaults", &defaults])
            .args(["--home", &self.home])
            .args(["-I", &instance.to_string()])
            .args(["--serial0", "tcp:0"])
            .args([
                "--serial1",
                &format!("uart:{}:{}", cable.path(0), self.fc_baud),
            ]);
        let log = dir.join(format!("{name}-sitl.log"));
        let process = Process::spawn_logged(name, command, &log).map_err(start_err)?;
        tracing::info!(name, instance, fc = cable.path(1), "ArduPilot SITL started");
        Ok(Autopilot {
            name: name.to_string(),
            // SYSID_THISMAV's default; -I does not change it.
            sysid: 1,
            fc_port: cable.path(1).to_string(),
            truth: Some(TruthPort::Tcp(SocketAddr::from((
                [127, 0, 0, 1],
                TCP_BASE + 10 * instance,
            )))),
            process: Some(process),
            cable: Some(cable),
            leftovers: Vec::new(),
        })
    }
}
