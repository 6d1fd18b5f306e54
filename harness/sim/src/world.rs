//! The virtual-clock world: a simulated flight controller (any [`Autopilot`],
//! [`Px4Fc`] by default), optionally the real bridge and router engines
//! ([`Relay`]), the radio model ([`Radio`]) or an ideal wire between air and
//! ground ([`Carrier`]), and the simulated ground station ([`GcsMock`]). The
//! clock jumps to the earliest deadline of any part (after quinn-proto's test
//! pair), so a 513 s flight costs what its events cost, not 513 s; everything
//! random is seeded, so a run is the same for the same seed.
//!
//! Counting happens where the brief's questions are asked: frames (by
//! message id) and bytes handed to the carrier per [`Direction`]
//! ([`World::sent`]), and frames parsed out of what the carrier delivered on
//! the far side ([`World::received`]): what crossed the radio.

use std::collections::BTreeMap;

use harness_radio::{ConfigError, Direction, LinkStats, Radio, RadioSetup};
use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::dialect::RADIO_STATUS_DATA;
use mavlora::quality::RssiScale;
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::ScheduleError;
use mavlora::wire::FrameReader;
use mavlora::{Duration, Instant};

use crate::autopilot::{Autopilot, Px4Fc};
use crate::gcs::GcsMock;

/// Why a world could not be built.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// The radio setup is invalid.
    #[error("radio: {0}")]
    Radio(#[from] ConfigError),
    /// A bridge or router scheduler setting is invalid.
    #[error("MavLora engine: {0}")]
    Engine(#[from] ScheduleError),
}

/// What carries bytes between the air side and the ground side.
#[derive(Debug)]
pub enum Carrier {
    /// An ideal wire: no loss, no delay, no limit (the paper's "wired" run).
    Wire,
    /// The rig's radio model; side A is the drone.
    Radio(Box<Radio>),
}

/// What sits at each end of the carrier.
#[derive(Debug)]
pub enum Relay {
    /// MavLora: the bridge on the drone, the router on the ground.
    MavLora(Box<Bridge>, Box<Router>),
    /// Nothing: the flight controller's bytes go onto the carrier as they are, and the
    /// ground station's protocol reaches the flight controller unchanged (the naive link).
    Transparent,
}

/// Frames and bytes by message id.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Counts {
    /// Frames per message id.
    pub frames: BTreeMap<u32, u64>,
    /// Bytes (whole frames) per message id.
    pub bytes: BTreeMap<u32, u64>,
}

impl Counts {
    fn add(&mut self, id: u32, len: usize) {
        *self.frames.entry(id).or_default() += 1;
        *self.bytes.entry(id).or_default() += len as u64;
    }

    /// All frames.
    pub fn total_frames(&self) -> u64 {
        self.frames.values().sum()
    }

    /// All bytes.
    pub fn total_bytes(&self) -> u64 {
        self.bytes.values().sum()
    }

    /// Frames of the given ids.
    pub fn frames_of(&self, ids: &[u32]) -> u64 {
        ids.iter().filter_map(|id| self.frames.get(id)).sum()
    }

    /// Bytes of the given ids.
    pub fn bytes_of(&self, ids: &[u32]) -> u64 {
        ids.iter().filter_map(|id| self.bytes.get(id)).sum()
    }

    /// What was added since `earlier` (a snapshot of the same counter).
    pub fn since(&self, earlier: &Counts) -> Counts {
        let diff = |now: &BTreeMap<u32, u64>, then: &BTreeMap<u32, u64>| {
            now.iter()
                .map(|(id, n)| (*id, n - then.get(id).copied().unwrap_or(0)))
                .filter(|(_, n)| *n > 0)
                .collect()
        };
        Counts {
            frames: diff(&self.frames, &earlier.frames),
            bytes: diff(&self.bytes, &earlier.bytes),
        }
    }
}

/// Counting reader on the receiving end of one direction of the carrier.
#[derive(Debug, Default)]
struct Tap {
    reader: FrameReader,
    counts: Counts,
}

