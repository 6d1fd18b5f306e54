//! What both binaries run around their engine, written once: the start-up common to both
//! ([`RadioOptions::setup`]: radio options, signing, the inbox and the signal handler; then
//! [`Setup::open_radio`]), and the main loop ([`Station::run`]): the radio port, timers,
//! signing state and status. Each binary adds its own side ([`Side`]): the bridge its flight
//! controller's port, the router its ground stations.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use serde::Serialize;
use tracing::info;

use super::status::{Joined, RadioCounters, RadioGauges, RadioStats, Status, StatusReport};
use super::{
    Clock, Event, INBOX_BYTES, Inbox, Order, PopError, RadioOptions, RadioSigning, SerialEvent,
    SerialLink, frame_gap, on_signal,
};
use crate::quality::{LinkQualityConfig, Notice};
use crate::schedule::SchedulerConfig;
use crate::signing::SigningState;
use crate::time::{Duration, Instant};
use crate::wire::OwnedFrame;

/// The name of the radio's [`SerialLink`] (and of its [`Event::Serial`]s).
const RADIO: &str = "radio";

/// An engine at one end of the radio link, as [`Station::run`] drives it.
pub trait RadioEngine {
    /// When it next needs [`handle_timeout`](Self::handle_timeout).
    fn poll_timeout(&self) -> Option<Instant>;
    /// Runs its timers.
    fn handle_timeout(&mut self, now: Instant);
    /// Bytes from the radio.
    fn handle_radio_bytes(&mut self, now: Instant, bytes: &[u8]);
    /// The radio fell idle after bytes.
    fn handle_radio_idle(&mut self, now: Instant);
    /// The radio port closed; it is being reopened.
    fn radio_port_closed(&mut self);
    /// The next frame for the radio, if the budget lets it out and it fits `room`.
    fn poll_radio_transmit(&mut self, now: Instant, room: usize) -> Option<OwnedFrame>;
    /// The radio signing state to save, `None` unsigned.
    fn signing_state(&self, now: Instant) -> Option<SigningState>;
    /// What it counts on its radio leg.
    fn radio_stats(&self) -> RadioStats;
    /// The loss the far end last reported (0..=1).
    fn peer_loss(&self) -> Option<f64>;
    /// The next link announcement it sent to the ground, for the status file.
    fn poll_link_notice(&mut self) -> Option<Notice>;
}

/// Both engines have these as inherent methods of the same names.
macro_rules! radio_engine {
    ($engine:ty, $poll_link_notice:expr) => {
        impl RadioEngine for $engine {
            fn poll_timeout(&self) -> Option<Instant> {
                <$engine>::poll_timeout(self)
            }
            fn handle_timeout(&mut self, now: Instant) {
                <$engine>::handle_timeout(self, now)
            }
            fn handle_radio_bytes(&mut self, now: Instant, bytes: &[u8]) {
                <$engine>::handle_radio_bytes(self, now, bytes)
            }
            fn handle_radio_idle(&mut self, now: Instant) {
                <$engine>::handle_radio_idle(self, now)
            }
            fn radio_port_closed(&mut self) {
                <$engine>::radio_port_closed(self)
            }
            fn poll_radio_transmit(&mut self, now: Instant, room: usize) -> Option<OwnedFrame> {
                <$engine>::poll_radio_transmit(self, now, room)
            }
            fn signing_state(&self, now: Instant) -> Option<SigningState> {
                <$engine>::signing_state(self, now)
            }
            fn radio_stats(&self) -> RadioStats {
                let s = self.stats();
                RadioStats {
                    reader: s.radio_reader,
                    scheduler: s.scheduler,
                    signing: s.signing,
                }
            }
            fn peer_loss(&self) -> Option<f64> {
                self.quality().peer().and_then(|p| p.loss_ratio)
            }
            fn poll_link_notice(&mut self) -> Option<Notice> {
                $poll_link_notice(self)
            }
        }
    };
}

// The bridge announces nothing to a ground station; the router tells it of the link's health.
radio_engine!(crate::bridge::Bridge, |_: &mut crate::bridge::Bridge| None);
radio_engine!(
    crate::router::Router,
    crate::router::Router::poll_link_notice
);

