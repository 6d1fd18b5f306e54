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
use multirx_core::Config;

use device::Device;
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
}

fn main() -> ExitCode {
    hostio::logging::init("info");
    let args = Args::parse();
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("multirx-emu: error: {e:#}");
            ExitCode::from(1)
        }
    }
}

fn run(args: Args) -> Result<()> {
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
        "MultiRX emulated device running"
    );
    hostio::realtime::request("engine");
    let tap = args.tx_log.as_deref().map(tap::TxTap::create).transpose()?;
    let mut device = Device::new(config, fc, status, tap);
    let stats = device.run(rx, &stop);
    tracing::info!(
        frames_out = stats.frames_out,
        frames_dropped = stats.frames_dropped,
        max_gap_ms = stats.max_gap.as_secs_f64() * 1000.0,
        host_held_ms = stats.held.as_secs_f64() * 1000.0,
        status_lines = stats.status_lines,
        "stopped"
    );
    if let Some(why) = stats.fc_gone {
        anyhow::bail!("flight-controller port gone for good: {why}");
    }
    Ok(())
}