impl Tap {
    fn push(&mut self, bytes: &[u8]) {
        self.reader.push(bytes);
        while let Some(rx) = self.reader.next_frame() {
            self.counts
                .add(rx.frame.message_id(), rx.frame.as_bytes().len());
        }
    }
}

/// The virtual-clock world, with flight controller `A`.
#[derive(Debug)]
pub struct World<A: Autopilot = Px4Fc> {
    /// Virtual time.
    pub now: Instant,
    /// The flight controller.
    pub fc: A,
    /// The ground station.
    pub gcs: GcsMock,
    /// Bridge and router, or nothing.
    pub relay: Relay,
    /// Wire or radio.
    pub carrier: Carrier,
    /// Frames handed to the carrier on the drone's side (downlink, UAV → GCS).
    downlink_sent: Counts,
    /// Frames handed to the carrier on the ground's side (uplink, GCS → UAV).
    uplink_sent: Counts,
    downlink_rx: Tap,
    uplink_rx: Tap,
    steps: u64,
    /// When each end's radio next reports its status (radio carrier only).
    next_radio_status: Option<Instant>,
}

/// How often a radio reports its status to its host (SiK: once a second).
pub const RADIO_STATUS_PERIOD: Duration = Duration::from_secs(1);

/// What the radio at the receiving end of `rx` tells its host, as a SiK radio would: its
/// receiver's readings, the far receiver's, and its free buffer.
pub fn radio_status(radio: &Radio, rx: Direction) -> RADIO_STATUS_DATA {
    let (here, there) = (radio.link(rx), radio.link(rx.reverse()));
    let sik = |dbm: f64| RssiScale::Sik.from_dbm(Some(dbm.round().clamp(-128.0, 126.0) as i8));
    RADIO_STATUS_DATA {
        rssi: sik(here.receiver().rssi_dbm),
        remrssi: sik(there.receiver().rssi_dbm),
        noise: sik(here.receiver().noise_dbm),
        remnoise: sik(there.receiver().noise_dbm),
        txbuf: (100.0 * there.buffer_free_share()).round() as u8,
        rxerrors: 0,
        fixed: 0,
    }
}

impl<A: Autopilot> World<A> {
    /// A world with `fc`, a fresh ground station, the MavLora engines if `mavlora` is given
    /// (bridge and router configuration) and `radio` as the carrier (`None`: an ideal wire).
    pub fn new(
        fc: A,
        mavlora: Option<(BridgeConfig, RouterConfig)>,
        radio: Option<&RadioSetup>,
    ) -> Result<World<A>, WorldError> {
        let now = Instant::ZERO;
        let relay = match mavlora {
            Some((b, r)) => Relay::MavLora(
                Box::new(Bridge::new(b, now)?),
                Box::new(Router::new(r, now)?),
            ),
            None => Relay::Transparent,
        };
        let carrier = match radio {
            Some(setup) => Carrier::Radio(Box::new(setup.radio()?)),
            None => Carrier::Wire,
        };
        Ok(World {
            now,
            fc,
            gcs: GcsMock::new(now),
            relay,
            carrier,
            downlink_sent: Counts::default(),
            uplink_sent: Counts::default(),
            downlink_rx: Tap::default(),
            uplink_rx: Tap::default(),
            steps: 0,
            next_radio_status: radio.map(|_| now),
        })
    }

    /// Frames handed to the carrier in `direction` (by the bridge or the flight controller
    /// for the downlink, by the router or the ground station for the uplink).
    pub fn sent(&self, direction: Direction) -> &Counts {
        match direction {
            Direction::Downlink => &self.downlink_sent,
            Direction::Uplink => &self.uplink_sent,
        }
    }

    /// Frames parsed out of what the carrier delivered at the far end of `direction`.
    pub fn received(&self, direction: Direction) -> &Counts {
        match direction {
            Direction::Downlink => &self.downlink_rx.counts,
            Direction::Uplink => &self.uplink_rx.counts,
        }
    }