/// A binary's own half of the main loop: its other ports and its part of the status.
pub trait Side<E> {
    /// Its counters (totals and maxima) on the status lines, after the radio link's.
    type Counters: Serialize;
    /// Its gauges (levels now) on the status lines, after the radio link's.
    type Gauges: Serialize;
    /// An event that is not the radio's (another port's, a ground station's frame).
    fn handle(&mut self, engine: &mut E, now: Instant, event: Event);
    /// Hands what the engine has for the side's ports to them (after every event).
    fn transmit(&mut self, engine: &mut E, now: Instant);
    /// Its counters and gauges now.
    fn status(&self, engine: &E) -> (Self::Counters, Self::Gauges);
    /// Stops its ports once the loop has ended (flushes files, stores what it keeps of the
    /// engine at `now`); an error ends the program with status 1 once the radio is stopped
    /// too.
    fn stop(&mut self, engine: &E, now: Instant) -> anyhow::Result<()>;
}

/// The start-up both binaries share, done: options checked, signing set up, the inbox and
/// the SIGINT/SIGTERM handler installed. The binary makes its engine's config from it and
/// spawns its own ports ([`spawn`](Self::spawn)), then [`open_radio`](Self::open_radio).
#[derive(Debug)]
pub struct Setup {
    /// The radio budget's settings.
    pub scheduler: SchedulerConfig,
    /// Radio signing, with its state file.
    pub signing: RadioSigning,
    /// Link-quality settings for this budget and signing.
    pub quality: LinkQualityConfig,
    /// The radio budget, bytes per second.
    pub rate: u32,
    /// The radio burst, bytes.
    pub burst: u32,
    radio_path: String,
    radio_baud: u32,
    status_every: Duration,
    inbox: Inbox,
    stop: Arc<AtomicBool>,
}

impl RadioOptions {
    /// The start-up both binaries share: the radio port named, the budget checked, radio
    /// signing set up as link `link_id` for `role` (see [`signing`](Self::signing)), the
    /// inbox made and the signal handler installed.
    pub fn setup(&self, link_id: u8, role: &str) -> anyhow::Result<Setup> {
        let radio_path = self.radio_port()?;
        if self.radio_baud() == 0 {
            return Err(super::UsageError::option(
                "radio_baud",
                "0: must be the radio port's baud rate",
            )
            .into());
        }
        let scheduler = self.scheduler()?;
        let signing = self.signing(link_id, role)?;
        let quality = self.link_quality(signing.config.is_some());
        let inbox = Inbox::new(INBOX_BYTES);
        on_signal(inbox.clone())?;
        Ok(Setup {
            scheduler,
            signing,
            quality,
            rate: self.rate(),
            burst: self.burst(),
            radio_path,
            radio_baud: self.radio_baud(),
            status_every: self.status_every(),
            inbox,
            stop: Arc::new(AtomicBool::new(false)),
        })
    }
}

impl Setup {
    /// Starts a serial port of the binary's own (`name` is its events' name), feeding the
    /// inbox and stopped with the rest.
    pub fn spawn(
        &self,
        name: &'static str,
        path: &str,
        baud: u32,
        idle_gap: std::time::Duration,
    ) -> anyhow::Result<SerialLink> {
        self.spawn_ordered(name, path, baud, idle_gap, Order::PriorityFirst)
    }

    fn spawn_ordered(
        &self,
        name: &'static str,
        path: &str,
        baud: u32,
        idle_gap: std::time::Duration,
        order: Order,
    ) -> anyhow::Result<SerialLink> {
        SerialLink::spawn(
            name,
            path,
            baud,
            idle_gap,
            order,
            self.inbox.clone(),
            self.stop.clone(),
        )
    }

    /// The inbox, for the binary's other endpoints (UDP, TCP).
    pub fn inbox(&self) -> &Inbox {
        &self.inbox
    }

    /// The flag that stops the IO threads when the loop ends.
    pub fn stop_flag(&self) -> &Arc<AtomicBool> {
        &self.stop
    }

    /// Starts the radio port (its idle gap: a frame's time at the budget or the line rate,
    /// whichever is slower) and the clock.
    pub fn open_radio(self) -> anyhow::Result<Station> {
        let gap = frame_gap(self.rate.min(self.radio_baud / 10));
        // Frames leave as the engine numbered and signed them: never reordered here.
        let radio = self.spawn_ordered(
            RADIO,
            &self.radio_path,
            self.radio_baud,
            gap,
            Order::Arrival,
        )?;
        Ok(Station {
            radio,
            clock: Clock::start(),
            setup: self,
        })
    }
}

/// One end of the radio link, running: the radio port and the clock, around an engine.
#[derive(Debug)]
pub struct Station {
    radio: SerialLink,
    clock: Clock,
    setup: Setup,
}

