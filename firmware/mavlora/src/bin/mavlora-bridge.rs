//! `mavlora-bridge`: runs on the companion computer between the flight controller's serial
//! port and the radio's. See the crate README for command lines.
//!
//! Exit codes: 0 after SIGINT/SIGTERM, 1 on a configuration or setup error, 2 on bad usage.

use mavlora::Duration;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::Parser;
use serde::{Deserialize, Serialize};
use tracing::info;

use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::filter::Profile;
use mavlora::io::{
    Event, Program, RadioOptions, SerialEvent, SerialLink, Side, StatusReport, UsageError,
    frame_gap,
};
use mavlora::schedule::DEFAULT_RADIO_BACKLOG;

/// MavLora bridge: flight controller serial port <-> radio serial port.
#[derive(Parser, Deserialize, Default, Debug)]
#[command(version)]
struct Options {
    #[command(flatten)]
    #[serde(skip)]
    shared: RadioOptions,
    /// Flight controller serial device (or pty path).
    #[arg(long)]
    fc: Option<String>,
    /// Flight controller baud rate [default: 921600].
    #[arg(long)]
    fc_baud: Option<u32>,
    /// Profile file (stream rates and radio filter), e.g. firmware/mavlora/profiles/px4-normal.toml.
    #[arg(long)]
    profile: Option<PathBuf>,
    /// Replace periodic telemetry by compact frames (the router expands them).
    #[arg(long, num_args = 0, default_missing_value = "true")]
    compact: Option<bool>,
    /// With --compact: hold compact frames this many ms so they share one radio packet
    /// (LoRa under a duty-cycle rule), at most 60000 [default: the profile's
    /// `[compact] coalesce_ms`, else 0].
    #[arg(long)]
    coalesce_ms: Option<u64>,
    /// Vehicle system id, until the flight controller's heartbeat tells [default: 1].
    #[arg(long)]
    system_id: Option<u8>,
}

/// The flight controller's baud rate unless `--fc-baud` says.
const FC_BAUD: u32 = 921_600;

impl Program for Options {
    const NAME: &'static str = "mavlora-bridge";

    fn shared(&mut self) -> &mut RadioOptions {
        &mut self.shared
    }

    fn start_options(&self) -> serde_json::Value {
        serde_json::json!({
            "fc": self.fc,
            "fc_baud": self.fc_baud.unwrap_or(FC_BAUD),
            "radio_backlog_ms": self.shared.radio_backlog(Some(DEFAULT_RADIO_BACKLOG)).map_or(0, |d| d.as_millis()),
            "profile": self.profile,
            "compact": self.compact.unwrap_or(false),
            // What runs: the flag, else the profile's [compact] table (read again at start).
            "coalesce_ms": self.coalesce_ms.unwrap_or_else(|| {
                self.profile
                    .as_ref()
                    .filter(|_| self.compact.unwrap_or(false))
                    .and_then(|p| Profile::load(p).ok())
                    .and_then(|p| p.compact())
                    .map_or(0, |c| c.coalesce.as_millis())
            }),
        })
    }

    fn run(self, report: &mut StatusReport) -> Result<()> {
        run(self, report)
    }
}

fn main() -> ExitCode {
    mavlora::io::main::<Options>()
}

fn run(o: Options, report: &mut StatusReport) -> Result<()> {
    let fc_path = o.fc.context("no flight-controller port: --fc or `fc`")?;
    let setup = o.shared.setup(1, "bridge")?;
    let profile = match o.profile {
        Some(p) => Profile::load(&p)?,
        None => Profile::parse("", "(no profile: everything passes)")?,
    };
    let mut config = BridgeConfig::new(profile, setup.scheduler);
    let coalesce_ms = o.coalesce_ms;
    if coalesce_ms.is_some_and(|ms| ms > 60_000) {
        return Err(UsageError::option("coalesce_ms", "must be at most 60000 ms").into());
    }
    if o.compact.unwrap_or(false) {
        // The profile's [compact] table, `--coalesce-ms` over its `coalesce_ms`.
        let mut compact = config.profile.compact().unwrap_or_default();
        if let Some(ms) = coalesce_ms {
            compact.coalesce = Duration::from_millis(ms);
        }
        config.compact = Some(compact);
    } else if coalesce_ms.is_some() {
        return Err(
            UsageError::option("coalesce_ms", "needs compact telemetry (--compact)").into(),
        );
    }
    if let Some(id) = o.system_id {
        // 0 addresses every system and is nobody's; 255 is the ground stations' by
        // convention (QGroundControl, Mission Planner, MAVProxy).
        if id == 0 || id == 255 {
            return Err(UsageError::option(
                "system_id",
                format!("{id}: a vehicle's id is 1..=254 (0 is broadcast, 255 a ground station's)"),
            )
            .into());
        }
        config.system_id = id;
    }
    config.signing = setup.signing.config.clone();
    config.quality = setup.quality;
    config.radio_backlog = o.shared.radio_backlog(Some(DEFAULT_RADIO_BACKLOG));

    let fc_baud = o.fc_baud.unwrap_or(FC_BAUD);
    if fc_baud == 0 {
        return Err(UsageError::option(
            "fc_baud",
            "0: must be the flight controller port's baud rate",
        )
        .into());
    }
    let fc = setup.spawn("fc", &fc_path, fc_baud, frame_gap(fc_baud / 10))?;
    let (rate, burst) = (setup.rate, setup.burst);
    let station = setup.open_radio()?;
    let compact = config.compact.is_some();
    let bridge = Bridge::new(config, station.now())?;
    info!(
        rate,
        burst,
        compact,
        signing = station.signing_label(),
        "bridge running"
    );
    station.run(bridge, FcSide { fc }, report)
}

