//! What the pilot is told, in messages every ground station knows (SORA OSO#6: the remote
//! pilot continuously monitors the C2 link): `RADIO_STATUS` once a second, built
//! from both ends' `LINK_QUALITY` and the local radio, and a `STATUSTEXT` when a direction's
//! health changes (degraded, lost, restored), once per change.
//!
//! A direction's health moves with hysteresis ([`MonitorConfig::degraded`] up,
//! [`MonitorConfig::restored`] down) and is announced at most once per
//! [`MonitorConfig::hold`]; a change within the hold is announced when it ends, only if the
//! health then still differs from the last announcement. A flapping link thus gives at most
//! one message per hold and never the same message twice in a row.

use std::fmt::Write as _;

use super::engine::{LinkQuality, PeerState};
use super::rssi::RssiScale;
use crate::dialect::{MavSeverity, RADIO_STATUS_DATA, STATUSTEXT_DATA};
use crate::time::{Duration, Instant};

/// Alarm thresholds and cadence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonitorConfig {
    /// Loss (0..=1) at or above which a direction is degraded: twice the paper's worst
    /// measured link (10.1 % UAV→GCS).
    pub degraded: f64,
    /// Loss below which a degraded or lost direction is restored.
    pub restored: f64,
    /// The drone's receiver noise floor this far (dB) above the lowest it reported degrades
    /// the uplink before any loss is counted (the paper's blind drone). 6 dB halves the
    /// free-space range the uplink had.
    pub noise_rise_db: f64,
    /// Noise rise below which a degraded uplink is restored (if its loss allows).
    pub noise_restored_db: f64,
    /// At most one announcement per direction per this.
    pub hold: Duration,
    /// Time between two `RADIO_STATUS` to the ground (SiK radios send one a second).
    pub radio_status_period: Duration,
}

impl Default for MonitorConfig {
    fn default() -> Self {
        Self {
            degraded: 0.20,
            restored: 0.10,
            noise_rise_db: 6.0,
            noise_restored_db: 3.0,
            hold: Duration::from_secs(2),
            radio_status_period: Duration::from_secs(1),
        }
    }
}

/// A direction of the radio link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Ground → air: what the drone hears (from its reports).
    Uplink,
    /// Air → ground: what the router hears.
    Downlink,
}

impl Direction {
    /// Lower-case name, as in status files.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Uplink => "uplink",
            Self::Downlink => "downlink",
        }
    }

    fn label(self) -> &'static str {
        match self {
            Self::Uplink => "Uplink GCS>UAV",
            Self::Downlink => "Downlink UAV>GCS",
        }
    }
}

/// A direction's health.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Health {
    /// Loss below the thresholds.
    Ok,
    /// Loss at or above [`MonitorConfig::degraded`].
    Degraded,
    /// Nothing gets through: the drone received none of our frames (uplink) or we heard
    /// nothing from it (downlink).
    Lost,
    /// The drone's reports stopped while its other frames still arrive: the uplink is not
    /// known (a bridge that stopped reporting must not look like a healthy link).
    Silent,
}

impl Health {
    /// Lower-case name, as in status files.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::Degraded => "degraded",
            Self::Lost => "lost",
            Self::Silent => "silent",
        }
    }
}

/// One announcement for the ground.
#[derive(Debug, Clone, PartialEq)]
pub struct Notice {
    /// Which direction.
    pub direction: Direction,
    /// Its new health.
    pub health: Health,
    /// Its loss estimate (0..=1), when known.
    pub loss: Option<f64>,
    /// How long the peer has been silent, s ([`Health::Silent`], downlink [`Health::Lost`]).
    pub silent_s: Option<f64>,
    /// Uplink: the drone's noise floor above its lowest, dB, when it reports one.
    pub noise_rise_db: Option<f64>,
    /// The noise rise, not the loss, is what degraded the direction.
    pub by_noise: bool,
}

impl Notice {
    /// The pilot's text (at most 50 characters, `STATUSTEXT`'s size).
    pub fn text(&self) -> String {
        let mut t = String::from(self.direction.label());
        let pct = |l: Option<f64>| l.map_or("?".into(), |l| format!("{:.0}", 100.0 * l));
        let noise = |r: Option<f64>| format!("drone noise {:+.0}dB", r.unwrap_or(0.0));
        let _ = match (self.health, self.direction) {
            (Health::Ok, _) if self.loss.is_none() && self.noise_rise_db.is_some() => {
                write!(t, " restored: {}", noise(self.noise_rise_db))
            }
            (Health::Ok, _) => write!(t, " restored: {}% lost", pct(self.loss)),
            (Health::Degraded, _) if self.by_noise => {
                write!(t, " degraded: {}", noise(self.noise_rise_db))
            }
            (Health::Degraded, _) => write!(t, " degraded: {}% lost", pct(self.loss)),
            (Health::Lost, Direction::Uplink) => write!(t, " lost: drone hears nothing"),
            (Health::Lost, Direction::Downlink) => write!(
                t,
                " lost: nothing heard {:.0}s",
                self.silent_s.unwrap_or(0.0)
            ),
            (Health::Silent, _) => write!(
                t,
                " unknown: no drone report {:.0}s",
                self.silent_s.unwrap_or(0.0)
            ),
        };
        t.truncate(50);
        t
    }

