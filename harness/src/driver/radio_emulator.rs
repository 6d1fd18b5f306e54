//! The radio emulator: a [`Radio`] between two pty pairs, on the real clock
//! ([`RadioEmulator::new`], CI), or between two serial devices on a bench
//! ([`RadioEmulator::between`]: two USB-serial adapters, each null-modem wired
//! to the bridge's or the router's radio port, in place of the radios).
//!
//! The drone's program (the bridge) opens [`RadioEmulator::air_path`], the
//! ground's (the router) [`RadioEmulator::ground_path`]; bytes written on one
//! side come out on the other
//! as the model decides (airtime, loss, buffer drops, duty cycle). One thread
//! runs the small loop the sans-IO contract asks for: read what is
//! available → `handle_input(now)`, `handle_timeout(now)`, write what
//! `poll_output()` hands over, sleep until the next deadline. A pty has no
//! "readable" wake-up here, so input is polled every [`POLL`]: a byte's
//! arrival time is known to within that, on top of host scheduling.
//!
//! By default each side is a plain wire into the model. [`RadioEmulator::with_sik`] puts SiK
//! firmware on either side instead ([`SikPersonality`]): that side answers the AT command
//! set, keeps its registers, injects `RADIO_STATUS` when its `MAVLINK` register says so, and
//! its air rate, ECC, power and network id reach the model (see [`harness_radio::sik`]). A
//! reboot that changes a preset rebuilds the model: its counters start again from there.

use std::io::{Read, Write};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result};
use serialport::{SerialPort, TTYPort};

use crate::clock::Mono;
use crate::driver::pty::{PtyPair, relink};
use harness_radio::sik::{self, Board, Params, SikPair, SikRadio};
use harness_radio::{Direction, LinkStats, Radio, Silence};
use timebase::Instant;

/// Longest the loop sleeps without looking for input.
pub const POLL: Duration = Duration::from_millis(1);

struct Shared {
    radio: Mutex<Radio>,
    /// SiK firmware on the sides, if any side has it; locked after `radio`.
    sik: Option<Mutex<SikPair>>,
    stop: AtomicBool,
    /// Master ends for the worker to take up (a replugged side) or `None` to let go of
    /// (an unplugged side), by side: 0 air, 1 ground.
    swaps: Mutex<Vec<(usize, Option<TTYPort>)>>,
    /// Swaps the worker has applied.
    swapped: AtomicU64,
    /// Delivered bytes the far port would not take (nobody reading).
    unwritten: AtomicU64,
    epoch: Mono,
}

/// A running emulated radio between two pty paths.
pub struct RadioEmulator {
    /// Air side, ground side; a replug replaces one.
    sides: Mutex<[Side; 2]>,
    /// The stable names (symlinks) the programs open, when made: [air, ground].
    links: Option<[String; 2]>,
    /// Swaps handed to the worker.
    swaps_sent: AtomicU64,
    shared: Arc<Shared>,
    worker: Option<JoinHandle<()>>,
}

/// One end of the radio, for [`RadioEmulator::replug`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    /// The drone's radio, the bridge's port.
    Air,
    /// The ground's radio, the router's port.
    Ground,
}

impl End {
    fn index(self) -> usize {
        match self {
            End::Air => 0,
            End::Ground => 1,
        }
    }
}

/// SiK firmware for one side of [`RadioEmulator::with_sik`]: the board, the registers
/// saved on it, and the escape's guard time (SiK's 1 s unless a test wants it short).
#[derive(Debug, Clone)]
pub struct SikPersonality {
    /// Banner, power levels, band.
    pub board: Board,
    /// Registers saved on the radio; `None` for the factory defaults.
    pub eeprom: Option<Params>,
    /// Quiet time the `+++` escape needs before and after.
    pub guard: Duration,
}

impl Default for SikPersonality {
    fn default() -> Self {
        SikPersonality {
            board: Board::hm_trp_915(),
            eeprom: None,
            guard: Duration::from_micros(sik::command::GUARD.as_micros()),
        }
    }
}

