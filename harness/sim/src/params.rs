//! A whole parameter list downloaded through MavLora as QGroundControl downloads it, in the
//! simulated world: the ArduPilot-like autopilot holding ArduCopter 4.6.3's 1,396 parameters
//! (served at its SITL's 270 a second, MAVLink 1) or the PX4-like one holding PX4 1.16's 904
//! (150 a second, integers byte-wise), flying the paper's route with its shipped compact
//! profile, through the real bridge and router, signed, over the rig file's radios. The
//! ground (`GcsMock`, as `fixtures/sitl_gcs.py`) asks for the list 20 s after boot, reads
//! the missing values by index once the list has been quiet for 1 s, and sends a `PARAM_SET`
//! 2 s into the list, as the rig's `sitl` `params` scenario does with the real autopilots.
//!
//! Measured: the time from the request to the last missing value at the ground (the rig's
//! `params_s`), the reads by index it took, the set's echo time, whether every value at the
//! ground is byte for byte the autopilot's, and the position at the ground while the list was
//! in flight (rate, longest wait for a newer one).

use harness_radio::Direction;
use mavlora::bridge::BridgeConfig;
use mavlora::dialect::MavParamType;
use mavlora::filter::Profile;
use mavlora::param::ReadGateStats;
use mavlora::quality::LinkQualityConfig;
use mavlora::router::RouterConfig;
use mavlora::wire::ids;
use mavlora::{Duration, Instant};

use crate::autopilot::{
    ARDUPILOT_PARAM_RATE, ArduPilotConfig, ArduPilotFc, Autopilot, Flight, PX4_NORMAL,
    PX4_PARAM_RATE, ParamTable, Px4Fc, Route,
};
use crate::freshness::{FreshnessRadio, longest_wait_for_news, signing};
use crate::scheduler_for;
use crate::world::World;

/// Which autopilot's list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamsAutopilot {
    /// ArduCopter 4.6.3: 1,396 parameters, 270 a second, MAVLink 1, sets echoed with index
    /// 65535; `profiles/ardupilot-compact.toml`.
    ArduPilot,
    /// PX4 1.16: 904 parameters, 150 a second, integers byte-wise, sets echoed with their
    /// index; `profiles/px4-compact.toml`.
    Px4,
}

impl ParamsAutopilot {
    /// Both.
    pub const ALL: [ParamsAutopilot; 2] = [ParamsAutopilot::ArduPilot, ParamsAutopilot::Px4];

    /// Its name in the tables.
    pub fn name(self) -> &'static str {
        match self {
            ParamsAutopilot::ArduPilot => "ardupilot",
            ParamsAutopilot::Px4 => "px4",
        }
    }

    /// Its list.
    pub fn table(self) -> ParamTable {
        match self {
            ParamsAutopilot::ArduPilot => ParamTable::arducopter(),
            ParamsAutopilot::Px4 => ParamTable::px4(),
        }
    }

    /// The parameter the rig's scenario sets, its new value's payload bytes and its type:
    /// the return altitude (ArduPilot's `RTL_ALT`, an INT32 in cm it sends as a float;
    /// PX4's `RTL_RETURN_ALT`, a REAL32 in m).
    pub fn set(self) -> (&'static str, [u8; 4], MavParamType) {
        match self {
            ParamsAutopilot::ArduPilot => (
                "RTL_ALT",
                2500.0f32.to_le_bytes(),
                MavParamType::MAV_PARAM_TYPE_INT32,
            ),
            ParamsAutopilot::Px4 => (
                "RTL_RETURN_ALT",
                45.0f32.to_le_bytes(),
                MavParamType::MAV_PARAM_TYPE_REAL32,
            ),
        }
    }

    fn profile_text(self) -> &'static str {
        match self {
            ParamsAutopilot::ArduPilot => crate::profiles::ARDUPILOT_COMPACT_TOML,
            ParamsAutopilot::Px4 => crate::profiles::PX4_COMPACT_TOML,
        }
    }
}

/// One download.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamsRun {
    /// Whose list.
    pub autopilot: ParamsAutopilot,
    /// Over which radio.
    pub radio: FreshnessRadio,
    /// Seed of the radio and the autopilot.
    pub seed: u64,
    /// The bridge packs the list (`MAVLORA_PARAM_VALUES`); `false`: one `PARAM_VALUE` per
    /// frame, the bridge before packing.
    pub packed: bool,
    /// When the ground asks for the list, s after boot.
    pub list_at_s: f64,
    /// The `PARAM_SET` this long into the list (`None`: none).
    pub set_after_s: Option<f64>,
    /// The ground gives up this long after asking, s.
    pub timeout_s: f64,
}

/// What one download measured.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamsFigures {
    /// Parameters the autopilot holds.
    pub count: usize,
    /// From the request to the last missing value at the ground, s (`None`: incomplete).
    pub seconds: Option<f64>,
    /// Values still missing at the end.
    pub missing: usize,
    /// `PARAM_REQUEST_READ`s the ground sent.
    pub rereads: u64,
    /// The set's echo, s after its first send (`None`: none came, or no set).
    pub echo_s: Option<f64>,
    /// Whether every value at the ground is byte for byte the autopilot's (the set
    /// parameter's: its value before or after the set).
    pub exact: bool,
    /// Positions at the ground per second while the list was in flight.
    pub position_hz: f64,
    /// Longest wait at the ground for a newer position while the list was in flight, s.
    pub position_gap_s: f64,
    /// Bytes of parameter frames the bridge handed the radio (packed or not).
    pub param_bytes: u64,
    /// Bytes the drone's radio dropped (its buffer full).
    pub radio_dropped_bytes: u64,
    /// Packed frames the bridge made.
    pub packed_frames: u64,
    /// What the router did with the ground's reads by index (forwarded, held because the
    /// list in flight brings the value, because the same read was in flight, because the
    /// value had just been given to the ground).
    pub reads: ReadGateStats,
}