    /// How urgent it is.
    pub fn severity(&self) -> MavSeverity {
        match self.health {
            Health::Ok => MavSeverity::MAV_SEVERITY_NOTICE,
            Health::Degraded | Health::Silent => MavSeverity::MAV_SEVERITY_WARNING,
            Health::Lost => MavSeverity::MAV_SEVERITY_CRITICAL,
        }
    }

    /// As a `STATUSTEXT`.
    pub fn statustext(&self) -> STATUSTEXT_DATA {
        STATUSTEXT_DATA {
            severity: self.severity(),
            text: self.text().as_str().into(),
            ..Default::default()
        }
    }
}

#[derive(Debug, Clone, Default)]
struct Track {
    health: Option<Health>,
    announced: Option<Health>,
    announced_at: Option<Instant>,
    loss: Option<f64>,
    silent_s: Option<f64>,
    noise_rise: Option<f64>,
    by_noise: bool,
}

/// Sans-IO: turns a [`LinkQuality`] into what the ground station is told. Call
/// [`handle_timeout`](Self::handle_timeout) at [`poll_timeout`](Self::poll_timeout) (and
/// after radio input), then drain [`poll_notice`](Self::poll_notice) and
/// [`poll_radio_status`](Self::poll_radio_status).
#[derive(Debug)]
pub struct LinkMonitor {
    config: MonitorConfig,
    up: Track,
    down: Track,
    notices: Vec<Notice>,
    next_status: Option<Instant>,
    status_due: bool,
    /// Announcements made, per direction (uplink, downlink).
    announced: (u64, u64),
}

impl LinkMonitor {
    /// A monitor with `config`.
    pub fn new(config: MonitorConfig) -> Self {
        Self {
            config,
            up: Track::default(),
            down: Track::default(),
            notices: Vec::new(),
            next_status: None,
            status_due: false,
            announced: (0, 0),
        }
    }

    /// The thresholds.
    pub fn config(&self) -> &MonitorConfig {
        &self.config
    }

    /// A direction's current health (`None` until something is known).
    pub fn health(&self, direction: Direction) -> Option<Health> {
        match direction {
            Direction::Uplink => self.up.health,
            Direction::Downlink => self.down.health,
        }
    }

    /// Announcements made so far (uplink, downlink).
    pub fn announced(&self) -> (u64, u64) {
        self.announced
    }

    /// Hysteresis on a loss estimate from the previous health.
    fn by_loss(&self, prev: Option<Health>, loss: f64) -> Health {
        if loss >= self.config.degraded {
            Health::Degraded
        } else if loss < self.config.restored {
            Health::Ok
        } else {
            match prev {
                None | Some(Health::Ok) => Health::Ok,
                Some(_) => Health::Degraded,
            }
        }
    }

    /// Hysteresis on the drone's noise rise from the previous health.
    fn by_noise(&self, prev: Option<Health>, rise_db: f64) -> Health {
        if rise_db >= self.config.noise_rise_db {
            Health::Degraded
        } else if rise_db < self.config.noise_restored_db {
            Health::Ok
        } else {
            match prev {
                None | Some(Health::Ok) => Health::Ok,
                Some(_) => Health::Degraded,
            }
        }
    }