impl SikPersonality {
    /// With a guard time of `guard`.
    pub fn guard(mut self, guard: Duration) -> Self {
        self.guard = guard;
        self
    }

    /// With `eeprom` saved on the radio instead of the factory defaults.
    pub fn eeprom(mut self, eeprom: Params) -> Self {
        self.eeprom = Some(eeprom);
        self
    }

    fn boot(&self) -> SikRadio {
        let guard = timebase::Duration::from_micros(self.guard.as_micros() as u64);
        let eeprom = self.eeprom.unwrap_or_else(|| Params::defaults(&self.board));
        SikRadio::with_eeprom(self.board.clone(), eeprom, guard, Instant::ZERO)
    }
}

/// Where one side's program connects.
enum Side {
    /// The program opens this pair's far end.
    Pty(PtyPair),
    /// The program is wired to this device.
    Device(String),
}

impl Side {
    fn path(&self) -> &str {
        match self {
            Side::Pty(p) => p.path(),
            Side::Device(d) => d,
        }
    }
}

impl RadioEmulator {
    /// Starts `radio` between two new pty pairs; `name` labels the thread and logs.
    pub fn new(name: &str, radio: Radio) -> Result<RadioEmulator> {
        let mut a = PtyPair::new()?;
        let mut b = PtyPair::new()?;
        let a_master = a.take_master()?;
        let b_master = b.take_master()?;
        Self::start(
            name,
            radio,
            None,
            Side::Pty(a),
            Side::Pty(b),
            a_master,
            b_master,
        )
    }

    /// As [`RadioEmulator::new`], with SiK firmware on the air side, the ground side or
    /// both (a side given `None` stays a plain wire).
    pub fn with_sik(
        name: &str,
        radio: Radio,
        air: Option<SikPersonality>,
        ground: Option<SikPersonality>,
    ) -> Result<RadioEmulator> {
        let base = radio.link(Direction::Uplink).preset().clone();
        let pair = SikPair::new(
            &base,
            air.as_ref().map(SikPersonality::boot),
            ground.as_ref().map(SikPersonality::boot),
        );
        let mut a = PtyPair::new()?;
        let mut b = PtyPair::new()?;
        let a_master = a.take_master()?;
        let b_master = b.take_master()?;
        Self::start(
            name,
            radio,
            Some(pair),
            Side::Pty(a),
            Side::Pty(b),
            a_master,
            b_master,
        )
    }

    /// The SiK radio on `end` as it is now (registers, settings), if it has one.
    pub fn sik_radio(&self, end: End) -> Option<SikRadio> {
        let pair = self.shared.sik.as_ref()?;
        let pair = pair.lock().unwrap_or_else(PoisonError::into_inner);
        pair.radio(sik_end(end)).cloned()
    }