impl Station {
    /// Engine time now.
    pub fn now(&self) -> Instant {
        self.clock.now()
    }

    /// For the status line: `on` or `OFF`.
    pub fn signing_label(&self) -> &'static str {
        self.setup.signing.label()
    }

    /// Runs `engine` with `side` until SIGINT or SIGTERM: events to the engine, timers, the
    /// engine's frames out to the radio and the side's ports, the signing state saved
    /// now and then, a status every `--status-interval`. Then stops every port, saves the
    /// signing state and reports the final status with how the program ends.
    pub fn run<E: RadioEngine, S: Side<E>>(
        mut self,
        mut engine: E,
        mut side: S,
        report: &mut StatusReport,
    ) -> anyhow::Result<()> {
        let every = self.setup.status_every;
        let mut next_status = self.clock.now() + every;
        loop {
            let now = self.clock.now();
            let deadline = engine
                .poll_timeout()
                .unwrap_or(now + Duration::from_secs(1))
                .min(next_status);
            match self.setup.inbox.recv_timeout(self.clock.until(deadline)) {
                Ok(Event::Serial(RADIO, SerialEvent::Bytes(b))) => {
                    engine.handle_radio_bytes(self.clock.now(), &b);
                }
                Ok(Event::Serial(RADIO, SerialEvent::Idle)) => {
                    engine.handle_radio_idle(self.clock.now());
                }
                Ok(Event::Serial(RADIO, SerialEvent::Closed)) => engine.radio_port_closed(),
                Ok(Event::Serial(RADIO, SerialEvent::Opened)) | Err(PopError::Timeout) => {}
                Ok(Event::Stop) => {
                    info!("signal received, shutting down");
                    break;
                }
                Err(PopError::Closed) => break,
                Ok(event) => side.handle(&mut engine, self.clock.now(), event),
            }
            let now = self.clock.now();
            engine.handle_timeout(now);
            while let Some(notice) = engine.poll_link_notice() {
                report.event("link_notice", &LinkNotice::from(&notice));
            }
            side.transmit(&mut engine, now);
            // Only into an open port: a frame leaves the engine numbered and signed, and one
            // dropped at a closed port would read as radio loss at the far end.
            while self.radio.is_open()
                && let Some(f) = engine.poll_radio_transmit(now, usize::MAX)
            {
                self.radio.write(f.as_bytes());
            }
            if let Some(file) = &mut self.setup.signing.state_file {
                file.tick(now, || engine.signing_state(now));
            }
            if now >= next_status {
                report.status(&self.status(&engine, &side));
                next_status = now + every;
            }
        }
        self.setup.stop.store(true, Ordering::Relaxed);
        let saved = match (
            &self.setup.signing.state_file,
            engine.signing_state(self.now()),
        ) {
            (Some(file), Some(state)) => file.save(&state),
            _ => Ok(()),
        };
        let stopped = side.stop(&engine, self.now());
        self.radio.stop();
        let result = saved.and(stopped);
        report.stop(Some(&self.status(&engine, &side)), &result);
        result
    }

    /// The status now: the radio link's counters and gauges, then the side's.
    fn status<E: RadioEngine, S: Side<E>>(
        &self,
        engine: &E,
        side: &S,
    ) -> Status<S::Counters, S::Gauges> {
        let port = self.radio.counters();
        let radio = RadioCounters::new(&engine.radio_stats(), &port, &self.setup.inbox.stats());
        let (counters, gauges) = side.status(engine);
        Status {
            signing: self.signing_label(),
            peer_loss: engine.peer_loss(),
            counters: Joined {
                radio,
                program: counters,
            },
            gauges: Joined {
                radio: RadioGauges::new(&port),
                program: gauges,
            },
        }
    }
}

/// A link announcement as its status-file event (`link_notice`).
#[derive(Serialize)]
struct LinkNotice {
    /// `uplink` or `downlink`.
    direction: &'static str,
    /// Its new health: `ok`, `degraded`, `lost` or `silent`.
    health: &'static str,
    /// Its loss estimate, percent, when known.
    loss_pct: Option<f64>,
    /// The `STATUSTEXT` the ground station was sent.
    text: String,
}

impl From<&Notice> for LinkNotice {
    fn from(n: &Notice) -> Self {
        LinkNotice {
            direction: n.direction.as_str(),
            health: n.health.as_str(),
            loss_pct: n.loss.map(|l| 100.0 * l),
            text: n.text(),
        }
    }
}
