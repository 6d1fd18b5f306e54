//! The link-quality engine: reports what this side hears (`LINK_QUALITY`) and keeps what the
//! other side reports hearing. The paper's reason: a drone's own RF noise can blind its
//! receiver while the ground still hears the drone, so the ground must be told.
//!
//! Reports are event-driven, so a quiet link costs little and a change is told at once: one
//! goes out early when our loss estimate moved by
//! [`LinkQualityConfig::change`] since the last one, or when the peer went quiet; otherwise
//! one per [`LinkQualityConfig::period`] (the steady cost). The side that sends the reports
//! also counts its own radio frames ([`LinkQuality::sent_frame`]), so a report that says "I
//! received nothing" while we sent is read as a deaf peer at once.
//!
//! Counting loss needs frames, and the uplink of a slow radio carries few: at one frame every
//! few seconds, 40 % loss takes tens of seconds to show. The paper's cause of a blind drone,
//! its own noise floor rising, shows at once in the drone radio's `RADIO_STATUS` (`noise`):
//! each report carries the sender's noise floor, one goes out early when it moved by
//! [`LinkQualityConfig::noise_change_db`], and the side reading the reports knows how far the
//! peer's receiver is desensitised ([`LinkQuality::peer_noise_rise_db`]).

use std::collections::VecDeque;

use tracing::debug;

use super::rssi::RssiScale;
use super::window::LossWindow;
use crate::dialect::{LINK_QUALITY_DATA, MavMessage, RADIO_STATUS_DATA};
use crate::time::{Duration, Instant};
use crate::wire::{Frame, ReaderStats, StreamId, ids};

/// A `LINK_QUALITY` frame on the radio: MAVLink 2, 13-byte payload with the noise floor (one
/// byte less when the radio reports none), unsigned.
pub const REPORT_BYTES: u32 = 25;
/// The same, signed (13-byte trailer).
pub const REPORT_BYTES_SIGNED: u32 = 38;
/// Share of a side's radio budget its steady reports may use: the steady cost allowed for
/// link monitoring is 3 B/s of LoRa SF7's 683 B/s (≈ 0.44 %), rounded down.
pub const MONITOR_SHARE: f64 = 0.004;

/// Settings of a [`LinkQuality`] engine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkQualityConfig {
    /// Longest time between our reports (the keep-alive): the steady cost is one report
    /// frame per period.
    pub period: Duration,
    /// Shortest time between our reports: event-driven reports never come faster.
    pub min_interval: Duration,
    /// Our loss estimate moving by at least this much (0..=1) since our last report sends
    /// the next one early.
    pub change: f64,
    /// Span of the loss estimates (ours and the peer's).
    pub window: Duration,
    /// Nothing heard from the peer for this long: it has gone quiet and one report goes
    /// out early (once per quiet spell).
    pub quiet_after: Duration,
    /// A peer report older than this counts as missing.
    pub peer_timeout: Duration,
    /// Our radio's noise floor moving by at least this much (dB) since our last report sends
    /// the next one early; the peer's moving by twice this starts its loss estimate afresh
    /// (what was counted before describes another channel).
    pub noise_change_db: f64,
    /// How to read `RADIO_STATUS` from the local radio; `None` ignores it.
    pub radio_status: Option<RssiScale>,
}

impl Default for LinkQualityConfig {
    /// For a LoRa SF7 channel's 683 B/s, unsigned: see [`LinkQualityConfig::for_budget`].
    fn default() -> Self {
        Self::for_budget(683, false)
    }
}