    /// As [`RadioEmulator::new`], with stable names for the programs to open: symlinks
    /// `<dir>/radio-air` and `<dir>/radio-ground` to the ptys (what `/dev/serial/by-id` is
    /// to a USB radio), so a side can be unplugged and plugged in again
    /// ([`RadioEmulator::replug`]) as a new pty under the same name.
    pub fn with_stable_names(name: &str, radio: Radio, dir: &Path) -> Result<RadioEmulator> {
        let mut emulator = Self::new(name, radio)?;
        let links = [dir.join("radio-air"), dir.join("radio-ground")];
        let sides = emulator
            .sides
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner);
        for (link, side) in links.iter().zip(sides.iter()) {
            relink(link, side.path())?;
        }
        emulator.links = Some(links.map(|l| l.display().to_string()));
        Ok(emulator)
    }

    /// Starts `radio` between two serial devices at `baud` (8N1): `air_device` is
    /// wired to the drone's radio port, `ground_device` to the ground's.
    pub fn between(
        name: &str,
        radio: Radio,
        air_device: &str,
        ground_device: &str,
        baud: u32,
    ) -> Result<RadioEmulator> {
        let open = |path: &str| {
            serialport::new(path, baud).open_native().with_context(|| {
                format!("radio emulator {name}: cannot open {path} at {baud} baud")
            })
        };
        let a_port = open(air_device)?;
        let b_port = open(ground_device)?;
        Self::start(
            name,
            radio,
            None,
            Side::Device(air_device.to_string()),
            Side::Device(ground_device.to_string()),
            a_port,
            b_port,
        )
    }

    fn start(
        name: &str,
        radio: Radio,
        sik: Option<SikPair>,
        a: Side,
        b: Side,
        mut a_master: TTYPort,
        mut b_master: TTYPort,
    ) -> Result<RadioEmulator> {
        for port in [&mut a_master, &mut b_master] {
            // A reader that stopped must not stall the radio for long.
            port.set_timeout(Duration::from_millis(20))?;
        }
        let shared = Arc::new(Shared {
            radio: Mutex::new(radio),
            sik: sik.map(Mutex::new),
            stop: AtomicBool::new(false),
            swaps: Mutex::new(Vec::new()),
            swapped: AtomicU64::new(0),
            unwritten: AtomicU64::new(0),
            epoch: Mono::now(),
        });
        let state = shared.clone();
        let label = name.to_string();
        let worker = std::thread::Builder::new()
            .name(format!("radio-{name}"))
            .spawn(move || run(&label, &state, [Some(a_master), Some(b_master)]))
            .context("cannot start the radio emulator thread")?;
        Ok(RadioEmulator {
            sides: Mutex::new([a, b]),
            links: None,
            swaps_sent: AtomicU64::new(0),
            shared,
            worker: Some(worker),
        })
    }

    /// The serial port the drone's program opens (its stable name, else a pty), or is
    /// wired to (a device).
    pub fn air_path(&self) -> String {
        self.path(End::Air)
    }

    /// As [`RadioEmulator::air_path`], for the ground's program.
    pub fn ground_path(&self) -> String {
        self.path(End::Ground)
    }

    fn path(&self, end: End) -> String {
        match &self.links {
            Some(links) => links[end.index()].clone(),
            None => self.sides.lock().unwrap_or_else(PoisonError::into_inner)[end.index()]
                .path()
                .to_string(),
        }
    }

    /// Unplugs one side's radio (its pty goes away: the program's port hangs up and its
    /// stable name leads nowhere), waits `down`, and plugs a new one in under the same
    /// name: a USB radio pulled and put back. What the far radio delivers meanwhile is lost
    /// (counted in [`RadioEmulator::unwritten`]). Returns when the new one was plugged in.
    /// Needs [`RadioEmulator::with_stable_names`].
    pub fn replug(&self, end: End, down: Duration) -> Result<Mono> {
        let links = self.links.as_ref().context(
            "this radio emulator has no stable names to replug under (with_stable_names)",
        )?;
        let link = Path::new(&links[end.index()]);
        let _ = std::fs::remove_file(link);
        self.swap(end, None);
        // The old pair (its slave) goes with the worker's master: the node is gone.
        let old = std::mem::replace(
            &mut self.sides.lock().unwrap_or_else(PoisonError::into_inner)[end.index()],
            Side::Device(String::new()),
        );
        drop(old);
        std::thread::sleep(down);
        let mut pair = PtyPair::new()?;
        let master = pair.take_master()?;
        relink(link, pair.path())?;
        self.sides.lock().unwrap_or_else(PoisonError::into_inner)[end.index()] = Side::Pty(pair);
        self.swap(end, Some(master));
        Ok(Mono::now())
    }

    /// Hands the worker a new master for `end` (or none) and waits until it took it.
    fn swap(&self, end: End, master: Option<TTYPort>) {
        let n = self.swaps_sent.fetch_add(1, Ordering::SeqCst) + 1;
        self.shared
            .swaps
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push((end.index(), master));
        while self.shared.swapped.load(Ordering::SeqCst) < n && self.worker.is_some() {
            std::thread::sleep(POLL);
        }
    }

    /// The model's time zero on the rig's clock: scheduled silences count from it.
    pub fn epoch(&self) -> Mono {
        self.shared.epoch
    }

    /// The model's time now: the emulator's epoch is its start.
    pub fn now(&self) -> Instant {
        model_time(self.shared.epoch)
    }

    /// Silences the air both ways from now for `length` (a hill, a hangar, a radio that
    /// browned out); returns when it began on the rig's clock.
    pub fn silence_now(&self, length: Duration) -> Result<Mono> {
        let mut radio = self.radio();
        let at = Mono::now();
        let silence = Silence {
            at_s: at.since(self.shared.epoch).as_secs_f64(),
            for_s: length.as_secs_f64(),
            every_s: None,
        };
        for direction in [Direction::Downlink, Direction::Uplink] {
            radio
                .link_mut(direction)
                .add_silence(silence)
                .context("radio emulator: cannot schedule the silence")?;
        }
        Ok(at)
    }

    /// Sets the path attenuation of both directions to `db` (a step attenuator between the
    /// two radios' antenna ports: it attenuates both ways alike). Other budget terms stay.
    pub fn set_attenuation(&self, db: f64) -> Result<()> {
        let mut radio = self
            .shared
            .radio
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        for direction in [Direction::Uplink, Direction::Downlink] {
            let link = radio.link_mut(direction);
            let budget = harness_radio::LinkBudget {
                path: harness_radio::PathLoss::AttenuationDb(db),
                ..*link.budget()
            };
            link.set_budget(budget)
                .with_context(|| format!("attenuation {db} dB refused by the radio model"))?;
        }
        Ok(())
    }

    /// Counters of one direction so far.
    pub fn stats(&self, direction: Direction) -> LinkStats {
        self.radio().link(direction).stats().clone()
    }

    /// Airtime share of one direction over its duty-cycle window, now.
    pub fn duty_share(&self, direction: Direction) -> f64 {
        let now = self.now();
        self.radio().link(direction).duty().share(now)
    }

    /// Delivered bytes that no reader took (the far port was not being read).
    pub fn unwritten(&self) -> u64 {
        self.shared.unwritten.load(Ordering::Relaxed)
    }

    /// Stops the thread and returns the radio, with all its counters.
    pub fn finish(mut self) -> Radio {
        self.halt();
        self.radio().clone()
    }

    fn radio(&self) -> MutexGuard<'_, Radio> {
        // A panicked worker leaves the model as it was; its counters still count.
        self.shared
            .radio
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn halt(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(worker) = self.worker.take() {
            let _ = worker.join();
        }
    }
}

