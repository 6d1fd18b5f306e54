//! `mavlora-router`: runs on the ground between the radio's serial port and ground-station
//! software on UDP and TCP. See the crate README for command lines.
//!
//! Exit codes: 0 after SIGINT/SIGTERM, 1 on a configuration or setup error, 2 on bad usage.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Parser;
use serde::Deserialize;
use tracing::{info, warn};

use mavlora::io::{
    Clock, Event, SerialEvent, SerialLink, TcpEndpoint, Tlog, UdpEndpoint, load_config, on_signal,
    run_main, signing_from_key_file,
};
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::SchedulerConfig;

/// MavLora router: radio serial port <-> ground stations on UDP and TCP.
#[derive(Parser, Debug)]
#[command(version)]
struct Args {
    /// TOML file with any of the options below (flags win).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Radio serial device (or pty path).
    #[arg(long)]
    radio: Option<String>,
    /// Radio baud rate [default: 57600].
    #[arg(long)]
    radio_baud: Option<u32>,
    /// Where to send until a ground station talks to us [default: 127.0.0.1:14550].
    #[arg(long)]
    udp: Option<SocketAddr>,
    /// Local UDP address [default: 0.0.0.0:14555].
    #[arg(long)]
    udp_bind: Option<SocketAddr>,
    /// Also listen for ground stations on TCP here, e.g. 0.0.0.0:5760 (QGroundControl "TCP",
    /// `mavproxy.py --master=tcp:HOST:5760`); every client gets every frame.
    #[arg(long)]
    tcp_listen: Option<SocketAddr>,
    /// Write a MAVProxy-format telemetry log here.
    #[arg(long)]
    tlog: Option<PathBuf>,
    /// Ground-to-air radio budget in bytes per second [default: 683].
    #[arg(long)]
    rate: Option<u32>,
    /// Radio burst in bytes [default: 600].
    #[arg(long)]
    burst: Option<u32>,
    /// Seconds between ground heartbeats sent over the radio [default: 5].
    #[arg(long)]
    gcs_heartbeat_period: Option<f64>,
    /// Seconds between LINK_QUALITY reports [default: 5].
    #[arg(long)]
    link_quality_period: Option<f64>,
    /// Seconds between status lines [default: 5].
    #[arg(long)]
    status_interval: Option<f64>,
    /// MAVLink 2 signing key file (64 hex characters or 32 bytes) for the radio link: our
    /// radio frames are signed, unsigned or replayed ones from the radio are dropped.
    #[arg(long)]
    key: Option<PathBuf>,
}

#[derive(Deserialize, Default, Debug)]
#[serde(deny_unknown_fields)]
struct FileConfig {
    radio: Option<String>,
    radio_baud: Option<u32>,
    udp: Option<SocketAddr>,
    udp_bind: Option<SocketAddr>,
    tcp_listen: Option<SocketAddr>,
    tlog: Option<PathBuf>,
    rate: Option<u32>,
    burst: Option<u32>,
    gcs_heartbeat_period: Option<f64>,
    link_quality_period: Option<f64>,
    status_interval: Option<f64>,
    key: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    run_main(|| run(args))
}

