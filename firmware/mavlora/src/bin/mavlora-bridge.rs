//! `mavlora-bridge`: runs on the companion computer between the flight controller's serial
//! port and the radio's. See the crate README for command lines.
//!
//! Exit codes: 0 after SIGINT/SIGTERM, 1 on a configuration or setup error, 2 on bad usage.

use mavlora::Duration;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context, Result};
use clap::Parser;
use serde::Deserialize;
use tracing::info;

use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::compact::CompactConfig;
use mavlora::filter::Profile;
use mavlora::io::{
    Clock, Event, INBOX_BYTES, Inbox, PopError, RadioOptions, SerialEvent, SerialLink, UsageError,
    frame_gap, on_signal,
};

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
    /// (LoRa under a duty-cycle rule: 1500 fits EU 433 MHz's 10 % at SF7/125 kHz), at most
    /// 60000 [default: 0].
    #[arg(long)]
    coalesce_ms: Option<u64>,
    /// Vehicle system id, until the flight controller's heartbeat tells [default: 1].
    #[arg(long)]
    system_id: Option<u8>,
}

fn main() -> ExitCode {
    mavlora::io::main(|o: &mut Options| &mut o.shared, run)
}

fn run(o: Options) -> Result<()> {
    let fc_path = o.fc.context("no flight-controller port: --fc or `fc`")?;
    let radio_path = o.shared.radio_port()?;
    let profile = match o.profile {
        Some(p) => Profile::load(&p)?,
        None => Profile::parse("", "(no profile: everything passes)")?,
    };
    let (rate, burst) = (o.shared.rate(), o.shared.burst());
    let mut config = BridgeConfig::new(profile, o.shared.scheduler()?);
    let coalesce_ms = o.coalesce_ms;
    if coalesce_ms.is_some_and(|ms| ms > 60_000) {
        return Err(UsageError::option("coalesce_ms", "must be at most 60000 ms").into());
    }
    if o.compact.unwrap_or(false) {
        config.compact = Some(CompactConfig {
            coalesce: Duration::from_millis(coalesce_ms.unwrap_or(0)),
            ..CompactConfig::default()
        });
    } else if coalesce_ms.is_some() {
        return Err(
            UsageError::option("coalesce_ms", "needs compact telemetry (--compact)").into(),
        );
    }
    if let Some(id) = o.system_id {
        config.system_id = id;
    }
    let mut signing = o.shared.signing(1, "bridge")?;
    config.signing = signing.config.clone();
    let signing_label = signing.label();
    config.quality = o.shared.link_quality(config.signing.is_some());
    let status_every = o.shared.status_every();

    let inbox = Inbox::new(INBOX_BYTES);
    on_signal(inbox.clone())?;
    let stop = Arc::new(AtomicBool::new(false));
    let fc_baud = o.fc_baud.unwrap_or(921_600);
    let fc_gap = frame_gap(fc_baud / 10);
    let mut fc = SerialLink::spawn("fc", &fc_path, fc_baud, fc_gap, inbox.clone(), stop.clone())?;
    let radio_baud = o.shared.radio_baud();
    let radio_gap = frame_gap(rate.min(radio_baud / 10));
    let mut radio = SerialLink::spawn(
        "radio",
        &radio_path,
        radio_baud,
        radio_gap,
        inbox.clone(),
        stop.clone(),
    )?;
    let clock = Clock::start();
    let compact = config.compact.is_some();
    let mut bridge = Bridge::new(config, clock.now())?;
    info!(
        rate,
        burst,
        compact,
        signing = signing_label,
        "bridge running"
    );
    let mut next_status = clock.now() + status_every;
    loop {
        let now = clock.now();
        let deadline = bridge
            .poll_timeout()
            .unwrap_or(now + Duration::from_secs(1))
            .min(next_status);
        match inbox.recv_timeout(clock.until(deadline)) {
            Ok(Event::Serial("fc", SerialEvent::Bytes(b))) => {
                bridge.handle_fc_bytes(clock.now(), &b);
            }
            Ok(Event::Serial("fc", SerialEvent::Idle)) => bridge.handle_fc_idle(clock.now()),
            Ok(Event::Serial("fc", SerialEvent::Closed)) => bridge.fc_port_closed(),
            Ok(Event::Serial(_, SerialEvent::Closed)) => bridge.radio_port_closed(),
            Ok(Event::Serial(_, SerialEvent::Bytes(b))) => {
                bridge.handle_radio_bytes(clock.now(), &b);
            }
            Ok(Event::Serial(_, SerialEvent::Idle)) => bridge.handle_radio_idle(clock.now()),
            Ok(Event::Serial(..) | Event::Udp(..) | Event::Tcp(..)) | Err(PopError::Timeout) => {}
            Ok(Event::Stop) => {
                info!("signal received, shutting down");
                break;
            }
            Err(PopError::Closed) => break,
        }
        let now = clock.now();
        bridge.handle_timeout(now);
        while let Some(f) = bridge.poll_fc_transmit(now) {
            fc.write(f.as_bytes());
        }
        // Only into an open port: a frame leaves the engine numbered and signed, and one
        // dropped at a closed port would read as radio loss at the far end.
        while radio.is_open()
            && let Some(f) = bridge.poll_radio_transmit(now, usize::MAX)
        {
            radio.write(f.as_bytes());
        }
        if let Some(file) = &mut signing.state_file {
            file.tick(now, || bridge.signing_state(now));
        }
        if now >= next_status {
            status(signing_label, &bridge, &fc, &radio, &inbox);
            next_status = now + status_every;
        }
    }
    stop.store(true, Ordering::Relaxed);
    if let Some(file) = &signing.state_file
        && let Some(state) = bridge.signing_state(clock.now())
    {
        file.save(&state)?;
    }
    fc.stop();
    radio.stop();
    status(signing_label, &bridge, &fc, &radio, &inbox);
    Ok(())
}

