//! What a session starts and with which settings: [`SessionOptions`] per run,
//! [`SessionDefaults`] from the rig file (or a checkout, for tests).

use std::path::{Path, PathBuf};
use std::time::Duration;

use super::Result;
use crate::mavlora::{MAVLORA_BRIDGE, MAVLORA_ROUTER};
use harness_radio::{GilbertElliott, LinkConfig, RadioSetup};

/// What sits between the flight controller and the radio.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// `mavlora-bridge` on the drone, `mavlora-router` on the ground.
    Bridge,
    /// Nothing: FC on the drone radio, GCS on the ground radio (see the module doc).
    Transparent,
}

/// PX4 stream profile the FC fixture boots with (`mavlora_fc.py --profile`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FcProfile {
    /// PX4, telemetry-radio default (`mavlora_fc.py`).
    Normal,
    /// PX4, USB default, closest to the paper's wired 11,440 B/s (`mavlora_fc.py`).
    Config,
    /// ArduPilot Copter on a MAVLink 1 telemetry port, every stream group at 4 Hz, that
    /// ignores stream requests (`ardupilot_fc.py --ignore-stream-requests`).
    ArduPilot,
}

impl FcProfile {
    pub fn as_str(self) -> &'static str {
        match self {
            FcProfile::Normal => "normal",
            FcProfile::Config => "config",
            FcProfile::ArduPilot => "ardupilot",
        }
    }

    /// The fixture program that plays it, in the fixtures folder.
    pub fn fixture(self) -> &'static str {
        match self {
            FcProfile::Normal | FcProfile::Config => "mavlora_fc.py",
            FcProfile::ArduPilot => "ardupilot_fc.py",
        }
    }

    /// The fixture's arguments for it (flying the paper's route).
    pub fn fixture_args(self) -> Vec<&'static str> {
        match self {
            FcProfile::Normal | FcProfile::Config => {
                vec!["--profile", self.as_str(), "--path", "route"]
            }
            FcProfile::ArduPilot => vec!["--ignore-stream-requests", "--path", "route"],
        }
    }
}

/// What the GCS fixture does, in order (see `fixtures/mavlora_gcs.py`).
#[derive(Debug, Clone, PartialEq)]
pub struct GcsPlan {
    /// Seconds of the telemetry phase.
    pub listen_s: f64,
    /// Seconds of it before the counting window opens.
    pub warmup_s: f64,
    /// Commands to send (0: none).
    pub commands: u32,
    pub command_interval_s: f64,
    pub command_retry_s: f64,
    pub command_tries: u32,
    /// Mission items to upload (0: none).
    pub items: u32,
    pub item_timeout_s: f64,
    pub upload_timeout_s: f64,
}

impl Default for GcsPlan {
    fn default() -> Self {
        GcsPlan {
            listen_s: 3.0,
            warmup_s: 0.0,
            commands: 0,
            command_interval_s: 0.5,
            command_retry_s: 1.5,
            command_tries: 5,
            items: 0,
            item_timeout_s: 1.5,
            upload_timeout_s: 60.0,
        }
    }
}

impl GcsPlan {
    /// Longest the plan can take, with a margin for start-up.
    pub fn budget(&self) -> Duration {
        let commands = f64::from(self.commands)
            * (self.command_interval_s + self.command_retry_s * f64::from(self.command_tries));
        let upload = if self.items > 0 {
            self.upload_timeout_s
        } else {
            0.0
        };
        Duration::from_secs_f64(self.listen_s + commands + upload + 10.0)
    }
}

/// Which program plays the ground station behind the router.
#[derive(Debug, Clone, PartialEq)]
pub enum Ground {
    /// `mavlora_gcs.py` (pymavlink) on [`SessionOptions::gcs`].
    Pymavlink,
    /// `mavsdk_gcs.py`: MAVSDK itself, uploading plans with its own timeouts and retries.
    Mavsdk(MavsdkPlan),
}

/// What `mavsdk_gcs.py` does: `uploads` plans of `items` waypoints, one after the other.
#[derive(Debug, Clone, PartialEq)]
pub struct MavsdkPlan {
    pub uploads: u32,
    pub items: u32,
    /// Seconds between one upload's end and the next.
    pub pause_s: f64,
    /// Seconds it stays after the last upload (a plan MAVSDK gave up on may still land).
    pub settle_s: f64,
}