fn run(args: Args) -> Result<()> {
    let file: FileConfig = load_config(args.config.as_deref())?;
    let radio_path = args
        .radio
        .or(file.radio)
        .context("no radio port: --radio or `radio`")?;
    let rate = args.rate.or(file.rate).unwrap_or(683);
    let burst = args.burst.or(file.burst).unwrap_or(600);
    let mut config = RouterConfig::new(SchedulerConfig::for_radio(rate, burst));
    if let Some(p) = args.gcs_heartbeat_period.or(file.gcs_heartbeat_period) {
        config.gcs_heartbeat_period = Duration::from_secs_f64(p);
    }
    if let Some(p) = args.link_quality_period.or(file.link_quality_period) {
        config.quality.period = Duration::from_secs_f64(p);
    }
    if let Some(path) = args.key.or(file.key) {
        config.signing = Some(signing_from_key_file(&path, 2)?);
    }
    let status_every =
        Duration::from_secs_f64(args.status_interval.or(file.status_interval).unwrap_or(5.0));
    let mut tlog = match args.tlog.or(file.tlog) {
        Some(p) => Some(Tlog::create(&p).with_context(|| format!("creating {}", p.display()))?),
        None => None,
    };

    let (tx, rx) = mpsc::channel();
    on_signal(tx.clone())?;
    let stop = Arc::new(AtomicBool::new(false));
    let peer = args
        .udp
        .or(file.udp)
        .unwrap_or(([127, 0, 0, 1], 14550).into());
    let bind = args
        .udp_bind
        .or(file.udp_bind)
        .unwrap_or(([0, 0, 0, 0], 14555).into());
    let mut udp = UdpEndpoint::spawn(bind, peer, tx.clone(), stop.clone())?;
    let tcp = match args.tcp_listen.or(file.tcp_listen) {
        Some(addr) => Some(TcpEndpoint::spawn(addr, tx.clone(), stop.clone())?),
        None => None,
    };
    let radio_baud = args.radio_baud.or(file.radio_baud).unwrap_or(57_600);
    let mut radio = SerialLink::spawn("radio", radio_path, radio_baud, tx, stop.clone());
    let clock = Clock::start();
    let mut router = Router::new(config, clock.now())?;
    info!(rate, burst, "router running");
    let mut next_status = clock.now() + status_every;
    let record = |tlog: &mut Option<Tlog>, bytes: &[u8]| {
        if let Some(t) = tlog
            && let Err(e) = t.record(bytes)
        {
            warn!(error = %e, "tlog write failed, logging stopped");
            *tlog = None;
        }
    };
    loop {
        let now = clock.now();
        let deadline = router
            .poll_timeout(now)
            .unwrap_or(now + Duration::from_secs(1))
            .min(next_status);
        match rx.recv_timeout(clock.until(deadline)) {
            Ok(Event::Serial(_, SerialEvent::Bytes(b))) => {
                router.handle_radio_bytes(&b, clock.now());
            }
            Ok(Event::Serial(_, SerialEvent::Closed)) => router.radio_port_closed(),
            Ok(Event::Udp(b, from)) => {
                udp.learn(from);
                record(&mut tlog, &b);
                router.handle_gcs_bytes(&b, clock.now());
            }
            Ok(Event::Tcp(b, _)) => {
                record(&mut tlog, &b);
                router.handle_gcs_bytes(&b, clock.now());
            }
            Ok(Event::Serial(_, SerialEvent::Opened)) | Err(RecvTimeoutError::Timeout) => {}
            Ok(Event::Stop) => {
                info!("signal received, shutting down");
                break;
            }
            Err(RecvTimeoutError::Disconnected) => break,
        }
        let now = clock.now();
        router.handle_timeout(now);
        while let Some(f) = router.poll_gcs_transmit() {
            record(&mut tlog, f.as_bytes());
            udp.send(f.as_bytes());
            if let Some(tcp) = &tcp {
                tcp.send(f.as_bytes());
            }
        }
        while let Some(f) = router.poll_radio_transmit(now, usize::MAX) {
            radio.write(f.as_bytes());
        }
        if now >= next_status {
            status(&router, &radio, tcp.as_ref());
            next_status = now + status_every;
        }
    }
    stop.store(true, Ordering::Relaxed);
    if let Some(t) = &mut tlog {
        t.flush().context("flushing tlog")?;
    }
    status(&router, &radio, tcp.as_ref());
    Ok(())
}

fn status(router: &Router, radio: &SerialLink, tcp: Option<&TcpEndpoint>) {
    let s = router.stats();
    let peer_loss = router.quality().peer().and_then(|p| p.loss_ratio);
    info!(
        radio_rx = s.radio_reader.frames(),
        radio_lost = s.radio_reader.lost,
        radio_bad_crc = s.radio_reader.bad_crc,
        radio_tx = s.scheduler.sent_frames,
        radio_tx_bytes = s.scheduler.sent_bytes,
        radio_opens = radio.opens.load(Ordering::Relaxed),
        gcs_rx = s.gcs_reader.frames(),
        gcs_tx = s.to_gcs_frames,
        tcp_clients = tcp.map_or(0, TcpEndpoint::clients),
        expanded = s.expanded_frames,
        heartbeats_thinned = s.filter.rate_limited,
        mission_duplicates = s.mission_duplicates,
        command_resends = s.commands.retransmissions,
        command_ground_retries_dropped = s.commands.ground_duplicates,
        rejected_unsigned = s.signing.unsigned,
        rejected_bad_signature = s.signing.bad_signature,
        rejected_replayed = s.signing.replayed,
        peer_loss = ?peer_loss,
        "status"
    );
}
