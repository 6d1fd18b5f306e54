//! `mavlora-router`: runs on the ground between the radio's serial port and ground-station
//! software on UDP and TCP. See the crate README for command lines.
//!
//! Exit codes: 0 after SIGINT/SIGTERM, 1 on a configuration or setup error, 2 on bad usage.

use mavlora::Duration;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context, Result};
use clap::Parser;
use serde::Deserialize;
use tracing::{info, warn};

use mavlora::io::{
    Clock, Decibels, Event, INBOX_BYTES, Inbox, Percent, PopError, RadioOptions, Seconds,
    SerialEvent, SerialLink, TcpEndpoint, Tlog, UdpEndpoint, UsageError, frame_gap, on_signal,
    signing_epoch_now,
};
use mavlora::router::{GroundInput, IpNet, Router, RouterConfig};
use mavlora::signing::{SigningConfig, SigningKey};

/// MavLora router: radio serial port <-> ground stations on UDP and TCP.
#[derive(Parser, Deserialize, Default, Debug)]
#[command(version)]
struct Options {
    #[command(flatten)]
    #[serde(skip)]
    shared: RadioOptions,
    /// Where to send until a ground station talks to us [default: 127.0.0.1:14550].
    #[arg(long)]
    udp: Option<SocketAddr>,
    /// Send each frame in a datagram of its own, for a ground station that reads only the
    /// first frame of a datagram [default: frames ready together share a datagram of up to
    /// 1472 bytes, as QGroundControl, MAVProxy, MAVSDK and mavlink-router accept].
    #[arg(long, num_args = 0, default_missing_value = "true")]
    udp_one_frame_per_datagram: Option<bool>,
    /// Local UDP address [default: 127.0.0.1:14555, this host only; 0.0.0.0:14555 opens it
    /// to the network, together with --allow].
    #[arg(long)]
    udp_bind: Option<SocketAddr>,
    /// Source networks (UDP and TCP) that may reach the vehicle and become the UDP peer,
    /// comma-separated, e.g. 127.0.0.1,10.0.0.0/24 [default: 127.0.0.1,::1].
    #[arg(long, value_delimiter = ',')]
    allow: Option<Vec<IpNet>>,
    /// System ids whose frames from the ground go to the radio, comma-separated
    /// [default: 255].
    #[arg(long, value_delimiter = ',')]
    allow_sysid: Option<Vec<u8>>,
    /// MAVLink 2 signing key file for the ground side (64 hex characters, mode 600; not
    /// the radio's --key): frames from ground stations must be signed with it, frames to
    /// them are signed with it.
    #[arg(long)]
    ground_key: Option<PathBuf>,
    /// Commands one ground source may have in the relay at once [default: 4].
    #[arg(long)]
    commands_per_source: Option<usize>,
    /// Also listen for ground stations on TCP here, e.g. 0.0.0.0:5760 (QGroundControl "TCP",
    /// `mavproxy.py --master=tcp:HOST:5760`); every client gets every frame.
    #[arg(long)]
    tcp_listen: Option<SocketAddr>,
    /// TCP clients connected at once; one more is refused [default: 8].
    #[arg(long)]
    tcp_max_clients: Option<usize>,
    /// Write a MAVProxy-format telemetry log here.
    #[arg(long)]
    tlog: Option<PathBuf>,
    /// Seconds between ground heartbeats sent over the radio, 0.1..=86400 [default: 5].
    #[arg(long)]
    gcs_heartbeat_period: Option<Seconds>,
    /// Uplink or downlink loss (percent) at which the ground station is told the link is
    /// degraded (STATUSTEXT) [default: 20].
    #[arg(long)]
    link_degraded: Option<Percent>,
    /// Loss (percent) below which a degraded link is announced restored [default: 10].
    #[arg(long)]
    link_restored: Option<Percent>,
    /// Rise (dB, 0..=60) of the drone's receiver noise floor over the lowest it reported at
    /// which the uplink is announced degraded before any loss shows; restored below half of
    /// it [default: 6, half the free-space range].
    #[arg(long)]
    link_noise_rise: Option<Decibels>,
}

fn main() -> ExitCode {
    mavlora::io::main(|o: &mut Options| &mut o.shared, run)
}