impl ParamsRun {
    /// `autopilot`'s list over `radio`, packed, seed 1, asked for 20 s after boot, a set 2 s
    /// into it, given up after 600 s.
    pub fn new(autopilot: ParamsAutopilot, radio: FreshnessRadio) -> Self {
        Self {
            autopilot,
            radio,
            seed: 1,
            packed: true,
            list_at_s: 20.0,
            set_after_s: Some(2.0),
            timeout_s: 600.0,
        }
    }

    /// Flies it and measures.
    pub fn measure(&self) -> ParamsFigures {
        let profile = Profile::parse(self.autopilot.profile_text(), "params").expect("profile");
        let budget = scheduler_for(Some(&self.radio.preset()));
        let mut b = BridgeConfig::new(profile.clone(), budget);
        b.compact = Some(profile.compact().unwrap_or_default());
        b.signing = Some(signing(1));
        b.quality = LinkQualityConfig::for_budget(budget.rate_bytes_per_s, true);
        if !self.packed {
            b.param_pack = None;
        }
        let mut r = RouterConfig::new(budget);
        r.signing = Some(signing(2));
        r.quality = LinkQualityConfig::for_budget(budget.rate_bytes_per_s, true);
        let setup = self.radio.setup(self.seed);
        let flight = Flight::Route(Route::PAPER);
        let table = self.autopilot.table();
        match self.autopilot {
            ParamsAutopilot::ArduPilot => {
                let fc = ArduPilotFc::new(ArduPilotConfig::default(), Instant::ZERO, self.seed)
                    .with_flight(flight)
                    .with_params(table.clone(), ARDUPILOT_PARAM_RATE);
                let w = World::new(fc, Some((b, r)), Some(&setup)).expect("world");
                self.fly(w, &table, |fc| fc.params().clone())
            }
            ParamsAutopilot::Px4 => {
                let fc = Px4Fc::new(PX4_NORMAL, Instant::ZERO, self.seed)
                    .with_flight(flight)
                    .with_params(table.clone(), PX4_PARAM_RATE);
                let w = World::new(fc, Some((b, r)), Some(&setup)).expect("world");
                self.fly(w, &table, |fc| fc.params().clone())
            }
        }
    }

    fn fly<A: Autopilot>(
        &self,
        mut w: World<A>,
        before: &ParamTable,
        params: impl Fn(&A) -> ParamTable,
    ) -> ParamsFigures {
        let start = crate::secs(self.list_at_s);
        w.run_until(start);
        w.gcs.download_params(w.now);
        let sent_before = w.sent(Direction::Downlink).clone();
        let dropped_before = w
            .link_stats(Direction::Downlink)
            .map_or(0, |s| s.bytes_dropped);
        if let Some(after) = self.set_after_s {
            w.run_until(start + Duration::from_secs_f64(after));
            let (name, value, t) = self.autopilot.set();
            w.gcs.set_param(w.now, name, value, t);
        }
        let until = start + Duration::from_secs_f64(self.timeout_s);
        w.run_until_or(until, |w| {
            w.gcs.param_download().is_some_and(|d| d.done.is_some())
        });
        let d = w.gcs.param_download().expect("started").clone();
        let end = d.done.unwrap_or(w.now);
        let after = params(&w.fc);
        let (set_name, _, _) = self.autopilot.set();
        let exact = (0..after.len()).all(|i| {
            let got = d.values.get(&(i as u16));
            let now = after.payload(i, i as u16);
            let then = before.payload(i, i as u16);
            got.is_some_and(|g| {
                *g == now || (after.get(i).unwrap().name_str() == set_name && *g == then)
            })
        });
        let sent = w.sent(Direction::Downlink).since(&sent_before);
        let packed_frames = w.bridge().map_or(0, |b| b.stats().params.frames);
        let reads = w
            .router()
            .map(|r| r.stats().param_reads)
            .unwrap_or_default();
        // positions that arrived while the list was in flight, and the waits for a newer one
        let positions: Vec<(Instant, u32)> = w
            .gcs
            .positions
            .iter()
            .copied()
            .filter(|(t, _)| *t >= start && *t <= end)
            .collect();
        let span = end.saturating_duration_since(start).as_secs_f64().max(1e-9);
        let gap = longest_wait_for_news(&positions, start, end);
        ParamsFigures {
            count: after.len(),
            seconds: d.seconds(),
            missing: d.missing(),
            rereads: d.rereads,
            echo_s: w.gcs.param_sets().first().and_then(|s| s.echo_s()),
            exact,
            position_hz: positions.len() as f64 / span,
            position_gap_s: gap.as_secs_f64(),
            param_bytes: sent.bytes_of(&[ids::PARAM_VALUE, ids::MAVLORA_PARAM_VALUES]),
            radio_dropped_bytes: w
                .link_stats(Direction::Downlink)
                .map_or(0, |s| s.bytes_dropped)
                - dropped_before,
            packed_frames,
            reads,
        }
    }
}
