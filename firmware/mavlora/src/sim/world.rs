//! The simulated chain and its virtual clock.

use crate::time::Duration;
use std::collections::BTreeMap;

use super::gcs::GcsMock;
use super::link::{Link, LinkConfig};
use super::px4::{Px4Fc, StreamSpec};
use crate::bridge::{Bridge, BridgeConfig};
use crate::router::{Router, RouterConfig};
use crate::time::Instant;

/// How the flight controller reaches the ground station.
#[derive(Debug)]
pub enum Path {
    /// Flight controller – bridge – radio – router – ground station.
    Relay(Box<Bridge>, Box<Router>),
    /// Flight controller – radio – ground station: the naive relay (a plain radio).
    Direct,
}

/// A flight controller, a ground station and a radio between them, under a virtual clock.
#[derive(Debug)]
pub struct World {
    /// Current virtual time.
    pub now: Instant,
    /// The flight controller.
    pub fc: Px4Fc,
    /// The ground station.
    pub gcs: GcsMock,
    /// What sits between them.
    pub path: Path,
    /// Air → ground radio.
    pub up: Link,
    /// Ground → air radio.
    pub down: Link,
    /// Bytes sent air → ground, by message id.
    pub up_bytes_by_id: BTreeMap<u32, u64>,
}

impl World {
    /// A world with the bridge and router built from `bridge` and `router`.
    pub fn relay(
        bridge: BridgeConfig,
        router: RouterConfig,
        profile: &[StreamSpec],
        up: LinkConfig,
        down: LinkConfig,
        seed: u64,
    ) -> Self {
        let now = Instant::ZERO;
        let b = Bridge::new(bridge, now).expect("valid bridge config");
        let r = Router::new(router, now).expect("valid router config");
        Self::new(
            Path::Relay(Box::new(b), Box::new(r)),
            profile,
            up,
            down,
            seed,
        )
    }

    /// A world with a plain radio between flight controller and ground station.
    pub fn direct(profile: &[StreamSpec], up: LinkConfig, down: LinkConfig, seed: u64) -> Self {
        Self::new(Path::Direct, profile, up, down, seed)
    }

    fn new(
        path: Path,
        profile: &[StreamSpec],
        up: LinkConfig,
        down: LinkConfig,
        seed: u64,
    ) -> Self {
        let now = Instant::ZERO;
        Self {
            now,
            fc: Px4Fc::new(profile, now, seed),
            gcs: GcsMock::new(now),
            path,
            up: Link::new(up, seed ^ 0x5555),
            down: Link::new(down, seed ^ 0xAAAA),
            up_bytes_by_id: BTreeMap::new(),
        }
    }

    fn next_deadline(&self) -> Option<Instant> {
        let mut t = [
            self.fc.poll_timeout(),
            self.gcs.poll_timeout(),
            self.up.next_arrival(),
            self.down.next_arrival(),
        ]
        .into_iter()
        .flatten()
        .min();
        if let Path::Relay(b, r) = &self.path {
            for d in [b.poll_timeout(), r.poll_timeout()].into_iter().flatten() {
                t = Some(t.map_or(d, |t| t.min(d)));
            }
        }
        t
    }

    /// Advances to the earliest deadline (at least 1 µs, so a deadline that does not clear
    /// cannot stall the clock) and runs everything due.
    pub fn step(&mut self) {
        let next = self
            .next_deadline()
            .unwrap_or(self.now + Duration::from_millis(10));
        self.now = next.max(self.now + Duration::from_micros(1));
        let now = self.now;
        self.fc.handle_timeout(now);
        self.gcs.handle_timeout(now);
        match &mut self.path {
            Path::Relay(b, r) => {
                while let Some(f) = self.fc.poll_transmit() {
                    b.handle_fc_bytes(now, f.as_bytes());
                }
                while let Some(f) = self.down.receive(now) {
                    b.handle_radio_bytes(now, &f);
                }
                b.handle_timeout(now);
                while let Some(f) = b.poll_fc_transmit(now) {
                    self.fc.handle_bytes(now, f.as_bytes());
                }
                while let Some(f) = b.poll_radio_transmit(now, usize::MAX) {
                    *self.up_bytes_by_id.entry(f.message_id()).or_default() +=
                        f.as_bytes().len() as u64;
                    self.up.send(f.as_bytes(), now);
                }
                while let Some(f) = self.up.receive(now) {
                    r.handle_radio_bytes(now, &f);
                }
                while let Some(f) = self.gcs.poll_transmit() {
                    r.handle_gcs_bytes(now, f.as_bytes());
                }
                r.handle_timeout(now);
                while let Some(f) = r.poll_gcs_transmit() {
                    self.gcs.handle_bytes(now, f.as_bytes());
                }
                while let Some(f) = r.poll_radio_transmit(now, usize::MAX) {
                    self.down.send(f.as_bytes(), now);
                }
            }
            Path::Direct => {
                while let Some(f) = self.fc.poll_transmit() {
                    *self.up_bytes_by_id.entry(f.message_id()).or_default() +=
                        f.as_bytes().len() as u64;
                    self.up.send(f.as_bytes(), now);
                }
                while let Some(f) = self.up.receive(now) {
                    self.gcs.handle_bytes(now, &f);
                }
                while let Some(f) = self.gcs.poll_transmit() {
                    self.down.send(f.as_bytes(), now);
                }
                while let Some(f) = self.down.receive(now) {
                    self.fc.handle_bytes(now, &f);
                }
            }
        }
    }

    /// Steps until `until`.
    pub fn run_until(&mut self, until: Instant) {
        while self.now < until {
            self.step();
        }
    }

    /// Steps until `done` holds or `until` passes; whether `done` held.
    pub fn run_until_or(&mut self, until: Instant, mut done: impl FnMut(&Self) -> bool) -> bool {
        while self.now < until {
            if done(self) {
                return true;
            }
            self.step();
        }
        done(self)
    }
}
