//! MultiRX firmware for the SAMD21G18: the host-tested `multirx_core` engine
//! wired to the board in [`board`]. This file only moves bytes and time:
//!
//! - [`Board::new`] starts the watchdog, the brown-out detector and the clocks,
//!   in that order, without waiting for the crystal ([`clocks`]); the loop
//!   polls [`clocks::CrystalSwitch`] to move onto the crystal once it runs,
//!   only in a quiet window between output frames ([`quiet_window`]).
//! - SBUS bytes from each receiver (and the IFS) arrive by RX interrupt into a
//!   small lock-free SPSC queue per SERCOM, each stamped with the timer in the
//!   interrupt; each loop pass hands the engine what a queue holds as one
//!   slice ([`Multiplexer::handle_receiver_bytes`] /
//!   [`Multiplexer::handle_ifs_bytes`]), split only where
//!   [`joins_slice`] says the engine's gap check needs it.
//!   A UART error travels the same queue as a marker, so the engine drops the
//!   frame it belongs to ([`Multiplexer::handle_receiver_error`]).
//! - When `now` reaches [`Multiplexer::poll_timeout`] it calls
//!   [`Multiplexer::handle_timeout`], then queues the due SBUS frame for the
//!   flight controller and turns events into power-switch changes and status
//!   lines, each TX queue drained into its UART as the data register empties.
//! - Power events go through [`PowerSequencer`] (switch-ons 20 ms apart); the
//!   status line reports a switch when it changes.
//! - Once the first frame is queued, and every second after, the boot line
//!   ([`BootReport`]: build id, config hash, reset cause, boot-to-first-frame).
//! - The watchdog is fed only after a pass that left the engine with no
//!   overdue deadline and the flight controller's bytes moving
//!   ([`FeedGate`]): a wedged TX resets the chip.
//! - A receive queue that overflows leaves [`RX_OVERFLOW`] in the stream;
//!   the engine drops the frame and reports it (`overflow <rx> <total>`).
//!
//! Why interrupts for RX rather than polling: a SERCOM buffers two bytes, so
//! a polled loop would have to come round within ~240 µs (two 120 µs SBUS
//! bytes) on every pass, whatever the engine and the status formatting cost
//! on a 48 MHz Cortex-M0+. The interrupt handlers only move a byte into a
//! 64-byte queue (7.7 ms of one receiver's line), so the loop's worst case
//! is decoupled from the byte timing. TX is polled: a late poll only widens
//! the gap between two bytes of a frame, which SBUS decoders accept.

#![no_std]
#![no_main]

mod board;
mod clocks;
mod uf2;

/// The configuration compiled in by `build.rs` from `MULTIRX_CONFIG`.
mod config {
    include!(concat!(env!("OUT_DIR"), "/config.rs"));
}

use core::cell::RefCell;
use core::fmt::Write as _;
use core::mem::MaybeUninit;

use atsamd_hal::ehal_nb::serial::{Read, Write};
use atsamd_hal::pac::{self, NVIC, interrupt};
use atsamd_hal::sercom::uart::{Flags, Status, Uart};
use cortex_m_rt::entry;
use critical_section::Mutex;
use heapless::Deque;
use heapless::spsc::{Consumer, Producer, Queue};
use multirx_core::boot::BootReport;
use multirx_core::clock_switch::{SAMD21_CRYSTAL_SWITCH, quiet_window};
use multirx_core::mux::joins_slice;
use multirx_core::power::{POWER_ON_STAGGER, PowerSequencer};
use multirx_core::watchdog::FeedGate;
use multirx_core::{Duration, Event, Instant, Multiplexer, TimedEvent};

use board::{Board, RECEIVER_PORTS, timer_raw};
use config::{BUILD_ID, CONFIG, CONFIG_HASH};

// panic-reset rather than panic-halt: a halted MultiRX sends nothing and the
// flight controller declares RC loss after COM_RC_LOSS_T (0.5 s on PX4);
// resetting at once restarts the neutral / auto-loiter frames after the
// start-up time (the watchdog would reset a halted chip too, but 250 ms
// later). For a debugging session swap in panic-halt and stop the watchdog.
use panic_reset as _;

