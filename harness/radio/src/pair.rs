//! A radio: two directions of one preset, paired.
//!
//! The drone's radio is side A: the downlink (drone → ground) sends in TDM
//! slot A, the uplink (ground → drone) in slot B. Burst presets (LoRa, DMD) share one half-duplex channel: a direction
//! waits while the other is on air (ideal carrier sense, no collisions); when
//! both are ready at once, the one that started least recently goes first,
//! so a saturated direction cannot starve the other.

use timebase::Instant;

use super::error::ConfigError;
use super::link::{Event, Link, LinkConfig, Slot, min_opt};
use super::preset::Preset;

/// A direction through a [`Radio`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Ground → drone: the pilot's commands, mission uploads (TDM slot B).
    Uplink,
    /// Drone → ground: telemetry (TDM slot A).
    Downlink,
}

impl Direction {
    fn index(self) -> usize {
        match self {
            Direction::Downlink => 0,
            Direction::Uplink => 1,
        }
    }

    /// The other direction.
    pub fn reverse(self) -> Direction {
        match self {
            Direction::Uplink => Direction::Downlink,
            Direction::Downlink => Direction::Uplink,
        }
    }
}

/// Two [`Link`]s of one preset, scheduled together.
#[derive(Debug, Clone)]
pub struct Radio {
    links: [Link; 2],
    half_duplex: bool,
    /// Per-direction settings, [downlink, uplink], for [`Radio::rebuilt`].
    configs: [LinkConfig; 2],
}

impl Radio {
    /// A radio of `preset` with per-direction settings (asymmetric loss,
    /// seeds, duty rules).
    pub fn new(
        preset: &Preset,
        uplink: &LinkConfig,
        downlink: &LinkConfig,
    ) -> Result<Radio, ConfigError> {
        Radio::with_presets(preset, preset, uplink, downlink)
    }

    fn with_presets(
        downlink_preset: &Preset,
        uplink_preset: &Preset,
        uplink: &LinkConfig,
        downlink: &LinkConfig,
    ) -> Result<Radio, ConfigError> {
        Ok(Radio {
            links: [
                Link::new(downlink_preset, downlink, Slot::A)?,
                Link::new(uplink_preset, uplink, Slot::B)?,
            ],
            half_duplex: downlink_preset.half_duplex(),
            configs: [downlink.clone(), uplink.clone()],
        })
    }

    /// A fresh radio with the same per-direction settings and a preset per direction (a
    /// SiK radio whose air rate or power changed at a reboot). Counters, buffers, bytes in
    /// flight and silences added while running start afresh.
    pub fn rebuilt(&self, downlink: &Preset, uplink: &Preset) -> Result<Radio, ConfigError> {
        Radio::with_presets(downlink, uplink, &self.configs[1], &self.configs[0])
    }

    /// Side `from`'s serial port offers `bytes` at `now`.
    pub fn handle_input(&mut self, now: Instant, from: Direction, bytes: &[u8]) {
        self.advance(now);
        self.links[from.index()].accept(now, bytes);
        self.advance(now);
    }

    /// Runs everything due by `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        self.advance(now);
    }

    /// When the radio next needs [`Radio::handle_timeout`] or has output.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let event = self.next().map(|(_, t, _)| t);
        self.links
            .iter()
            .fold(event, |acc, l| min_opt(acc, l.next_delivery()))
    }

    /// Bytes of one packet that reached the far end of `direction` by the time of the last
    /// [`Radio::handle_input`] or [`Radio::handle_timeout`].
    pub fn poll_output(&mut self, direction: Direction) -> Option<Vec<u8>> {
        self.links[direction.index()].pop_delivery()
    }

    /// One direction, for its counters and duty share.
    pub fn link(&self, direction: Direction) -> &Link {
        &self.links[direction.index()]
    }

    /// One direction, to change its budget or trace it.
    pub fn link_mut(&mut self, direction: Direction) -> &mut Link {
        &mut self.links[direction.index()]
    }

    /// The channel is busy for direction `i` until the other's packet ends.
    fn busy_for(&self, i: usize) -> Instant {
        if self.half_duplex {
            self.links[1 - i].on_air_until().unwrap_or(Instant::ZERO)
        } else {
            Instant::ZERO
        }
    }

    /// The earliest event of either direction: ends before starts, then the
    /// direction that started least recently.
    fn next(&self) -> Option<(usize, Instant, Event)> {
        let rank = |i: usize, t: Instant, e: Event| {
            let starts = matches!(e, Event::TxStart(_));
            (t, starts, self.links[i].last_start(), i)
        };
        (0..2)
            .filter_map(|i| {
                self.links[i]
                    .next_event(self.busy_for(i))
                    .map(|(t, e)| (i, t, e))
            })
            .min_by_key(|&(i, t, e)| rank(i, t, e))
    }

    fn advance(&mut self, now: Instant) {
        while let Some((i, t, event)) = self.next() {
            if t > now {
                break;
            }
            // Time moves for both: the other must not start in the past
            // once this event frees the channel.
            for link in &mut self.links {
                link.set_now(t);
            }
            self.links[i].fire(t, event);
        }
        for link in &mut self.links {
            link.set_now(now);
        }
    }
}
