//! The link-quality engine: reports what this side hears (`LINK_QUALITY`, periodically) and keeps what
//! the other side reports hearing. The paper's reason: a drone's own RF noise can blind its
//! receiver while the ground still hears the drone, so the ground must be told.

use crate::time::Duration;

use tracing::debug;

use super::rssi::RssiScale;
use crate::dialect::{LINK_QUALITY_DATA, MavMessage};
use crate::time::Instant;
use crate::wire::{Frame, ReaderStats, ids};

/// Settings of a [`LinkQuality`] engine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkQualityConfig {
    /// Time between our reports. Each costs a 24-byte MAVLink 2 frame on the radio.
    pub period: Duration,
    /// A peer report older than this counts as missing.
    pub peer_timeout: Duration,
    /// How to read `RADIO_STATUS` from the local radio; `None` ignores it.
    pub radio_status: Option<RssiScale>,
}

impl Default for LinkQualityConfig {
    /// A report every 5 s (~5 B/s: a 1 s period would spend a third of a 68 B/s LoRa duty
    /// cycle budget on it), peer missing after three silent periods, SiK radio.
    fn default() -> Self {
        Self {
            period: Duration::from_secs(5),
            peer_timeout: Duration::from_secs(15),
            radio_status: Some(RssiScale::Sik),
        }
    }
}

/// The latest report from the other side of the link.
#[derive(Debug, Clone, PartialEq)]
pub struct PeerReport {
    /// The report as received.
    pub report: LINK_QUALITY_DATA,
    /// When it arrived.
    pub received_at: Instant,
    /// Fraction of our frames the peer lost between its previous report and this one, from
    /// the differences of its wrapping counters; `None` for its first report or when no
    /// frames were counted in between.
    pub loss_ratio: Option<f64>,
}

/// What we know about how the peer hears us.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PeerState {
    /// No report received yet.
    Unknown,
    /// The last report is older than the timeout: either the peer stopped hearing us (it
    /// reports nonetheless) or we stopped hearing it.
    Missing {
        /// When the last report arrived.
        since: Instant,
    },
    /// A recent report.
    Reporting {
        /// See [`PeerReport::loss_ratio`].
        loss_ratio: Option<f64>,
    },
}

/// Sans-IO link-quality engine for one radio link.
///
/// Feed it every frame read from the radio ([`handle_frame`](Self::handle_frame)); at
/// [`poll_timeout`](Self::poll_timeout) call [`handle_timeout`](Self::handle_timeout) with the
/// radio reader's counters, then send what [`poll_report`](Self::poll_report) returns.
#[derive(Debug)]
pub struct LinkQuality {
    config: LinkQualityConfig,
    started: Instant,
    next_report: Instant,
    rssi: Option<i8>,
    remote_rssi: Option<i8>,
    peer: Option<PeerReport>,
    /// Our report, made at its time and waiting for [`poll_report`](Self::poll_report).
    due: Option<LINK_QUALITY_DATA>,
}

impl LinkQuality {
    /// An engine started at `now`; the first report is due one period later.
    pub fn new(config: LinkQualityConfig, now: Instant) -> Self {
        Self {
            config,
            started: now,
            next_report: now + config.period,
            rssi: None,
            remote_rssi: None,
            peer: None,
            due: None,
        }
    }

    /// Sets signal strengths from a source other than `RADIO_STATUS` (e.g. a LoRa modem's
    /// packet RSSI), in dBm.
    pub fn set_rssi(&mut self, rssi: Option<i8>, remote_rssi: Option<i8>) {
        self.rssi = rssi;
        self.remote_rssi = remote_rssi;
    }

    /// Looks at a frame read from the radio. Only the peer's `LINK_QUALITY` and the local
    /// radio's `RADIO_STATUS` are decoded; other frames are ignored by header.
    pub fn handle_frame<T: AsRef<[u8]>>(&mut self, now: Instant, frame: &Frame<T>) {
        match frame.message_id() {
            ids::LINK_QUALITY => {
                if let Ok(MavMessage::LINK_QUALITY(report)) = frame.decode::<MavMessage>() {
                    self.peer_report(report, now);
                }
            }
            ids::RADIO_STATUS => {
                let Some(scale) = self.config.radio_status else {
                    return;
                };
                if let Ok(MavMessage::RADIO_STATUS(status)) = frame.decode::<MavMessage>() {
                    self.rssi = scale.to_dbm(status.rssi);
                    self.remote_rssi = scale.to_dbm(status.remrssi);
                }
            }
            _ => {}
        }
    }

    fn peer_report(&mut self, report: LINK_QUALITY_DATA, now: Instant) {
        let loss_ratio = self.peer.as_ref().and_then(|prev| {
            let lost = report.rx_lost.wrapping_sub(prev.report.rx_lost);
            let received = report.rx_packets.wrapping_sub(prev.report.rx_packets);
            let total = u32::from(lost) + u32::from(received);
            (total > 0).then(|| f64::from(lost) / f64::from(total))
        });
        debug!(
            ?loss_ratio,
            rx = report.rx_packets,
            "peer link-quality report"
        );
        self.peer = Some(PeerReport {
            report,
            received_at: now,
            loss_ratio,
        });
    }

    /// When the next report is due (always `Some`: reports never stop).
    pub fn poll_timeout(&self) -> Option<Instant> {
        Some(self.next_report)
    }

    /// Makes our report if one is due at `now`, from the radio reader's counters (cumulative,
    /// truncated to 16 bits as the message defines); [`poll_report`](Self::poll_report)
    /// hands it out.
    pub fn handle_timeout(&mut self, now: Instant, stats: &ReaderStats) {
        if now < self.next_report {
            return;
        }
        // Keep the cadence, but do not fire a burst of reports after a stall.
        let next = self.next_report + self.config.period;
        self.next_report = if next <= now {
            now + self.config.period
        } else {
            next
        };
        let unknown = |v: Option<i8>| v.unwrap_or(i8::MAX);
        self.due = Some(LINK_QUALITY_DATA {
            time_boot_ms: now.saturating_duration_since(self.started).as_millis() as u32,
            rx_packets: stats.frames() as u16,
            rx_lost: stats.lost as u16,
            rx_bad_crc: stats.bad_crc as u16,
            rssi: unknown(self.rssi),
            remote_rssi: unknown(self.remote_rssi),
        });
    }

    /// The report made by [`handle_timeout`](Self::handle_timeout), once.
    pub fn poll_report(&mut self) -> Option<LINK_QUALITY_DATA> {
        self.due.take()
    }

    /// The peer's latest report.
    pub fn peer(&self) -> Option<&PeerReport> {
        self.peer.as_ref()
    }

    /// How the peer hears us, as of `now`.
    pub fn peer_state(&self, now: Instant) -> PeerState {
        match &self.peer {
            None => PeerState::Unknown,
            Some(p) if now.saturating_duration_since(p.received_at) > self.config.peer_timeout => {
                PeerState::Missing {
                    since: p.received_at,
                }
            }
            Some(p) => PeerState::Reporting {
                loss_ratio: p.loss_ratio,
            },
        }
    }
}

#[cfg(test)]
mod tests;