/// Whether SERCOM5's RX pad is the independent fail-safe system's input
/// rather than receiver 5's.
const IFS: bool = !CONFIG.ifs_channels.is_empty();
/// The SERCOM (and queue) the IFS uses when [`IFS`]: the last one.
const IFS_PORT: usize = RECEIVER_PORTS - 1;
const _: () = assert!(
    multirx_core::board::uarts_needed(CONFIG.receivers, IFS) as usize <= RECEIVER_PORTS,
    "build.rs checks the board limits; this backs it up"
);

/// Bytes buffered per SBUS input between the RX interrupt and the main loop.
const RX_QUEUE: usize = 64;
/// Bytes queued for the flight controller: two 25-byte frames.
const FC_QUEUE: usize = 64;
/// Bytes queued for the status output (~13 lines); a line that does not fit
/// whole is dropped: status never holds up SBUS or the power switches.
const STATUS_QUEUE: usize = 512;

/// How often the boot line is repeated, so a rig that opens the status port
/// after the board started still learns which image and config it runs.
const BOOT_LINE_EVERY: Duration = Duration::from_secs(1);

/// The receive queues, one per SBUS input: 3,120 of the image's RAM bytes.
/// In cortex-m-rt's `.uninit` rather than `.bss`: the reset handler zeroes
/// `.bss` at the reset clock (1 MHz), before the timer `first-frame-us`
/// counts from starts, at 6 cycles a word (see `ci/check-firmware-elf.py`),
/// so these 3 KiB cost 4.7 ms there; [`rx_queues`] initialises them at
/// 48 MHz instead.
#[unsafe(link_section = ".uninit.RX_QUEUES")]
static mut RX_QUEUES: MaybeUninit<[Queue<RxEntry, RX_QUEUE>; RECEIVER_PORTS]> =
    MaybeUninit::uninit();

/// The receive queues, initialised: empty (`Queue::new` sets head and tail;
/// its slots are `MaybeUninit` and need nothing).
///
/// # Safety
///
/// Once only, before any RX interrupt is unmasked: the reference is the
/// only one to the queues until `split` hands their halves out.
unsafe fn rx_queues() -> &'static mut [Queue<RxEntry, RX_QUEUE>; RECEIVER_PORTS] {
    // `&raw mut`: no reference to the uninitialised static is made.
    let slot = &raw mut RX_QUEUES;
    // SAFETY: the caller's contract makes this the only access; `write`
    // returns the reference to what it initialised.
    unsafe { (*slot).write([const { Queue::new() }; RECEIVER_PORTS]) }
}

/// A queue entry: a received byte, or [`UART_ERROR`], and the timer's raw
/// count when the interrupt read it. Stamped in the interrupt, not when the
/// main loop gets round to it, so the core's gap check (a new frame starts
/// after a quiet line) sees the line's timing rather than the loop's.
#[derive(Clone, Copy)]
struct RxEntry {
    at: u32,
    value: u16,
}
/// Queued in place of a byte received with a parity, framing or overrun error.
const UART_ERROR: u16 = 0x100;
/// Queued where bytes were lost because the queue was full, before the first
/// byte that fits again, so the engine drops the frame and counts the loss.
const RX_OVERFLOW: u16 = 0x200;

/// An SBUS input owned by its interrupt handler.
struct RxPort<U> {
    uart: U,
    queue: Producer<'static, RxEntry>,
    /// Bytes lost to a full queue since the last [`RX_OVERFLOW`] was queued
    /// (saturating). A number rather than a flag: a `bool` here gave
    /// `Option<RxPort>` a niche, and the code built around it kept a panic
    /// path in the handler that `ci/check-firmware-elf.py` refuses.
    lost: u16,
}

type Slot<U> = Mutex<RefCell<Option<RxPort<U>>>>;

static RX0: Slot<board::Rx0> = Mutex::new(RefCell::new(None));
static RX1: Slot<board::Rx1> = Mutex::new(RefCell::new(None));
static RX2: Slot<board::Rx2> = Mutex::new(RefCell::new(None));
static RX3: Slot<board::Rx3> = Mutex::new(RefCell::new(None));
static RX4: Slot<board::Rx4> = Mutex::new(RefCell::new(None));
static RX5: Slot<board::Rx5> = Mutex::new(RefCell::new(None));