impl Drop for RadioEmulator {
    fn drop(&mut self) {
        self.halt();
        // The stable names lead to ptys that die with us: a dangling link left in the
        // phase's folder is no evidence, and `rig certify` could not seal the folder.
        for link in self.links.iter().flatten() {
            let _ = std::fs::remove_file(link);
        }
    }
}

fn run(name: &str, shared: &Shared, mut ports: [Option<TTYPort>; 2]) {
    // Airtime is the point of this thread: ask for the CPU when it is due.
    hostio::realtime::request("radio-emulator");
    let mut buf = vec![0u8; 4096];
    while !shared.stop.load(Ordering::Relaxed) {
        for (side, master) in shared
            .swaps
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .drain(..)
        {
            // The old master closes here: the program on that side sees its port hang up.
            ports[side] = master;
            shared.swapped.fetch_add(1, Ordering::SeqCst);
        }
        let [a, b] = &mut ports;
        let next = {
            let mut radio = shared
                .radio
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner());
            let mut sik = shared
                .sik
                .as_ref()
                .map(|s| s.lock().unwrap_or_else(PoisonError::into_inner));
            let now = model_time(shared.epoch);
            for (port, from) in [(&mut *a, Direction::Downlink), (&mut *b, Direction::Uplink)] {
                // An unplugged side sends nothing.
                let Some(port) = port else { continue };
                match read_available(port, &mut buf) {
                    Ok(0) => {}
                    Ok(n) => match &mut sik {
                        None => radio.handle_input(now, from, &buf[..n]),
                        Some(sik) => {
                            let end = sik_end_sending(from);
                            let air = sik.handle_host_input(now, end, &buf[..n], &radio);
                            radio.handle_input(now, from, &air);
                        }
                    },
                    Err(e) => {
                        tracing::debug!(radio = name, error = %e, "radio emulator port closed");
                        return;
                    }
                }
            }
            radio.handle_timeout(now);
            if let Some(sik) = &mut sik {
                sik.handle_timeout(now, &radio);
            }
            for (port, to) in [(&mut *b, Direction::Downlink), (&mut *a, Direction::Uplink)] {
                while let Some(bytes) = radio.poll_output(to) {
                    if let Some(sik) = &mut sik {
                        sik.handle_air_output(sik_end_sending(to.reverse()), &bytes);
                        continue;
                    }
                    let written = port.as_mut().is_some_and(|p| p.write_all(&bytes).is_ok());
                    if !written {
                        shared
                            .unwritten
                            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
                    }
                }
            }
            match &mut sik {
                None => radio.poll_timeout(),
                Some(sik) => {
                    if let Some([down, up]) = sik.take_presets() {
                        match radio.rebuilt(&down, &up) {
                            Ok(r) => *radio = r,
                            Err(e) => {
                                tracing::warn!(radio = name, error = %e, "SiK settings the model cannot run; the link keeps its preset")
                            }
                        }
                    }
                    for (port, end) in [(&mut *a, sik::End::Air), (&mut *b, sik::End::Ground)] {
                        while let Some(bytes) = sik.poll_host_output(end) {
                            let written =
                                port.as_mut().is_some_and(|p| p.write_all(&bytes).is_ok());
                            if !written {
                                shared
                                    .unwritten
                                    .fetch_add(bytes.len() as u64, Ordering::Relaxed);
                            }
                        }
                    }
                    [radio.poll_timeout(), sik.poll_timeout()]
                        .into_iter()
                        .flatten()
                        .min()
                }
            }
        };
        let now = model_time(shared.epoch);
        let wait = next.map_or(POLL, |t| {
            Duration::from(t.saturating_duration_since(now)).min(POLL)
        });
        if !wait.is_zero() {
            std::thread::sleep(wait);
        }
    }
    let unwritten = shared.unwritten.load(Ordering::Relaxed);
    if unwritten > 0 {
        tracing::warn!(
            radio = name,
            unwritten,
            "radio emulator delivered bytes nobody read"
        );
    }
}

/// The SiK side whose port sends on `direction`.
fn sik_end_sending(direction: Direction) -> sik::End {
    match direction {
        Direction::Downlink => sik::End::Air,
        Direction::Uplink => sik::End::Ground,
    }
}

fn sik_end(end: End) -> sik::End {
    match end {
        End::Air => sik::End::Air,
        End::Ground => sik::End::Ground,
    }
}

/// The radio model's time: microseconds on the rig's monotonic clock since `epoch` (the
/// edge where the real clock becomes the model's [`Instant`]).
fn model_time(epoch: Mono) -> Instant {
    Instant::ZERO + timebase::Duration::from(Mono::now().since(epoch))
}

/// Reads what the port has without blocking.
fn read_available(port: &mut TTYPort, buf: &mut [u8]) -> std::io::Result<usize> {
    let ready = port.bytes_to_read().map_err(std::io::Error::from)? as usize;
    if ready == 0 {
        return Ok(0);
    }
    let n = ready.min(buf.len());
    port.read(&mut buf[..n])
}
