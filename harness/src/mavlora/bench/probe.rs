//! The sweep's sender and receiver, as in the paper's Fig. 1: numbered HEARTBEATs written
//! into the drone's radio at a fixed rate, read at the ground's, and whatever the ground's
//! radio says of the link (SiK's own `RADIO_STATUS`, when its MAVLink framing is on).
//!
//! Each HEARTBEAT carries its step and number in `custom_mode` (step << 16 | number), so a
//! frame still in flight from one step is never counted in the next.

use std::collections::BTreeSet;
use std::io::Read as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant as WallInstant};

use anyhow::{Context, Result};
use serialport::SerialPort;

use mavlink::{MavHeader, MavlinkVersion};
use mavlora::dialect::{HEARTBEAT_DATA, MavMessage};
use mavlora::wire::{FrameReader, encode, ids};

/// The system id the probe sends as: a ground-test sender no autopilot uses.
const PROBE_SYSTEM: u8 = 42;
/// The ground station's system id (what ground stations use).
const GROUND_SYSTEM: u8 = 255;
/// How often the ground station says it is there.
const GROUND_HEARTBEAT: Duration = Duration::from_secs(1);
/// SiK's own `RADIO_STATUS`: system `'3'`, component `'D'`.
const SIK_SYSTEM: u8 = b'3';

/// What the ground's radio reported of the link during a step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RadioReport {
    /// Reports received.
    pub reports: u32,
    /// Mean of the local (ground) radio's `rssi`, SiK units.
    pub rssi: f64,
    /// Mean of the remote (drone) radio's `remrssi`.
    pub remrssi: f64,
    /// Mean `noise`.
    pub noise: f64,
    /// Least `txbuf` seen, %.
    pub min_txbuf: u8,
}

#[derive(Default)]
struct Heard {
    /// (step, number) of each HEARTBEAT received.
    heartbeats: BTreeSet<(u16, u16)>,
    /// Arrival times of HEARTBEATs per step, for the period.
    arrivals: Vec<(u16, WallInstant)>,
    /// `RADIO_STATUS` (rssi, remrssi, noise, txbuf) by arrival.
    status: Vec<(WallInstant, [u8; 4])>,
    /// Bytes read that were not part of a frame.
    garbage: u64,
}

/// A running receiver on the ground radio's port and the sender on the drone's.
pub struct Probe {
    air: Box<dyn SerialPort>,
    /// The ground's port again, for the ground station's HEARTBEAT: SiK reports
    /// `RADIO_STATUS` to its host after each HEARTBEAT the host sends, as a ground station
    /// does once a second.
    ground: Box<dyn SerialPort>,
    ground_name: String,
    air_name: String,
    sequence: u8,
    heard: Arc<Mutex<Heard>>,
    stop: Arc<AtomicBool>,
    reader: Option<JoinHandle<Result<()>>>,
    /// Reads and drops what the drone's radio hands its host (the ground's HEARTBEATs, its
    /// own `RADIO_STATUS`), so a full port never stalls the radio.
    air_drain: Option<JoinHandle<()>>,
}

impl Probe {
    /// Opens both ports at `baud` and starts reading the ground's.
    pub fn open(air: &str, ground: &str, baud: u32) -> Result<Probe> {
        let open = |path: &str, role: &str| {
            serialport::new(path, baud)
                .timeout(Duration::from_millis(20))
                .open()
                .with_context(|| {
                    format!("cannot open the {role} radio's port {path} at {baud} baud")
                })
        };
        let air_port = open(air, "drone")?;
        let mut air_reader = air_port
            .try_clone()
            .with_context(|| format!("cannot share the drone radio's port {air}"))?;
        let mut ground_port = open(ground, "ground")?;
        let ground_writer = ground_port
            .try_clone()
            .with_context(|| format!("cannot share the ground radio's port {ground}"))?;
        let heard = Arc::new(Mutex::new(Heard::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let reader = {
            let (heard, stop, ground) = (heard.clone(), stop.clone(), ground.to_string());
            std::thread::Builder::new()
                .name("bench-probe-rx".into())
                .spawn(move || read_ground(&mut *ground_port, &ground, &heard, &stop))
                .context("cannot start the probe's reader")?
        };
        let air_drain = {
            let stop = stop.clone();
            std::thread::Builder::new()
                .name("bench-probe-air".into())
                .spawn(move || {
                    let mut buf = [0u8; 512];
                    while !stop.load(Ordering::Relaxed) {
                        if let Err(e) = air_reader.read(&mut buf)
                            && e.kind() != std::io::ErrorKind::TimedOut
                            && e.kind() != std::io::ErrorKind::Interrupted
                        {
                            return;
                        }
                    }
                })
                .context("cannot start the probe's drain")?
        };
        Ok(Probe {
            air: air_port,
            air_drain: Some(air_drain),
            ground: ground_writer,
            ground_name: ground.to_string(),
            air_name: air.to_string(),
            sequence: 0,
            heard,
            stop,
            reader: Some(reader),
        })
    }

    /// Sends `messages` HEARTBEATs numbered for `step` at `hz` into the drone's radio, then
    /// waits `drain` for the last to land; returns (received, mean period ms, radio report).
    pub fn step(
        &mut self,
        step: u16,
        messages: u32,
        hz: f64,
        drain: Duration,
    ) -> Result<StepCount> {
        let start = WallInstant::now();
        let period = Duration::from_secs_f64(1.0 / hz);
        let mut next_ground_heartbeat = start;
        for n in 0..messages {
            if WallInstant::now() >= next_ground_heartbeat {
                self.ground_heartbeat()?;
                next_ground_heartbeat += GROUND_HEARTBEAT;
            }
            let due = start + period * n;
            if let Some(wait) = due.checked_duration_since(WallInstant::now()) {
                std::thread::sleep(wait);
            }
            let frame = encode(
                MavlinkVersion::V2,
                MavHeader {
                    system_id: u32::from(PROBE_SYSTEM),
                    component_id: 1,
                    sequence: self.sequence,
                },
                &MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                    custom_mode: (u32::from(step) << 16) | n,
                    mavlink_version: 3,
                    ..HEARTBEAT_DATA::default()
                }),
            );
            self.sequence = self.sequence.wrapping_add(1);
            std::io::Write::write_all(&mut self.air, frame.as_bytes())
                .with_context(|| format!("writing to the drone's radio on {}", self.air_name))?;
        }
        let sent_until = WallInstant::now();
        std::thread::sleep(drain);
        self.check_reader()?;
        let heard = self.heard.lock().unwrap_or_else(PoisonError::into_inner);
        let received = heard.heartbeats.range((step, 0)..=(step, u16::MAX)).count() as u64;
        let times: Vec<WallInstant> = heard
            .arrivals
            .iter()
            .filter(|(s, _)| *s == step)
            .map(|(_, t)| *t)
            .collect();
        let gaps: Vec<f64> = times
            .windows(2)
            .map(|p| (p[1] - p[0]).as_secs_f64() * 1000.0)
            .collect();
        let mean_period_ms = if gaps.is_empty() {
            f64::NAN
        } else {
            gaps.iter().sum::<f64>() / gaps.len() as f64
        };
        let status: Vec<[u8; 4]> = heard
            .status
            .iter()
            .filter(|(t, _)| *t >= start && *t <= sent_until + drain)
            .map(|(_, s)| *s)
            .collect();
        let mean = |i: usize| {
            status.iter().map(|s| f64::from(s[i])).sum::<f64>() / status.len().max(1) as f64
        };
        let radio = RadioReport {
            reports: status.len() as u32,
            rssi: mean(0),
            remrssi: mean(1),
            noise: mean(2),
            min_txbuf: status.iter().map(|s| s[3]).min().unwrap_or(0),
        };
        Ok(StepCount {
            sent: u64::from(messages),
            received,
            mean_period_ms,
            radio,
        })
    }

