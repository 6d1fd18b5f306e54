//! Bridge settings.

use crate::time::Duration;

use crate::command::Redundancy;
use crate::compact::CompactConfig;
use crate::filter::Profile;
use crate::mission::MissionConfig;
use crate::param::ParamPackConfig;
use crate::quality::LinkQualityConfig;
use crate::schedule::SchedulerConfig;
use crate::signing::SigningConfig;

/// Everything a [`Bridge`](super::Bridge) needs to start.
#[derive(Debug, Clone)]
pub struct BridgeConfig {
    /// Stream rates for the flight controller and radio filter rules.
    pub profile: Profile,
    /// The radio's byte budget.
    pub scheduler: SchedulerConfig,
    /// The most the radio may hold unsent ([`LinkScheduler::with_radio_backlog`]); `None`:
    /// no limit but the budget's burst.
    ///
    /// [`LinkScheduler::with_radio_backlog`]: crate::schedule::LinkScheduler::with_radio_backlog
    pub radio_backlog: Option<Duration>,
    /// Link-quality reports.
    pub quality: LinkQualityConfig,
    /// Compact telemetry instead of the standard periodic messages; `None` forwards them
    /// (filtered and limited by the profile).
    pub compact: Option<CompactConfig>,
    /// Mission relay timeouts.
    pub mission: MissionConfig,
    /// Sign radio frames and accept only signed, fresh ones; `None`: no signing.
    pub signing: Option<SigningConfig>,
    /// Our system id: the vehicle's (the companion computer is part of the vehicle).
    pub system_id: u8,
    /// Our component id (191: `MAV_COMP_ID_ONBOARD_COMPUTER`).
    pub component_id: u8,
    /// The flight controller's heartbeat missing this long, then back, counts as a reboot.
    pub fc_silence: Duration,
    /// Stream-rate requests not all acknowledged after this are sent again (at most
    /// `config_attempts` times in all).
    pub config_retry: Duration,
    /// See `config_retry`.
    pub config_attempts: u32,
    /// Ground-station heartbeats are regenerated towards the flight controller at this period…
    pub gcs_heartbeat_period: Duration,
    /// …until this long after the ground's next heartbeat over the radio was due (its period
    /// measured, see `bridge::gcs_heartbeat`): the radio's latency and jitter. A real link
    /// loss reaches the autopilot's GCS failsafe (ArduPilot `FS_GCS_TIMEOUT` 5 s, PX4
    /// `COM_DL_LOSS_T` 10 s) at most the router's period and this late.
    pub gcs_heartbeat_margin: Duration,
    /// Each ack of a command from the radio goes twice on a lossy link (see
    /// [`AckCache::with_redundancy`](crate::command::AckCache::with_redundancy)); the radio's
    /// timing (default: SiK 64k). `None`: once, and again only for a copy of the command.
    pub command_redundancy: Option<Redundancy>,
    /// The autopilot's `PARAM_VALUE`s go packed several to a frame (`MAVLORA_PARAM_VALUES`;
    /// the router must be of the same version); `None`: one `PARAM_VALUE` per frame, as
    /// before.
    pub param_pack: Option<ParamPackConfig>,
}

impl BridgeConfig {
    /// Defaults around a profile and a radio budget.
    pub fn new(profile: Profile, scheduler: SchedulerConfig) -> Self {
        Self {
            profile,
            scheduler,
            radio_backlog: None,
            quality: LinkQualityConfig::for_budget(scheduler.rate_bytes_per_s, false),
            compact: None,
            mission: MissionConfig::for_rate(scheduler.rate_bytes_per_s),
            signing: None,
            system_id: 1,
            component_id: 191,
            fc_silence: Duration::from_secs(3),
            config_retry: Duration::from_secs(2),
            config_attempts: 3,
            gcs_heartbeat_period: Duration::from_secs(1),
            gcs_heartbeat_margin: Duration::from_secs(2),
            command_redundancy: Some(Redundancy::SIK_64K),
            param_pack: Some(ParamPackConfig::for_rate(scheduler.rate_bytes_per_s)),
        }
    }
}