fn run(o: Options) -> Result<()> {
    let radio_path = o.shared.radio_port()?;
    let (rate, burst) = (o.shared.rate(), o.shared.burst());
    let mut config = RouterConfig::new(o.shared.scheduler()?);
    if let Some(p) = o.gcs_heartbeat_period {
        config.gcs_heartbeat_period = p.into();
    }
    let mut signing = o.shared.signing(2, "router")?;
    config.signing = signing.config.clone();
    let signing_label = signing.label();
    config.quality = o.shared.link_quality(config.signing.is_some());
    if let Some(p) = o.link_degraded {
        config.monitor.degraded = p.fraction();
    }
    if let Some(p) = o.link_restored {
        config.monitor.restored = p.fraction();
    }
    if let Some(db) = o.link_noise_rise {
        config.monitor.noise_rise_db = db.db();
        config.monitor.noise_restored_db = db.db() / 2.0;
    }
    if config.monitor.restored > config.monitor.degraded {
        return Err(UsageError::option(
            "link_restored",
            format!(
                "{} % is above the degraded threshold ({} %)",
                100.0 * config.monitor.restored,
                100.0 * config.monitor.degraded
            ),
        )
        .into());
    }
    if let Some(allow) = o.allow {
        config.ground.allow = allow;
    }
    if let Some(ids) = o.allow_sysid {
        config.ground.allow_sysid = ids;
    }
    if let Some(n) = o.commands_per_source {
        if n == 0 {
            return Err(UsageError::option("commands_per_source", "must be at least 1").into());
        }
        config.ground.commands_in_flight = n;
    }
    if let Some(path) = &o.ground_key {
        config.ground_signing = Some(SigningConfig {
            key: SigningKey::load(path)
                .with_context(|| format!("ground key {}", path.display()))?,
            link_id: 3,
            epoch: signing_epoch_now(),
            state: Default::default(),
        });
        info!(key = %path.display(), "ground signing on");
    }
    info!(allow = ?config.ground.allow.iter().map(ToString::to_string).collect::<Vec<_>>(), allow_sysid = ?config.ground.allow_sysid, "ground policy");
    let status_every = o.shared.status_every();
    let mut tlog = match o.tlog {
        Some(p) => Some(Tlog::create(&p).with_context(|| format!("creating {}", p.display()))?),
        None => None,
    };

    let inbox = Inbox::new(INBOX_BYTES);
    on_signal(inbox.clone())?;
    let stop = Arc::new(AtomicBool::new(false));
    let peer = o.udp.unwrap_or(([127, 0, 0, 1], 14550).into());
    let bind = o.udp_bind.unwrap_or(([127, 0, 0, 1], 14555).into());
    let mut udp = UdpEndpoint::spawn(bind, peer, inbox.clone(), stop.clone())?;
    if o.udp_one_frame_per_datagram.unwrap_or(false) {
        udp.one_frame_per_datagram();
    }
    let tcp = match o.tcp_listen {
        Some(addr) => {
            let max = o
                .tcp_max_clients
                .unwrap_or(mavlora::io::DEFAULT_MAX_CLIENTS);
            Some(TcpEndpoint::spawn(addr, max, inbox.clone(), stop.clone())?)
        }
        None => None,
    };
    let radio_baud = o.shared.radio_baud();
    let gap = frame_gap(rate.min(radio_baud / 10));
    let mut radio = SerialLink::spawn(
        "radio",
        &radio_path,
        radio_baud,
        gap,
        inbox.clone(),
        stop.clone(),
    )?;
    let clock = Clock::start();
    let mut router = Router::new(config, clock.now())?;
    info!(rate, burst, signing = signing_label, "router running");
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
            .poll_timeout()
            .unwrap_or(now + Duration::from_secs(1))
            .min(next_status);
        match inbox.recv_timeout(clock.until(deadline)) {
            Ok(Event::Serial(_, SerialEvent::Bytes(b))) => {
                router.handle_radio_bytes(clock.now(), &b);
            }
            Ok(Event::Serial(_, SerialEvent::Idle)) => router.handle_radio_idle(clock.now()),
            Ok(Event::Serial(_, SerialEvent::Closed)) => router.radio_port_closed(),
            // One whole frame each (framed per datagram / per client where it entered), let
            // through only as far as the ground policy allows; the tlog records what it let
            // through, and only a sender it accepted becomes the UDP peer.
            Ok(Event::Udp(frame, from)) => {
                let input = router.handle_gcs_input(clock.now(), from.ip(), &frame);
                report(from, &input);
                if input.learn_peer() {
                    udp.learn(from);
                    record(&mut tlog, &frame);
                }
            }
            Ok(Event::Tcp(frame, from)) => {
                let input = router.handle_gcs_input(clock.now(), from.ip(), &frame);
                report(from, &input);
                if input.learn_peer() {
                    record(&mut tlog, &frame);
                }
            }
            Ok(Event::Serial(_, SerialEvent::Opened)) | Err(PopError::Timeout) => {}
            Ok(Event::Stop) => {
                info!("signal received, shutting down");
                break;
            }
            Err(PopError::Closed) => break,
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
        udp.flush();
        // Only into an open port: a frame leaves the engine numbered and signed, and one
        // dropped at a closed port would read as radio loss at the far end.
        while radio.is_open()
            && let Some(f) = router.poll_radio_transmit(now, usize::MAX)
        {
            radio.write(f.as_bytes());
        }
        if let Some(file) = &mut signing.state_file {
            file.tick(now, || router.signing_state(now));
        }
        if now >= next_status {
            status(signing_label, &router, &radio, &udp, tcp.as_ref(), &inbox);
            next_status = now + status_every;
        }
    }
    stop.store(true, Ordering::Relaxed);
    if let Some(file) = &signing.state_file
        && let Some(state) = router.signing_state(clock.now())
    {
        file.save(&state)?;
    }
    radio.stop();
    if let Some(t) = &mut tlog {
        t.flush().context("flushing tlog")?;
    }
    status(signing_label, &router, &radio, &udp, tcp.as_ref(), &inbox);
    Ok(())
}