impl MavsdkPlan {
    /// Longest the plan can take: MAVSDK gives up on an upload by itself (0.5 s × 5 per step,
    /// 2.5 s after its last item), so 30 s an upload is far beyond it; and start-up.
    pub fn budget(&self) -> Duration {
        let uploads = f64::from(self.uploads) * (30.0 + self.pause_s);
        Duration::from_secs_f64(uploads + self.settle_s + 20.0)
    }
}

/// Everything one session needs; the lead maps the rig file onto this.
#[derive(Debug, Clone)]
pub struct SessionOptions {
    /// Labels the radio thread and the logs.
    pub name: String,
    pub python: PathBuf,
    pub fixtures_dir: PathBuf,
    pub bridge_program: PathBuf,
    pub router_program: PathBuf,
    pub radio: RadioSetup,
    pub variant: Variant,
    /// `--profile` of the bridge.
    pub bridge_profile: PathBuf,
    /// `--compact` of the bridge.
    pub compact: bool,
    /// `--rate` of the bridge and the router (radio budget, B/s): by default what the
    /// simulated world gives the engines for this radio, 80 % of one direction's capacity.
    pub rate: u32,
    /// `--burst` of both (bytes the budget lets go at once): what the radio's serial buffer
    /// takes ([`burst_of`]).
    pub burst: u32,
    /// `--link-quality-period` of both ends (s); `None`: derived from the budget.
    pub link_quality_period: Option<f64>,
    pub fc_profile: FcProfile,
    /// The ground station: `mavlora_gcs.py` on [`Self::gcs`], or MAVSDK.
    pub ground: Ground,
    pub gcs: GcsPlan,
    /// Logs, summaries and the router's tlog go here.
    pub out_dir: PathBuf,
    /// Longest wait for the first telemetry at the GCS.
    pub ready_timeout: Duration,
    /// Sign the ground side too: the router's `--ground-key`, the GCS fixture's `--key`.
    pub ground_key: bool,
    /// The FC fixture reboots when this item of an upload reaches it (`--reboot-at-item`).
    pub fc_reboot_at_item: Option<u32>,
    /// `--fc-baud` of the bridge; `None`: its default.
    pub fc_baud: Option<u32>,
    /// A radio path already up to run over instead of a new emulator of [`Self::radio`]:
    /// the bench suite's (SiK on both sides, an attenuator stepping its path loss).
    pub radio_path: Option<RadioPath>,
}

/// A running radio emulator a session is handed ([`SessionOptions::radio_path`]).
#[derive(Clone)]
pub struct RadioPath(pub std::sync::Arc<crate::driver::radio_emulator::RadioEmulator>);

impl std::fmt::Debug for RadioPath {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "RadioPath(air {}, ground {})",
            self.0.air_path(),
            self.0.ground_path()
        )
    }
}

/// What comes from the rig file, shared by every real-time scenario.
#[derive(Debug, Clone)]
pub struct SessionDefaults {
    pub python: PathBuf,
    pub fixtures_dir: PathBuf,
    pub bridge_program: PathBuf,
    pub router_program: PathBuf,
    /// Folder holding `px4-normal.toml` and `px4-compact.toml`.
    pub profile_dir: PathBuf,
    /// SiK with loss, for the mission and command scenarios.
    pub lossy_radio: RadioSetup,
    /// SiK without loss, for bandwidth.
    pub clean_radio: RadioSetup,
    /// SiK with 10 % independent loss per packet, for commands.
    pub c2_radio: RadioSetup,
    /// Length of the opt-in real-time soak, seconds.
    pub soak_s: f64,
}

impl SessionDefaults {
    /// Defaults for a checkout at `repo`: `python3`, `fixtures/`,
    /// `firmware/mavlora/profiles/`, the MavLora programs next to the running
    /// executable (or one folder up, for test binaries in `deps/`), SiK 64k
    /// loss-free and with 10 % bursty loss each way (10 % of the time in 250 ms fades).
    pub fn for_repo(repo: &Path) -> Result<SessionDefaults> {
        Ok(SessionDefaults {
            python: PathBuf::from("python3"),
            fixtures_dir: repo.join("fixtures"),
            bridge_program: MAVLORA_BRIDGE.find()?,
            router_program: MAVLORA_ROUTER.find()?,
            profile_dir: repo.join("firmware/mavlora/profiles"),
            lossy_radio: sik_with_loss(0.10, 250.0)?,
            clean_radio: RadioSetup::builtin("sik-64k")?,
            c2_radio: sik_with_independent_loss(0.10)?,
            soak_s: 600.0,
        })
    }

