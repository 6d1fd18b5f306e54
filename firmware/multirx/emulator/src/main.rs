//! `multirx-emu`: MultiRX on a host, over real serial ports.
//!
//! Runs the same `multirx-core` engine as the SAMD21 firmware. The rig starts
//! it on pty pairs in CI; on a bench it can sit on USB-serial adapters (with
//! SBUS inverters) in place of the board. Receiver power is reported as status
//! lines (`<micros> power <rx> on|off`) so whoever plays the receivers can
//! honour it.
//!
//! Exit codes: 0 after SIGINT/SIGTERM, 1 on a startup error (bad config, a
//! port that cannot be opened), 2 on bad command-line usage.

mod clock;
mod device;
mod ports;
mod tap;

use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Parser;
use hostio::status::StatusWriter;
use multirx_core::Config;
use multirx_core::boot::ResetCause;
use serde::Serialize;

use device::{Device, Status, StatusJson};
use ports::{Output, Source, open_sbus, spawn_reader};

/// MultiRX receiver multiplexer, emulated on a host over serial ports.
#[derive(Debug, Parser)]
#[command(version)]
struct Args {
    /// MultiRX configuration file (TOML), as compiled into the firmware.
    #[arg(long)]
    config: std::path::PathBuf,
    /// Serial port of each receiver, in receiver order (repeat once per receiver).
    #[arg(long = "rx", required = true)]
    receivers: Vec<String>,
    /// Serial port towards the flight controller (SBUS out).
    #[arg(long)]
    fc: String,
    /// Serial port for status lines (power, link, active receiver).
    #[arg(long)]
    status: Option<String>,
    /// Serial port of the independent fail-safe system (SBUS in).
    #[arg(long)]
    ifs: Option<String>,
    /// Write when each frame left for the flight controller (CLOCK_MONOTONIC
    /// seconds, a line per frame): a probe on the TX pin, for the rig.
    #[arg(long)]
    tx_log: Option<std::path::PathBuf>,
    /// Write the device's status as JSON lines to this file, created or truncated (`-`:
    /// stdout): a start line, a status line every --status-interval and a stop line; schema
    /// `c2-status/1`, every field in firmware/hostio/STATUS-JSON.md.
    #[arg(long)]
    status_json: Option<std::path::PathBuf>,
    /// Seconds between status lines in --status-json, 0.1..=86400.
    #[arg(long, default_value = "5", value_parser = seconds)]
    status_interval: Duration,
    /// The reset cause the boot line reports: `host` (a process start), or, when the rig
    /// restarts this program to play a chip reset in flight, that reset's cause (`software`:
    /// a panic or a debugger's reset, `watchdog`, ...; the boot line's names).
    #[arg(long, default_value = "host", value_parser = reset_cause)]
    reset_cause: ResetCause,
}

/// A reset cause by its boot-line name.
fn reset_cause(text: &str) -> Result<ResetCause, String> {
    ResetCause::from_name(text).ok_or_else(|| {
        let names: Vec<&str> = ResetCause::ALL.iter().map(|c| c.name()).collect();
        format!("{text} is not a reset cause; one of {}", names.join(", "))
    })
}

/// A period option: 0.1..=86400 seconds.
fn seconds(text: &str) -> Result<Duration, String> {
    match text.trim().parse::<f64>() {
        Ok(s) if (0.1..=86_400.0).contains(&s) => Ok(Duration::from_secs_f64(s)),
        _ => Err(format!("{text} is not a number of seconds in 0.1..=86400")),
    }
}

/// The start line's options: what the device runs and where.
#[derive(Serialize)]
struct StartOptions<'a> {
    config: &'a std::path::Path,
    mode: &'a str,
    receivers: u8,
    frame_period_ms: u64,
    /// As on the boot line: 16 hex digits.
    config_hash: String,
    build_id: String,
    rx: &'a [String],
    fc: &'a str,
    status: Option<&'a str>,
    ifs: Option<&'a str>,
    tx_log: Option<&'a std::path::Path>,
    status_interval_s: f64,
}