/// The bridge's side of the loop: the flight controller's port.
struct FcSide {
    fc: SerialLink,
}

/// What the bridge counts beyond the radio link (status lines; STATUS-JSON.md).
#[derive(Debug, Serialize)]
struct BridgeCounters {
    fc_rx: u64,
    fc_tx: u64,
    fc_dropped_bytes: u64,
    fc_write_failures: u64,
    fc_partials_dropped: u64,
    fc_opens: u64,
    fc_refused_opens: u64,
    filtered: u64,
    rate_limited: u64,
    replaced: u64,
    compact_batches: u64,
    compact_merged: u64,
    compact_samples_dropped: u64,
    config_acks: u64,
    fc_reboots: u64,
    missions: u64,
    command_acks_replayed: u64,
    command_copies_dropped: u64,
    command_acks_repeated: u64,
    commands_refused_after_restart: u64,
    commands_untagged: u64,
    fc_own_commands_dropped: u64,
    unlisted_dropped: u64,
    unlisted_dropped_bytes: u64,
    /// `unlisted_dropped_<id>`: the unlisted frames dropped, per message id (the first
    /// `UNLISTED_IDS_KEPT` ids seen).
    #[serde(flatten)]
    unlisted_dropped_by_id: std::collections::BTreeMap<String, u64>,
}

impl Side<Bridge> for FcSide {
    type Counters = BridgeCounters;
    type Gauges = ();

    fn handle(&mut self, bridge: &mut Bridge, now: mavlora::Instant, event: Event) {
        match event {
            Event::Serial("fc", SerialEvent::Bytes(b)) => bridge.handle_fc_bytes(now, &b),
            Event::Serial("fc", SerialEvent::Idle) => bridge.handle_fc_idle(now),
            Event::Serial("fc", SerialEvent::Closed) => bridge.fc_port_closed(),
            _ => {}
        }
    }

    fn transmit(&mut self, bridge: &mut Bridge, now: mavlora::Instant) {
        while let Some(f) = bridge.poll_fc_transmit(now) {
            self.fc.write(f.as_bytes());
        }
    }

    fn status(&self, bridge: &Bridge) -> (BridgeCounters, ()) {
        let (s, f) = (bridge.stats(), self.fc.counters());
        let counters = BridgeCounters {
            fc_rx: s.fc_reader.frames(),
            fc_tx: s.to_fc_frames,
            fc_dropped_bytes: f.dropped_bytes,
            fc_write_failures: f.write_failures,
            fc_partials_dropped: s.fc_reader.partials_dropped,
            fc_opens: f.opens,
            fc_refused_opens: f.refused_opens,
            filtered: s.filter.filtered,
            rate_limited: s.filter.rate_limited,
            replaced: s.scheduler.replaced,
            compact_batches: s.compact.batches,
            compact_merged: s.compact_merged,
            compact_samples_dropped: s.compact_samples_dropped,
            config_acks: s.config_acks,
            fc_reboots: s.fc_reboots,
            missions: s.mission.completed,
            command_acks_replayed: s.commands.replayed,
            command_copies_dropped: s.commands.dropped,
            command_acks_repeated: s.commands.repeated,
            commands_refused_after_restart: s.commands.refused_after_restart,
            commands_untagged: s.commands.untagged,
            fc_own_commands_dropped: s.fc_own_commands_dropped,
            unlisted_dropped: s.unlisted_dropped,
            unlisted_dropped_bytes: s.unlisted_dropped_bytes,
            unlisted_dropped_by_id: s
                .unlisted_dropped_by_id
                .iter()
                .map(|(id, n)| (format!("unlisted_dropped_{id}"), *n))
                .collect(),
        };
        (counters, ())
    }

    fn stop(&mut self, _: &Bridge, _: mavlora::Instant) -> Result<()> {
        self.fc.stop();
        Ok(())
    }
}