impl LinkQualityConfig {
    /// Settings for a side that may send `rate` bytes/s on the radio: the keep-alive period
    /// spends [`MONITOR_SHARE`] of it (0.5 s … 30 s), so a slow LoRa channel gets a report
    /// every ~9 s (13.5 s signed) and a 64 kbit/s SiK link one or two a second; the peer is
    /// quiet after 1.5 periods without a frame and missing after 2.5 periods plus 5 s.
    pub fn for_budget(rate_bytes_per_s: u32, signed: bool) -> Self {
        let bytes = if signed {
            REPORT_BYTES_SIGNED
        } else {
            REPORT_BYTES
        };
        let secs = f64::from(bytes) / (MONITOR_SHARE * f64::from(rate_bytes_per_s.max(1)));
        let period = Duration::from_secs_f64(secs.clamp(0.5, 30.0));
        Self {
            period,
            min_interval: Duration::from_millis(500),
            change: 0.1,
            window: Duration::from_secs(4).max(period * 2),
            quiet_after: (period * 3) / 2 + Duration::from_millis(500),
            peer_timeout: (period * 5) / 2 + Duration::from_secs(5),
            // Past the jitter of a SiK radio's noise readings (a few of its 0.5 dB units):
            // a change, not a reading's noise.
            noise_change_db: 4.0,
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
    /// Frames we sent (counted with [`LinkQuality::sent_frame`]) between the arrival of the
    /// last report that counted new frames and one second before this one's, while the peer
    /// received none since: a deaf peer when at least two.
    pub unheard: u32,
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

/// A frame sent this long before a report arrived may still have been in flight when the
/// peer made it: not counted against the report.
const IN_FLIGHT: Duration = Duration::from_secs(1);

/// The ids a SiK radio (and radios that follow it: RFD900, mLRS) writes its own
/// `RADIO_STATUS` with into its serial output: system `'3'`, component `'D'`
/// (`MAV_COMP_ID_TELEMETRY_RADIO`), unsigned.
pub const LOCAL_RADIO: StreamId = StreamId {
    system: b'3',
    component: b'D',
};

/// Whether a frame read from the radio's port is the local radio's own `RADIO_STATUS`: unsigned,
/// from [`LOCAL_RADIO`]. Any other `RADIO_STATUS` is a frame like the rest: it must be signed.
/// (One sent over the air with these ids comes out of the radio the same way: it can move the
/// rssi and noise the pilot sees, nothing else.)
pub fn is_local_radio_status<T: AsRef<[u8]>>(frame: &Frame<T>) -> bool {
    frame.message_id() == ids::RADIO_STATUS
        && !frame.is_signed()
        && frame.system_id() == LOCAL_RADIO.system
        && frame.component_id() == LOCAL_RADIO.component
}

/// Sans-IO link-quality engine for one radio link.
///
/// Feed it every frame the peer sent ([`handle_frame`](Self::handle_frame)), the local
/// radio's own reports ([`handle_local_radio`](Self::handle_local_radio)) and the
/// radio reader's counters after each read ([`observe`](Self::observe)); count what leaves
/// on the radio ([`sent_frame`](Self::sent_frame)); at [`poll_timeout`](Self::poll_timeout)
/// call [`handle_timeout`](Self::handle_timeout), then send what
/// [`poll_report`](Self::poll_report) returns.
#[derive(Debug)]
pub struct LinkQuality {
    config: LinkQualityConfig,
    started: Instant,
    last_report: Option<Instant>,
    /// Our loss estimate at our last report.
    reported_loss: f64,
    rssi: Option<i8>,
    remote_rssi: Option<i8>,
    local_radio: Option<RADIO_STATUS_DATA>,
    /// Our receiver's noise floor, dBm, from the local radio.
    noise: Option<i8>,
    /// The noise floor in our last report.
    reported_noise: Option<i8>,
    peer: Option<PeerReport>,
    /// The lowest noise floor the peer has reported: its receiver undisturbed.
    peer_noise_floor: Option<i8>,
    /// The peer's noise floor when its loss estimate last started afresh.
    peer_regime_noise: Option<i8>,
    /// The peer's uptime went back since [`take_peer_restart`](Self::take_peer_restart).
    peer_restarted: bool,
    /// The peer's counters, unwrapped, over the window.
    peer_window: LossWindow,
    peer_totals: (u64, u64),
    /// Our reader's counters over the window.
    own_window: LossWindow,
    /// Latest reader counters seen.
    stats: ReaderStats,
    /// When we last heard a frame from the peer.
    heard: Option<Instant>,
    /// A quiet spell was reported already.
    quiet_reported: bool,
    /// When our radio frames left, recent ones.
    sent: VecDeque<Instant>,
    /// When the last peer report that counted new frames of ours arrived.
    progress_at: Option<Instant>,
    /// When the early conditions were last looked at.
    checked_at: Option<Instant>,
    /// When the reader's counters last came in ([`observe`](Self::observe)).
    observed_at: Option<Instant>,
    /// Our report, made at its time and waiting for [`poll_report`](Self::poll_report).
    due: Option<LINK_QUALITY_DATA>,
}

impl LinkQuality {
    /// An engine started at `now`; the first report is due one period later.
    pub fn new(config: LinkQualityConfig, now: Instant) -> Self {
        Self {
            config,
            started: now,
            last_report: None,
            reported_loss: 0.0,
            rssi: None,
            remote_rssi: None,
            local_radio: None,
            noise: None,
            reported_noise: None,
            peer: None,
            peer_noise_floor: None,
            peer_regime_noise: None,
            peer_restarted: false,
            peer_window: LossWindow::new(config.window),
            peer_totals: (0, 0),
            own_window: LossWindow::new(config.window),
            stats: ReaderStats::default(),
            heard: None,
            quiet_reported: false,
            sent: VecDeque::new(),
            progress_at: None,
            checked_at: None,
            observed_at: None,
            due: None,
        }
    }

    /// The settings.
    pub fn config(&self) -> &LinkQualityConfig {
        &self.config
    }

    /// Sets signal strengths from a source other than `RADIO_STATUS` (e.g. a LoRa modem's
    /// packet RSSI), in dBm.
    pub fn set_rssi(&mut self, rssi: Option<i8>, remote_rssi: Option<i8>) {
        self.rssi = rssi;
        self.remote_rssi = remote_rssi;
    }

    /// Looks at a frame the peer sent (signature checked). Only its `LINK_QUALITY` is
    /// decoded; other frames are ignored by header.
    pub fn handle_frame<T: AsRef<[u8]>>(&mut self, now: Instant, frame: &Frame<T>) {
        self.heard(now);
        if frame.message_id() == ids::LINK_QUALITY
            && let Ok(MavMessage::LINK_QUALITY(report)) = frame.decode::<MavMessage>()
        {
            self.peer_report(report, now);
        }
    }

    /// The local radio's own `RADIO_STATUS` frame, injected into its serial output
    /// ([`is_local_radio_status`]): not the peer's, and not one of its frames either (the
    /// radio reader must not count it as received).
    pub fn handle_local_radio<T: AsRef<[u8]>>(&mut self, frame: &Frame<T>) {
        if let Ok(MavMessage::RADIO_STATUS(status)) = frame.decode::<MavMessage>() {
            self.handle_radio_status(status);
        }
    }

    /// The peer's report carried inside another frame (compact telemetry: the bridge's
    /// report rides in its `MAVLORA_COMPACT` frames), as if its `LINK_QUALITY` had arrived.
    pub fn handle_report(&mut self, now: Instant, report: LINK_QUALITY_DATA) {
        self.heard(now);
        self.peer_report(report, now);
    }

    /// A status report of the local radio: in the radio's byte stream (SiK injects
    /// `RADIO_STATUS` there, see [`handle_local_radio`](Self::handle_local_radio)) or read out of band
    /// (a modem's registers), with the scale of its `rssi`/`noise` bytes.
    /// Ignored when [`LinkQualityConfig::radio_status`] is `None`.
    pub fn handle_radio_status(&mut self, status: RADIO_STATUS_DATA) {
        let Some(scale) = self.config.radio_status else {
            return;
        };
        self.rssi = scale.to_dbm(status.rssi);
        self.remote_rssi = scale.to_dbm(status.remrssi);
        // 0 dBm of noise is no receiver's floor: the report's "unknown".
        self.noise = scale.to_dbm(status.noise).filter(|n| *n != 0);
        self.local_radio = Some(status);
    }

    fn heard(&mut self, now: Instant) {
        self.heard = Some(now);
        self.quiet_reported = false;
    }

    /// The radio reader's counters at `now` (call after each read): our loss estimate, and
    /// an early report when it moved.
    pub fn observe(&mut self, now: Instant, stats: &ReaderStats) {
        self.observed_at = Some(now);
        self.own_window.push(now, stats.frames(), stats.lost);
        self.stats = stats.clone();
    }

    /// One of our frames left on the radio at `now`.
    pub fn sent_frame(&mut self, now: Instant) {
        self.sent.push_back(now);
        let keep = self.config.peer_timeout + IN_FLIGHT;
        while self
            .sent
            .front()
            .is_some_and(|t| now.saturating_duration_since(*t) > keep)
        {
            self.sent.pop_front();
        }
    }

    fn peer_report(&mut self, report: LINK_QUALITY_DATA, now: Instant) {
        // Its uptime went back: the peer restarted. Its counters and its frames' numbering
        // start again, and the sequence jump its first frames made is not loss.
        let restarted = self
            .peer
            .as_ref()
            .is_some_and(|p| report.time_boot_ms < p.report.time_boot_ms);
        if restarted {
            debug!("peer restarted");
            self.peer_restarted = true;
            self.own_window = LossWindow::new(self.config.window);
        }
        let prev = self.peer.as_ref().filter(|_| !restarted);
        let deltas = prev.map(|p| {
            (
                report.rx_packets.wrapping_sub(p.report.rx_packets),
                report.rx_lost.wrapping_sub(p.report.rx_lost),
            )
        });
        // The peer's receiver changed: what was counted before describes another channel.
        let noise = (report.noise != 0).then_some(report.noise);
        if let Some(n) = noise {
            match self.peer_regime_noise {
                Some(r) if f64::from(n.abs_diff(r)) >= 2.0 * self.config.noise_change_db => {
                    // Neither the loss counted nor the frames unheard before the change
                    // speak for the channel after it.
                    self.peer_window = LossWindow::new(self.config.window);
                    self.progress_at = Some(now);
                    self.peer_regime_noise = Some(n);
                }
                Some(_) => {}
                None => self.peer_regime_noise = Some(n),
            }
        }
        if let Some(n) = noise {
            self.peer_noise_floor = Some(self.peer_noise_floor.map_or(n, |f| f.min(n)));
        }
        // It hears us again after hearing nothing: the sequence gap it counts now is the
        // outage (already announced as lost), not the channel it hears from here on. A
        // window holding it would say "degraded" for one more window after the link is
        // back; the loss is judged again from this report on.
        if prev.is_some_and(|p| p.unheard >= 2) && deltas.is_some_and(|(received, _)| received > 0)
        {
            self.peer_window = LossWindow::new(self.config.window);
        }
        let loss_ratio = deltas.and_then(|(received, lost)| {
            let total = u32::from(lost) + u32::from(received);
            (total > 0).then(|| f64::from(lost) / f64::from(total))
        });
        // Ours sent since the last report that counted progress, old enough to have
        // arrived: reports of "nothing new" add up (each alone may span less than the
        // in-flight allowance).
        let unheard = match deltas {
            Some((0, _)) => {
                let from = self.progress_at.unwrap_or(now);
                self.sent
                    .iter()
                    .filter(|t| **t >= from && **t + IN_FLIGHT <= now)
                    .count() as u32
            }
            _ => {
                self.progress_at = Some(now);
                0
            }
        };
        if let Some((received, lost)) = deltas {
            self.peer_totals.0 += u64::from(received);
            self.peer_totals.1 += u64::from(lost);
        }
        self.peer_window
            .push(now, self.peer_totals.0, self.peer_totals.1);
        debug!(
            ?loss_ratio,
            unheard,
            rx = report.rx_packets,
            "peer link-quality report"
        );
        self.peer = Some(PeerReport {
            report,
            received_at: now,
            loss_ratio,
            unheard,
        });
    }

    /// Frames the reader counted that came from the peer.
    /// Our loss estimate over the window, as of `now`.
    pub fn own_loss(&self, now: Instant) -> Option<f64> {
        self.own_window.estimate(now)
    }

    /// The peer's loss estimate (of our frames) over the window, as of `now`: 1 when its
    /// latest report says it received none of at least two frames we sent.
    pub fn peer_loss(&self, now: Instant) -> Option<f64> {
        let p = self.peer.as_ref()?;
        if p.unheard >= 2 {
            return Some(1.0);
        }
        self.peer_window.estimate(now)
    }

    /// How far the peer's receiver noise floor is above the lowest it has reported, dB, as of
    /// its latest report (while not missing); `None` when it does not report one.
    pub fn peer_noise_rise_db(&self, now: Instant) -> Option<f64> {
        let p = self.peer.as_ref()?;
        if now.saturating_duration_since(p.received_at) > self.config.peer_timeout {
            return None;
        }
        let noise = (p.report.noise != 0).then_some(p.report.noise)?;
        Some(f64::from(noise) - f64::from(self.peer_noise_floor?))
    }

    /// Our receiver's noise floor as the local radio last reported it, dBm.
    pub fn noise(&self) -> Option<i8> {
        self.noise
    }

    /// Whether the peer restarted (its report's uptime went back) since the last call: the
    /// caller's reader should take the next gap of each stream as new numbering
    /// ([`ReaderStats::expect_restart`](crate::wire::ReaderStats::expect_restart)).
    pub fn take_peer_restart(&mut self) -> bool {
        std::mem::take(&mut self.peer_restarted)
    }

    /// When we last heard the peer.
    pub fn last_heard(&self) -> Option<Instant> {
        self.heard
    }

    /// Whether nothing was heard from the peer for [`LinkQualityConfig::quiet_after`].
    pub fn peer_quiet(&self, now: Instant) -> bool {
        let since = self.heard.unwrap_or(self.started);
        now.saturating_duration_since(since) >= self.config.quiet_after
    }

    /// The local radio's latest `RADIO_STATUS`, if it sends one.
    pub fn local_radio(&self) -> Option<&RADIO_STATUS_DATA> {
        self.local_radio.as_ref()
    }

    /// Our RSSI and the remote RSSI our radio reports, dBm.
    pub fn rssi(&self) -> (Option<i8>, Option<i8>) {
        (self.rssi, self.remote_rssi)
    }

    /// The counters of the radio reader as last observed.
    pub fn reader_stats(&self) -> &ReaderStats {
        &self.stats
    }

    /// The first report goes out at once: a restarted end tells its peer so (its uptime went
    /// back) before its other frames' new numbering reads as loss there.
    fn keepalive_at(&self) -> Instant {
        self.last_report
            .map_or(self.started, |t| t + self.config.period)
    }

    fn early_ok_at(&self) -> Instant {
        self.last_report
            .map_or(self.started, |t| t + self.config.min_interval)
    }

    /// Why a report should go early at `now`, if it should.
    fn early(&self, now: Instant) -> Option<&'static str> {
        let quiet = self.heard.unwrap_or(self.started) + self.config.quiet_after;
        if !self.quiet_reported && self.heard.is_some() && now >= quiet {
            return Some("peer quiet");
        }
        if let (Some(n), Some(r)) = (self.noise, self.reported_noise)
            && f64::from(n.abs_diff(r)) >= self.config.noise_change_db
        {
            return Some("noise changed");
        }
        let loss = self.own_loss(now).unwrap_or(0.0);
        ((loss - self.reported_loss).abs() >= self.config.change).then_some("loss changed")
    }

    /// When the engine next wants [`handle_timeout`](Self::handle_timeout): the keep-alive,
    /// or the first moment an early condition can turn true (new counters came in, the
    /// peer goes quiet, a counted frame leaves the loss window, or one is true already),
    /// not before the shortest interval allows a report. An idle link wakes nobody: nothing
    /// here runs on a period of its own, so an idle program costs no CPU for it.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let Some(checked) = self.checked_at else {
            return Some(self.started);
        };
        let quiet = self
            .heard
            .filter(|_| !self.quiet_reported)
            .map(|heard| heard + self.config.quiet_after);
        let look = [
            self.observed_at.filter(|t| *t > checked),
            quiet,
            self.own_window.next_change(checked),
            self.early(checked).map(|_| checked),
        ]
        .into_iter()
        .flatten()
        .min();
        let keepalive = self.keepalive_at();
        Some(look.map_or(keepalive, |t| keepalive.min(t.max(self.early_ok_at()))))
    }