fn main() -> ExitCode {
    hostio::logging::init("info");
    let args = Args::parse();
    let (mut json, mut last) = (None, None);
    let result = run(args, &mut json, &mut last);
    if let Some(w) = &mut json {
        w.stop(if result.is_ok() { 0 } else { 1 }, &result, last.as_ref());
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("multirx-emu: error: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// Runs the device; the status file, once open, is left in `json` for the stop line, with the
/// last status in `last` if the device ran.
fn run(args: Args, json: &mut Option<StatusWriter>, last: &mut Option<Status>) -> Result<()> {
    let text = std::fs::read_to_string(&args.config)
        .with_context(|| format!("cannot read {}", args.config.display()))?;
    let config =
        Config::from_toml(&text).map_err(|e| anyhow::anyhow!("{}:{e}", args.config.display()))?;
    if args.receivers.len() != usize::from(config.receivers) {
        bail!(
            "{} configures {} receivers but {} --rx ports were given",
            args.config.display(),
            config.receivers,
            args.receivers.len()
        );
    }
    if let Some(path) = &args.status_json {
        let mut w = StatusWriter::create(path, "multirx-emu")?;
        let hash = config.identity_hash();
        w.start(
            env!("CARGO_PKG_VERSION"),
            &StartOptions {
                config: &args.config,
                mode: config.mode.as_str(),
                receivers: config.receivers,
                frame_period_ms: config.frame_period.as_millis(),
                config_hash: format!("{hash:016x}"),
                build_id: format!("{:016x}", device::emulated_build_id(hash)),
                rx: &args.receivers,
                fc: &args.fc,
                status: args.status.as_deref(),
                ifs: args.ifs.as_deref(),
                tx_log: args.tx_log.as_deref(),
                status_interval_s: args.status_interval.as_secs_f64(),
            },
        )?;
        *json = Some(w);
    }
    if args.ifs.is_some() && config.ifs_channels.is_empty() {
        tracing::warn!("--ifs given but the config names no [ifs] channels; IFS input ignored");
    }

    let read_timeout = Duration::from_millis(200);
    // Writes wait at most a couple of milliseconds: a full output drops frames.
    let write_timeout = Duration::from_millis(2);
    let (tx, rx) = mpsc::channel();
    for (i, path) in args.receivers.iter().enumerate() {
        let port = open_sbus(path, read_timeout)?;
        spawn_reader(
            Source::Receiver(i as u8),
            path.clone(),
            port,
            read_timeout,
            tx.clone(),
        )?;
    }
    if let Some(path) = &args.ifs {
        let port = open_sbus(path, read_timeout)?;
        spawn_reader(Source::Ifs, path.clone(), port, read_timeout, tx.clone())?;
    }
    drop(tx);
    let fc = Output::new(&args.fc, open_sbus(&args.fc, write_timeout)?, write_timeout);
    let status = match &args.status {
        Some(path) => Some(Output::new(
            path,
            open_sbus(path, write_timeout)?,
            write_timeout,
        )),
        None => None,
    };

    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed))
        .context("cannot install the SIGINT/SIGTERM handler")?;

    tracing::info!(
        mode = config.mode.as_str(),
        receivers = config.receivers,
        period_ms = config.frame_period.as_millis(),
        source = device::SOURCE_ID,
        "MultiRX emulated device running"
    );
    hostio::realtime::request("engine");
    let tap = args.tx_log.as_deref().map(tap::TxTap::create).transpose()?;
    let mut device = Device::new(config, fc, status, tap, args.reset_cause);
    let every = args.status_interval;
    let stats = device.run(
        rx,
        &stop,
        json.as_mut().map(|writer| StatusJson { writer, every }),
    );
    match hostio::status::fields(&stats.status) {
        Ok(fields) => tracing::info!("stopped {fields}"),
        Err(e) => tracing::error!(error = %e, "status not rendered"),
    }
    *last = Some(stats.status);
    if let Some(why) = stats.fc_gone {
        anyhow::bail!("flight-controller port gone for good: {why}");
    }
    Ok(())
}