    /// The radio, if the carrier is one.
    pub fn radio(&self) -> Option<&Radio> {
        match &self.carrier {
            Carrier::Radio(r) => Some(r),
            Carrier::Wire => None,
        }
    }

    /// The radio's counters for one direction.
    pub fn link_stats(&self, direction: Direction) -> Option<LinkStats> {
        self.radio().map(|r| r.link(direction).stats().clone())
    }

    /// The bridge, if MavLora is in the path.
    pub fn bridge(&self) -> Option<&Bridge> {
        match &self.relay {
            Relay::MavLora(b, _) => Some(b),
            Relay::Transparent => None,
        }
    }

    /// The router, if MavLora is in the path.
    pub fn router(&self) -> Option<&Router> {
        match &self.relay {
            Relay::MavLora(_, r) => Some(r),
            Relay::Transparent => None,
        }
    }

    /// The bridge, to feed it directly (an attacker on the radio).
    pub fn bridge_mut(&mut self) -> Option<&mut Bridge> {
        match &mut self.relay {
            Relay::MavLora(b, _) => Some(b),
            Relay::Transparent => None,
        }
    }

    /// The router, to feed it directly (a flood on the ground side).
    pub fn router_mut(&mut self) -> Option<&mut Router> {
        match &mut self.relay {
            Relay::MavLora(_, r) => Some(r),
            Relay::Transparent => None,
        }
    }

    /// The radio, to change it while the world runs (a silence scheduled mid-flight).
    pub fn radio_mut(&mut self) -> Option<&mut Radio> {
        match &mut self.carrier {
            Carrier::Radio(r) => Some(r),
            Carrier::Wire => None,
        }
    }