fn status(signing: &str, bridge: &Bridge, fc: &SerialLink, radio: &SerialLink, inbox: &Inbox) {
    let s = bridge.stats();
    let peer_loss = bridge.quality().peer().and_then(|p| p.loss_ratio);
    let (f, r, inbox) = (fc.counters(), radio.counters(), inbox.stats());
    info!(
        fc_rx = s.fc_reader.frames(),
        fc_tx = s.to_fc_frames,
        fc_dropped_bytes = f.dropped_bytes,
        fc_write_failures = f.write_failures,
        fc_partials_dropped = s.fc_reader.partials_dropped,
        fc_opens = f.opens,
        fc_refused_opens = f.refused_opens,
        radio_rx = s.radio_reader.frames(),
        radio_lost = s.radio_reader.lost,
        radio_bad_crc = s.radio_reader.bad_crc,
        radio_tx = s.scheduler.sent_frames,
        radio_tx_bytes = s.scheduler.sent_bytes,
        radio_offered_bytes = r.offered_bytes,
        radio_written_bytes = r.written_bytes,
        radio_dropped_bytes = r.dropped_bytes,
        radio_queued_bytes = r.queued_bytes,
        radio_write_failures = r.write_failures,
        radio_partials_dropped = s.radio_reader.partials_dropped,
        radio_opens = r.opens,
        radio_refused_opens = r.refused_opens,
        filtered = s.filter.filtered,
        rate_limited = s.filter.rate_limited,
        replaced = s.scheduler.replaced,
        compact_batches = s.compact.batches,
        config_acks = s.config_acks,
        fc_reboots = s.fc_reboots,
        missions = s.mission.completed,
        command_acks_replayed = s.commands.replayed,
        command_copies_dropped = s.commands.dropped,
        command_acks_repeated = s.commands.repeated,
        rejected_unsigned = s.signing.unsigned,
        rejected_bad_signature = s.signing.bad_signature,
        rejected_replayed = s.signing.replayed,
        rejected_stale = s.signing.stale,
        radio_tx_unsigned = s.signing.sent_unsigned,
        signing = %signing,
        inbox_dropped = inbox.dropped_items,
        inbox_peak_bytes = inbox.peak_bytes,
        peer_loss = ?peer_loss,
        "status"
    );
}