    /// Makes our report if one is due at `now` (the keep-alive, or early: our loss estimate
    /// moved, the peer went quiet), from the radio reader's counters (cumulative, truncated
    /// to 16 bits as the message defines); [`poll_report`](Self::poll_report) hands it out.
    pub fn handle_timeout(&mut self, now: Instant, stats: &ReaderStats) {
        self.observe(now, stats);
        self.checked_at = Some(now);
        let why = if now >= self.keepalive_at() {
            Some("period")
        } else if now >= self.early_ok_at() {
            self.early(now)
        } else {
            None
        };
        let Some(why) = why else {
            return;
        };
        if self.peer_quiet(now) && self.heard.is_some() {
            self.quiet_reported = true;
        }
        self.last_report = Some(now);
        self.reported_loss = self.own_loss(now).unwrap_or(0.0);
        self.reported_noise = self.noise;
        debug!(why, loss = self.reported_loss, noise = ?self.noise, "link-quality report");
        let unknown = |v: Option<i8>| v.unwrap_or(i8::MAX);
        self.due = Some(LINK_QUALITY_DATA {
            time_boot_ms: now.saturating_duration_since(self.started).as_millis() as u32,
            rx_packets: stats.frames() as u16,
            rx_lost: stats.lost as u16,
            rx_bad_crc: stats.bad_crc as u16,
            rssi: unknown(self.rssi),
            remote_rssi: unknown(self.remote_rssi),
            noise: self.noise.unwrap_or(0),
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