/// Logs a rejection the router says is due (at most one per source and reason per 10 s).
fn report(from: SocketAddr, input: &GroundInput) {
    if let Some(why) = input.report {
        warn!(%from, %why, rejected = input.rejected, "ground input rejected (reported once per 10 s)");
    }
}

fn status(
    signing: &str,
    router: &Router,
    radio: &SerialLink,
    udp: &UdpEndpoint,
    tcp: Option<&TcpEndpoint>,
    inbox: &Inbox,
) {
    let s = router.stats();
    let peer_loss = router.quality().peer().and_then(|p| p.loss_ratio);
    let r = radio.counters();
    let t = tcp.map(TcpEndpoint::counters).unwrap_or_default();
    let (_, udp_partials, _) = udp.framing().snapshot();
    let inbox = inbox.stats();
    info!(
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
        gcs_rx = s.gcs_reader.frames(),
        gcs_tx = s.to_gcs_frames,
        udp_datagrams = udp.datagrams(),
        udp_partials_dropped = udp_partials,
        tcp_clients = t.clients,
        tcp_refused = t.refused,
        tcp_dropped_bytes = t.dropped_bytes,
        tcp_partials_dropped = t.partials_dropped,
        inbox_dropped = inbox.dropped_items,
        inbox_dropped_priority = inbox.dropped_priority,
        inbox_peak_bytes = inbox.peak_bytes,
        expanded = s.expanded_frames,
        heartbeats_thinned = s.filter.rate_limited,
        missions_accepted = s.mission.accepted,
        missions_failed = s.mission.failed,
        mission_repairs = s.mission.items_repaired,
        command_resends = s.commands.retransmissions,
        command_blind_resends = s.commands.blind,
        command_copies = s.commands.early_copies,
        command_ground_retries_dropped = s.commands.ground_duplicates,
        commands_queued = s.commands.queued,
        command_late_acks = s.commands.late_acks,
        commands_abandoned = s.commands.abandoned,
        ground_rejected = s.ground.total(),
        rejected_unsigned = s.signing.unsigned,
        rejected_bad_signature = s.signing.bad_signature,
        rejected_replayed = s.signing.replayed,
        rejected_stale = s.signing.stale,
        radio_tx_unsigned = s.signing.sent_unsigned,
        signing = %signing,
        peer_loss = ?peer_loss,
        "status"
    );
}