    /// Options for a bridge session over `radio`, logging into `out_dir`.
    pub fn options(&self, name: &str, radio: &RadioSetup, out_dir: &Path) -> SessionOptions {
        SessionOptions {
            name: name.to_string(),
            python: self.python.clone(),
            fixtures_dir: self.fixtures_dir.clone(),
            bridge_program: self.bridge_program.clone(),
            router_program: self.router_program.clone(),
            radio: radio.clone(),
            variant: Variant::Bridge,
            bridge_profile: self.profile_dir.join("px4-compact.toml"),
            compact: true,
            rate: budget_of(radio),
            burst: burst_of(radio),
            link_quality_period: None,
            fc_profile: FcProfile::Normal,
            ground: Ground::Pymavlink,
            gcs: GcsPlan::default(),
            out_dir: out_dir.to_path_buf(),
            ready_timeout: Duration::from_secs(15),
            ground_key: false,
            fc_reboot_at_item: None,
            fc_baud: None,
            radio_path: None,
        }
    }
}

/// SiK 64k with Gilbert-Elliott fades `bad_share` (0..1) of the time, `burst_ms` long on
/// average, in both directions (seeds 1 down, 2 up).
pub fn sik_with_loss(bad_share: f64, burst_ms: f64) -> Result<RadioSetup> {
    let mut setup = RadioSetup::builtin("sik-64k")?;
    let ge = GilbertElliott::with_mean(bad_share, burst_ms)?;
    setup.downlink = LinkConfig {
        burst: Some(ge),
        seed: 1,
        ..LinkConfig::default()
    };
    setup.uplink = LinkConfig {
        burst: Some(ge),
        seed: 2,
        ..LinkConfig::default()
    };
    Ok(setup)
}

/// SiK 64k losing `loss` of the air packets each way, independently (seeds 3 down, 4 up).
pub fn sik_with_independent_loss(loss: f64) -> Result<RadioSetup> {
    let mut setup = RadioSetup::builtin("sik-64k")?;
    let independent = |seed| LinkConfig {
        packet_loss: loss,
        seed,
        ..LinkConfig::default()
    };
    setup.downlink = independent(3);
    setup.uplink = independent(4);
    setup.radio()?;
    Ok(setup)
}

/// The binaries' default `--burst`.
pub const DEFAULT_BURST: u32 = 600;

/// The engines' burst for `radio`: no more than its serial buffer takes at once (LoRa SF7's
/// is 256 B: with the default 600 the emulator dropped 160 B of ArduPilot's boot traffic, and
/// the router told the pilot the clean downlink was 24 % lost), but never below one largest
/// frame, which the engines must be able to send. The default for radios with room for it.
pub fn burst_of(radio: &RadioSetup) -> u32 {
    let largest = mavlora::wire::MAX_FRAME_LEN as u32;
    match radio.preset.resolve() {
        Ok(p) => (p.buffer_bytes as u32).clamp(largest, DEFAULT_BURST),
        Err(_) => DEFAULT_BURST,
    }
}

/// The engines' byte budget for `radio`, as the simulated world sets it: a burst such as an
/// autopilot's boot parameters then waits in the bridge's queue instead of overflowing the
/// radio's buffer. A preset that does not resolve is refused, with its error, by the session's
/// radio emulator.
fn budget_of(radio: &RadioSetup) -> u32 {
    harness_sim::scheduler_for(radio.preset.resolve().ok().as_ref()).rate_bytes_per_s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_burst_fits_the_radio_buffer_but_never_below_one_largest_frame() {
        let burst = |name: &str| burst_of(&RadioSetup::builtin(name).unwrap());
        // LoRa SF7 buffers 256 B: one largest signed frame (280 B) is the least the engines
        // can send; SiK (1850 B) and DMD (2048 B) keep the default.
        assert_eq!(burst("lora-sf7"), mavlora::wire::MAX_FRAME_LEN as u32);
        assert_eq!(burst("sik-64k"), DEFAULT_BURST);
        assert_eq!(burst("dmd-dl1"), DEFAULT_BURST);
    }
}