    /// Looks at the link as of `now`.
    pub fn handle_timeout(&mut self, now: Instant, q: &LinkQuality) {
        let heard = q.last_heard();
        let down_quiet = heard.is_some() && q.peer_quiet(now);
        // Downlink: what we hear.
        let down = if heard.is_none() {
            None
        } else if down_quiet {
            self.down.silent_s = heard.map(|h| now.saturating_duration_since(h).as_secs_f64());
            Some(Health::Lost)
        } else {
            self.down.loss = q.own_loss(now);
            self.down.loss.map(|l| self.by_loss(self.down.health, l))
        }
        .or(self.down.health);
        self.down.health = down;
        // Uplink: what the drone says it hears.
        let up = match q.peer_state(now) {
            PeerState::Unknown => None,
            // Nothing comes at all: the downlink's alarm says it; the uplink is not known.
            _ if down_quiet => self.up.health,
            PeerState::Missing { since } => {
                self.up.silent_s = Some(now.saturating_duration_since(since).as_secs_f64());
                Some(Health::Silent)
            }
            PeerState::Reporting { .. } => {
                let loss = q.peer_loss(now);
                let rise = q.peer_noise_rise_db(now);
                self.up.loss = loss;
                self.up.noise_rise = rise;
                let prev = self.up.health.filter(|h| *h != Health::Silent);
                match loss {
                    Some(l) if l >= 1.0 => Some(Health::Lost),
                    _ => {
                        let by_loss = loss.map(|l| self.by_loss(prev, l));
                        let by_noise = rise.map(|r| self.by_noise(prev, r));
                        self.up.by_noise =
                            by_noise == Some(Health::Degraded) && by_loss != Some(Health::Degraded);
                        match (by_loss, by_noise) {
                            (Some(Health::Degraded), _) | (_, Some(Health::Degraded)) => {
                                Some(Health::Degraded)
                            }
                            (None, None) => prev,
                            _ => Some(Health::Ok),
                        }
                    }
                }
            }
        };
        self.up.health = up;
        self.announce(now, Direction::Uplink);
        self.announce(now, Direction::Downlink);
        // RADIO_STATUS once a period, from the first frame heard on.
        if heard.is_some() {
            let next = *self.next_status.get_or_insert(now);
            if now >= next {
                self.status_due = true;
                let period = self.config.radio_status_period;
                self.next_status = Some(if next + period <= now {
                    now + period
                } else {
                    next + period
                });
            }
        }
    }

    fn announce(&mut self, now: Instant, direction: Direction) {
        let hold = self.config.hold;
        let track = match direction {
            Direction::Uplink => &mut self.up,
            Direction::Downlink => &mut self.down,
        };
        let Some(health) = track.health else {
            return;
        };
        if track.announced == Some(health) {
            return;
        }
        // A link that comes up healthy is not news.
        if track.announced.is_none() && health == Health::Ok {
            track.announced = Some(Health::Ok);
            return;
        }
        if track
            .announced_at
            .is_some_and(|at| now.saturating_duration_since(at) < hold)
        {
            return;
        }
        track.announced = Some(health);
        track.announced_at = Some(now);
        let notice = Notice {
            direction,
            health,
            loss: track.loss,
            silent_s: track.silent_s,
            noise_rise_db: track.noise_rise,
            by_noise: track.by_noise,
        };
        match direction {
            Direction::Uplink => self.announced.0 += 1,
            Direction::Downlink => self.announced.1 += 1,
        }
        tracing::info!(text = notice.text(), "link announcement");
        self.notices.push(notice);
    }

    /// When the monitor next wants [`handle_timeout`](Self::handle_timeout).
    pub fn poll_timeout(&self) -> Option<Instant> {
        let held = [&self.up, &self.down]
            .into_iter()
            .filter(|t| t.health.is_some() && t.health != t.announced)
            .filter_map(|t| t.announced_at.map(|at| at + self.config.hold))
            .min();
        [self.next_status, held].into_iter().flatten().min()
    }

    /// The next announcement.
    pub fn poll_notice(&mut self) -> Option<Notice> {
        (!self.notices.is_empty()).then(|| self.notices.remove(0))
    }

    /// The `RADIO_STATUS` due, once: our RSSI and the drone's (from its report, else our
    /// radio's remote RSSI), receive errors on the downlink (lost + bad CRC, wrapping), the
    /// drone's noise floor (from its report, else our radio's remote noise), the local
    /// radio's noise, corrected packets and free buffer when it sends `RADIO_STATUS` (else
    /// unknown: 255, 0 corrected, 100 % free).
    // `..Default::default()` stays: the dialect gains MAVLink 2 extension fields.
    #[allow(clippy::needless_update)]
    pub fn poll_radio_status(&mut self, q: &LinkQuality) -> Option<RADIO_STATUS_DATA> {
        if !std::mem::take(&mut self.status_due) {
            return None;
        }
        let scale = q.config().radio_status.unwrap_or(RssiScale::Sik);
        let (rssi, remote) = q.rssi();
        let drone = q
            .peer()
            .map(|p| p.report.rssi)
            .filter(|r| *r != i8::MAX)
            .or(remote);
        let local = q.local_radio();
        let stats = q.reader_stats();
        Some(RADIO_STATUS_DATA {
            rssi: scale.from_dbm(rssi),
            remrssi: scale.from_dbm(drone),
            rxerrors: (stats.lost + stats.bad_crc) as u16,
            fixed: local.map_or(0, |l| l.fixed),
            noise: local.map_or(u8::MAX, |l| l.noise),
            // The drone's own word on its noise floor first: it is what deafens it.
            remnoise: q
                .peer()
                .map(|p| p.report.noise)
                .filter(|n| *n != 0)
                .map_or(local.map_or(u8::MAX, |l| l.remnoise), |n| {
                    scale.from_dbm(Some(n))
                }),
            txbuf: local.map_or(100, |l| l.txbuf),
            ..Default::default()
        })
    }
}

#[cfg(test)]
mod tests;