/// What an RX interrupt needs of a UART, whatever its pads.
trait SbusRx {
    fn listen(&mut self);
    fn service(&mut self, queue: &mut Producer<'static, RxEntry>, lost: &mut u16);
}

impl<C, D> SbusRx for Uart<C, D>
where
    C: atsamd_hal::sercom::uart::ValidConfig<Word = u8>,
    D: atsamd_hal::sercom::uart::Receive,
{
    fn listen(&mut self) {
        self.flush_rx_buffer();
        self.enable_interrupts(Flags::RXC);
    }

    /// Moves every received byte to `queue`. A byte with a parity or framing
    /// error, or after an overrun, becomes [`UART_ERROR`] so the engine drops
    /// the frame it belongs to. A full queue drops bytes and counts them in
    /// `lost`; [`RX_OVERFLOW`] then goes in ahead of the next byte that
    /// fits, so the loss reaches the engine in its place in the stream.
    fn service(&mut self, queue: &mut Producer<'static, RxEntry>, lost: &mut u16) {
        let errors = || Status::PERR | Status::FERR | Status::BUFOVF;
        while self.read_flags().contains(Flags::RXC) {
            let bad = self.read_status().intersects(errors());
            if bad {
                // `read` refuses while an error flag is set; clear it, then
                // read the byte it belongs to and drop it.
                self.clear_status(errors());
            }
            if let Ok(byte) = self.read() {
                let at = timer_raw();
                // The marker first, where there is room again; if this byte
                // then finds none, the loss goes on and is marked again.
                if *lost > 0
                    && queue
                        .enqueue(RxEntry {
                            at,
                            value: RX_OVERFLOW,
                        })
                        .is_ok()
                {
                    *lost = 0;
                }
                let value = if bad { UART_ERROR } else { byte.into() };
                if *lost > 0 || queue.enqueue(RxEntry { at, value }).is_err() {
                    *lost = lost.saturating_add(1);
                }
            }
        }
    }
}

fn on_interrupt<U: SbusRx>(slot: &Slot<U>) {
    critical_section::with(|cs| {
        // `try_`: the slot is only borrowed here, with interrupts masked, so
        // it is never busy; but `borrow_ref_mut` would keep a panic path in
        // the handler, which ci/check-firmware-elf.py refuses.
        if let Ok(mut slot) = slot.borrow(cs).try_borrow_mut()
            && let Some(port) = slot.as_mut()
        {
            port.uart.service(&mut port.queue, &mut port.lost);
        }
    });
}

#[interrupt]
fn SERCOM0() {
    on_interrupt(&RX0);
}

#[interrupt]
fn SERCOM1() {
    on_interrupt(&RX1);
}

#[interrupt]
fn SERCOM2() {
    on_interrupt(&RX2);
}

#[interrupt]
fn SERCOM3() {
    on_interrupt(&RX3);
}

#[interrupt]
fn SERCOM4() {
    on_interrupt(&RX4);
}

#[interrupt]
fn SERCOM5() {
    on_interrupt(&RX5);
}

/// SERCOMi's interrupt serves SBUS input i.
const SERCOM_IRQ: [pac::Interrupt; RECEIVER_PORTS] = [
    pac::Interrupt::SERCOM0,
    pac::Interrupt::SERCOM1,
    pac::Interrupt::SERCOM2,
    pac::Interrupt::SERCOM3,
    pac::Interrupt::SERCOM4,
    pac::Interrupt::SERCOM5,
];

/// Hands SBUS input `port` to its interrupt handler and unmasks it, if the
/// configuration uses it; an unused input stays masked and is never read.
fn install<U: SbusRx + Send>(
    slot: &'static Slot<U>,
    mut uart: U,
    queue: Producer<'static, RxEntry>,
    port: usize,
) {
    if !port_used(port) {
        return;
    }
    uart.listen();
    critical_section::with(|cs| {
        slot.replace(
            cs,
            Some(RxPort {
                uart,
                queue,
                lost: 0,
            }),
        )
    });
    // SAFETY: the handler's slot is filled, and nothing here relies on
    // interrupts being masked (all shared state is behind critical sections
    // or in SPSC queues).
    unsafe { NVIC::unmask(SERCOM_IRQ[port]) };
}

/// Whether SBUS input `port` is wired to something the configuration uses.
const fn port_used(port: usize) -> bool {
    port < CONFIG.receivers as usize || (IFS && port == IFS_PORT)
}

#[entry]
fn main() -> ! {
    // Behind a UF2 bootloader, before anything that could hang: the next
    // watchdog, panic or brown-out reset must not wait out its 500 ms.
    let mut quick_boot = uf2::QuickBoot::at_reset();
    let dp = pac::Peripherals::take().expect("first and only take");
    // Watchdog, brown-out detector and clocks, in that order (see `clocks`).
    let Board {
        receivers,
        mut fc_out,
        mut status_out,
        mut power,
        mut clock,
        mut watchdog,
        mut crystal,
        reset_cause,
    } = Board::new(dp);

    // Per input, the raw stamp the engine last got bytes at (for
    // `joins_slice`); before any, one read before the first interrupt can
    // stamp a byte.
    let mut fed: [u32; RECEIVER_PORTS] = [timer_raw(); RECEIVER_PORTS];

    // SAFETY: here only, and every RX interrupt is still masked (`install`
    // unmasks them below).
    let queues = unsafe { rx_queues() };
    let [q0, q1, q2, q3, q4, q5] = queues;
    let (p0, c0) = q0.split();
    let (p1, c1) = q1.split();
    let (p2, c2) = q2.split();
    let (p3, c3) = q3.split();
    let (p4, c4) = q4.split();
    let (p5, c5) = q5.split();
    let mut inputs: [Consumer<'static, RxEntry>; RECEIVER_PORTS] = [c0, c1, c2, c3, c4, c5];
    install(&RX0, receivers.rx0, p0, 0);
    install(&RX1, receivers.rx1, p1, 1);
    install(&RX2, receivers.rx2, p2, 2);
    install(&RX3, receivers.rx3, p3, 3);
    install(&RX4, receivers.rx4, p4, 4);
    install(&RX5, receivers.rx5, p5, 5);

    let mut mux = Multiplexer::new(CONFIG, clock.now());
    let mut sequencer = PowerSequencer::new(POWER_ON_STAGGER);
    let mut feed_gate = FeedGate::new(&CONFIG);
    let mut fc_queue: Deque<u8, FC_QUEUE> = Deque::new();
    let mut status_queue: Deque<u8, STATUS_QUEUE> = Deque::new();
    let mut boot = BootReport {
        at: Instant::ZERO,
        build_id: BUILD_ID,
        config_hash: CONFIG_HASH,
        reset: reset_cause,
        first_frame: Duration::ZERO,
    };
    let mut next_boot_line: Option<Instant> = None;

    loop {
        let now = clock.now();
        quick_boot.poll(now);

        for (port, input) in inputs.iter_mut().enumerate() {
            // What the queue holds, as few slices as the gap check allows,
            // each fed at its last byte's stamp: one engine call per frame
            // instead of one per byte (stamps stay raw counts until then: the
            // 64-bit time costs more per byte). Bytes that arrived after `now`
            // was read wait for the next pass, so the engine's time never runs
            // backwards.
            let mut slice = RxSlice::new();
            for _ in 0..RX_QUEUE {
                let Some(&entry) = input.peek() else { break };
                if clock.is_after_now(entry.at) {
                    break;
                }
                let marker = entry.value == UART_ERROR || entry.value == RX_OVERFLOW;
                if marker || !joins_slice(fed[port], entry.at) {
                    slice.feed(&mut mux, &clock, port, &mut fed[port]);
                }
                input.dequeue();
                let ifs = IFS && port == IFS_PORT;
                match (entry.value, ifs) {
                    // Drop the frame the damaged byte belongs to.
                    (UART_ERROR, true) => mux.handle_ifs_error(clock.at(entry.at)),
                    (UART_ERROR, false) => {
                        mux.handle_receiver_error(clock.at(entry.at), port as u8)
                    }
                    // Bytes lost here: drop the frame, count and report it.
                    (RX_OVERFLOW, true) => mux.handle_ifs_overflow(clock.at(entry.at)),
                    (RX_OVERFLOW, false) => {
                        mux.handle_receiver_overflow(clock.at(entry.at), port as u8)
                    }
                    (byte, _) => slice.push(entry.at, byte as u8),
                }
            }
            slice.feed(&mut mux, &clock, port, &mut fed[port]);
        }

        if mux.poll_timeout().is_some_and(|due| now >= due) {
            mux.handle_timeout(now);
        }
        while let Some(frame) = mux.poll_transmit() {
            push_whole(&mut fc_queue, &frame);
            if next_boot_line.is_none() {
                boot.first_frame = now.since_epoch();
                next_boot_line = Some(now);
            }
        }
        while let Some(event) = mux.poll_event() {
            match event.event {
                // Reported when the switch actually changes, below.
                Event::Power { rx, on } => sequencer.request(rx, on),
                _ => status_line(&mut status_queue, &event),
            }
        }
        while let Some((rx, on)) = sequencer.poll(now) {
            power.set(rx, on);
            let event = TimedEvent {
                at: now,
                event: Event::Power { rx, on },
            };
            status_line(&mut status_queue, &event);
        }
        if let Some(due) = next_boot_line.filter(|&due| now >= due) {
            next_boot_line = Some(due + BOOT_LINE_EVERY);
            boot.at = now;
            let mut line = heapless::String::<128>::new();
            if writeln!(line, "{boot}").is_ok() {
                push_whole(&mut status_queue, line.as_bytes());
            }
        }

        let sent = drain(&mut fc_out, &mut fc_queue);
        feed_gate.note_tx(now, sent, fc_queue.len());
        drain(&mut status_out, &mut status_queue);

        if feed_gate.may_feed(now, mux.poll_timeout()) {
            watchdog.feed();
        }

        // The 48 MHz onto the crystal between two frames, never while a
        // byte for the flight controller is queued or shifting out.
        if crystal.pending() {
            let tx_idle = fc_queue.is_empty() && fc_out.read_flags().contains(Flags::TXC);
            if quiet_window(
                clock.now(),
                mux.poll_timeout(),
                tx_idle,
                SAMD21_CRYSTAL_SWITCH,
            ) {
                crystal.poll();
            }
        }
    }
}

/// Bytes gathered from one receive queue for one engine call.
struct RxSlice {
    bytes: heapless::Vec<u8, RX_QUEUE>,
    /// The last byte's raw timer stamp.
    at: u32,
}

impl RxSlice {
    fn new() -> Self {
        RxSlice {
            bytes: heapless::Vec::new(),
            at: 0,
        }
    }

    /// Adds a byte stamped `at`. Never full: a pass takes at most `RX_QUEUE` bytes.
    fn push(&mut self, at: u32, byte: u8) {
        let _ = self.bytes.push(byte);
        self.at = at;
    }

    /// Hands the gathered bytes to the engine at the last one's stamp, if any.
    fn feed(
        &mut self,
        mux: &mut Multiplexer,
        clock: &board::MicrosClock,
        port: usize,
        fed: &mut u32,
    ) {
        if self.bytes.is_empty() {
            return;
        }
        let at = clock.at(self.at);
        if IFS && port == IFS_PORT {
            mux.handle_ifs_bytes(at, &self.bytes);
        } else {
            mux.handle_receiver_bytes(at, port as u8, &self.bytes);
        }
        *fed = self.at;
        self.bytes.clear();
    }
}

/// Queues `event` as one status line, or drops it whole if there is no room.
fn status_line<const N: usize>(queue: &mut Deque<u8, N>, event: &TimedEvent) {
    // "18446744073709551615 link 5 acquiring\n" is 38 bytes.
    let mut line = heapless::String::<48>::new();
    if writeln!(line, "{event}").is_ok() {
        push_whole(queue, line.as_bytes());
    }
}

/// Appends all of `bytes` or none: a partial SBUS frame or status line is
/// worse than a missing one.
fn push_whole<const N: usize>(queue: &mut Deque<u8, N>, bytes: &[u8]) {
    if queue.capacity() - queue.len() >= bytes.len() {
        for &byte in bytes {
            let _ = queue.push_back(byte);
        }
    }
}

/// Writes queued bytes while the UART's data register has room; never waits.
/// Returns how many it wrote.
fn drain<const N: usize>(uart: &mut impl Write<u8>, queue: &mut Deque<u8, N>) -> usize {
    let mut sent = 0;
    while let Some(&byte) = queue.front() {
        if uart.write(byte).is_err() {
            break;
        }
        queue.pop_front();
        sent += 1;
    }
    sent
}