    /// Steps taken so far (one per distinct deadline), for profiling.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    fn next_deadline(&self) -> Option<Instant> {
        let mut t = [self.fc.poll_timeout(), self.gcs.poll_timeout()]
            .into_iter()
            .flatten()
            .min();
        let mut fold = |d: Option<Instant>| {
            if let Some(d) = d {
                t = Some(t.map_or(d, |t| t.min(d)));
            }
        };
        if let Relay::MavLora(b, r) = &self.relay {
            fold(b.poll_timeout());
            fold(r.poll_timeout());
        }
        if let Carrier::Radio(radio) = &self.carrier {
            fold(radio.poll_timeout());
        }
        fold(self.next_radio_status);
        t
    }

    /// Advances to the earliest deadline (at least 1 µs on, so a deadline that does not
    /// clear cannot stall the clock) and runs everything due.
    pub fn step(&mut self) {
        let next = self
            .next_deadline()
            .unwrap_or(self.now + Duration::from_millis(10));
        self.now = next.max(self.now + Duration::from_micros(1));
        self.steps += 1;
        let now = self.now;
        self.fc.handle_timeout(now);
        self.gcs.handle_timeout(now);
        self.report_radio_status(now);

        // Air side: whatever the radio delivered up to now, then what leaves for the ground.
        let mut downlink: Vec<Vec<u8>> = Vec::new();
        let mut arrived = Vec::new();
        if let Carrier::Radio(radio) = &mut self.carrier {
            radio.handle_timeout(now);
            while let Some(bytes) = radio.poll_output(Direction::Uplink) {
                arrived.push(bytes);
            }
        }
        for bytes in &arrived {
            self.uplink_rx.push(bytes);
            self.air_input(now, bytes);
        }
        match &mut self.relay {
            Relay::MavLora(b, _) => {
                while let Some(f) = self.fc.poll_transmit() {
                    b.handle_fc_bytes(now, f.as_bytes());
                }
                b.handle_timeout(now);
                while let Some(f) = b.poll_fc_transmit(now) {
                    self.fc.handle_bytes(now, f.as_bytes());
                }
                while let Some(f) = b.poll_radio_transmit(now, usize::MAX) {
                    self.downlink_sent.add(f.message_id(), f.as_bytes().len());
                    downlink.push(f.into_inner());
                }
            }
            Relay::Transparent => {
                while let Some(f) = self.fc.poll_transmit() {
                    self.downlink_sent.add(f.message_id(), f.as_bytes().len());
                    downlink.push(f.into_inner());
                }
            }
        }

        // Across, on the downlink.
        match &mut self.carrier {
            Carrier::Wire => {
                for bytes in &downlink {
                    self.downlink_rx.push(bytes);
                    self.ground_input(now, bytes);
                }
            }
            Carrier::Radio(radio) => {
                for bytes in &downlink {
                    radio.handle_input(now, Direction::Downlink, bytes);
                }
                let mut delivered = Vec::new();
                while let Some(bytes) = radio.poll_output(Direction::Downlink) {
                    delivered.push(bytes);
                }
                for bytes in &delivered {
                    self.downlink_rx.push(bytes);
                    self.ground_input(now, bytes);
                }
            }
        }

        // Ground side.
        let mut uplink: Vec<Vec<u8>> = Vec::new();
        match &mut self.relay {
            Relay::MavLora(_, r) => {
                while let Some(f) = self.gcs.poll_transmit() {
                    r.handle_gcs_bytes(now, f.as_bytes());
                }
                r.handle_timeout(now);
                while let Some(f) = r.poll_gcs_transmit() {
                    self.gcs.handle_bytes(now, f.as_bytes());
                }
                while let Some(f) = r.poll_radio_transmit(now, usize::MAX) {
                    self.uplink_sent.add(f.message_id(), f.as_bytes().len());
                    uplink.push(f.into_inner());
                }
            }
            Relay::Transparent => {
                while let Some(f) = self.gcs.poll_transmit() {
                    self.uplink_sent.add(f.message_id(), f.as_bytes().len());
                    uplink.push(f.into_inner());
                }
            }
        }

        // Across, on the uplink.
        match &mut self.carrier {
            Carrier::Wire => {
                for bytes in &uplink {
                    self.uplink_rx.push(bytes);
                    self.air_input(now, bytes);
                }
            }
            Carrier::Radio(radio) => {
                for bytes in &uplink {
                    radio.handle_input(now, Direction::Uplink, bytes);
                }
            }
        }
    }

    /// Whether each end's radio reports its status to its host once a
    /// [`RADIO_STATUS_PERIOD`] (on with a radio carrier, as SiK radios do); off plays a
    /// radio that reports nothing, so loss must be counted from frames.
    pub fn set_radio_status(&mut self, on: bool) {
        let radio = matches!(self.carrier, Carrier::Radio(_));
        self.next_radio_status = (on && radio).then_some(self.now);
    }

    /// Each end's radio reports its status when due (out of band: the sim has no serial
    /// stream to inject it into).
    fn report_radio_status(&mut self, now: Instant) {
        let (Some(due), Carrier::Radio(radio)) = (self.next_radio_status, &self.carrier) else {
            return;
        };
        if now < due {
            return;
        }
        self.next_radio_status = Some(due + RADIO_STATUS_PERIOD);
        if let Relay::MavLora(b, r) = &mut self.relay {
            b.handle_radio_status(radio_status(radio, Direction::Uplink));
            r.handle_radio_status(radio_status(radio, Direction::Downlink));
        }
    }

    fn air_input(&mut self, now: Instant, bytes: &[u8]) {
        match &mut self.relay {
            Relay::MavLora(b, _) => b.handle_radio_bytes(now, bytes),
            Relay::Transparent => self.fc.handle_bytes(now, bytes),
        }
    }

    fn ground_input(&mut self, now: Instant, bytes: &[u8]) {
        match &mut self.relay {
            Relay::MavLora(_, r) => r.handle_radio_bytes(now, bytes),
            Relay::Transparent => self.gcs.handle_bytes(now, bytes),
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

/// `s` seconds after the epoch.
pub fn secs(s: f64) -> Instant {
    Instant::from_micros((s * 1e6).round() as u64)
}