    fn ground_heartbeat(&mut self) -> Result<()> {
        let frame = encode(
            MavlinkVersion::V2,
            MavHeader {
                system_id: u32::from(GROUND_SYSTEM),
                component_id: 190,
                sequence: self.sequence,
            },
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                mavtype: mavlora::dialect::MavType::MAV_TYPE_GCS,
                mavlink_version: 3,
                ..HEARTBEAT_DATA::default()
            }),
        );
        std::io::Write::write_all(&mut self.ground, frame.as_bytes())
            .with_context(|| format!("writing to the ground radio on {}", self.ground_name))
    }

    /// Bytes read at the ground that were not part of a frame, so far.
    pub fn garbage(&self) -> u64 {
        self.heard
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .garbage
    }

    /// The reader's own error, if it stopped.
    fn check_reader(&mut self) -> Result<()> {
        if self.reader.as_ref().is_some_and(JoinHandle::is_finished)
            && let Some(reader) = self.reader.take()
        {
            return match reader.join() {
                Ok(Ok(())) => anyhow::bail!("the ground radio's reader stopped"),
                Ok(Err(e)) => Err(e),
                Err(_) => anyhow::bail!("the ground radio's reader panicked"),
            };
        }
        Ok(())
    }
}

impl Drop for Probe {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
        if let Some(d) = self.air_drain.take() {
            let _ = d.join();
        }
    }
}

/// One step's counts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepCount {
    pub sent: u64,
    pub received: u64,
    pub mean_period_ms: f64,
    pub radio: RadioReport,
}

fn read_ground(
    port: &mut dyn SerialPort,
    name: &str,
    heard: &Mutex<Heard>,
    stop: &AtomicBool,
) -> Result<()> {
    let mut reader = FrameReader::new();
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::Relaxed) {
        let n = match port.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => 0,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => 0,
            Err(e) => {
                return Err(e).with_context(|| format!("reading the ground radio's port {name}"));
            }
        };
        if n == 0 {
            continue;
        }
        let now = WallInstant::now();
        reader.push(&buf[..n]);
        let mut h = heard.lock().unwrap_or_else(PoisonError::into_inner);
        while let Some(received) = reader.next_frame() {
            let frame = received.frame;
            match (frame.message_id(), frame.system_id()) {
                (ids::HEARTBEAT, PROBE_SYSTEM) => {
                    if let Ok(MavMessage::HEARTBEAT(hb)) = frame.decode::<MavMessage>() {
                        let key = ((hb.custom_mode >> 16) as u16, hb.custom_mode as u16);
                        if h.heartbeats.insert(key) {
                            h.arrivals.push((key.0, now));
                        }
                    }
                }
                (ids::RADIO_STATUS, SIK_SYSTEM) => {
                    if let Ok(MavMessage::RADIO_STATUS(s)) = frame.decode::<MavMessage>() {
                        h.status.push((now, [s.rssi, s.remrssi, s.noise, s.txbuf]));
                    }
                }
                _ => {}
            }
        }
        h.garbage = reader.stats().garbage_bytes;
    }
    Ok(())
}
