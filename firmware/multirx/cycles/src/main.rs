//! Instruction-count benchmark of `multirx-core` as the SAMD21 firmware runs
//! it: built for `thumbv6m-none-eabi` with the firmware's release profile and
//! run on QEMU's micro:bit machine (a Cortex-M0, the same ARMv6-M instruction
//! set as the SAMD21's M0+). `ci/cycle-budget.py` runs it with an
//! instruction trace and turns the regions below into instructions and
//! estimated cycles; this program only drives the engine and marks regions.
//!
//! A region is announced on the semihosting console (`region NAME [per N]`),
//! then run between calls to [`cycles_region_start`] and [`cycles_region_end`],
//! whose addresses the script finds in the ELF; `per N` says the region does
//! N units of work (the script divides). The `empty` region measures the
//! markers themselves, which the script subtracts.
//!
//! The engine runs a steady flight: six receivers, every one up, receiver 0
//! in control, each sending a frame every 7 ms (after warm-up rounds that
//! bring the links up). Measured each round:
//!
//! - `frame_slice_active`, `frame_slice_standby`: one 25-byte frame fed as one
//!   slice, as the firmware now feeds what a receive queue holds, to the
//!   receiver in control and to another one;
//! - `frame_bytes_standby`: a frame fed byte by byte (the firmware's earlier
//!   feeding, and what a loop that comes round for every byte still pays);
//! - `output_period`: the output deadline: `handle_timeout`, the frame taken
//!   with `poll_transmit`, events polled, the next deadline read;
//! - `status_line`, `boot_line`: a status line and the boot line formatted and
//!   queued as `../samd21/src/main.rs` does;
//! - `rx_interrupt`, `rx_gather`: the receive path of one byte outside the
//!   engine, with plain memory standing in for the SERCOM's and the timer's
//!   registers: the RX interrupt's body (critical section, flag, status and
//!   data reads, the timer stamp, the queue), and the loop's side per byte
//!   (stamp to `Instant`, [`joins_slice`], dequeue, gather). Exception entry
//!   and return are hardware, not instructions: the script adds them.

#![no_std]
#![no_main]

/// The configuration compiled in by `build.rs` from `cycles.toml`.
mod config {
    include!(concat!(env!("OUT_DIR"), "/config.rs"));
}

use core::cell::RefCell;
use core::fmt::{self, Write as _};
use core::hint::black_box;
use core::ptr::{addr_of, addr_of_mut};

use cortex_m_rt::entry;
use critical_section::Mutex;
use heapless::Deque;
use heapless::spsc::{Consumer, Producer, Queue};
use multirx_core::boot::{BootReport, ResetCause};
use multirx_core::counter::Counter32;
use multirx_core::mux::{LinkState, joins_slice};
use multirx_core::wire::SbusRepr;
use multirx_core::{Duration, Event, Instant, Multiplexer, TimedEvent};

use config::CONFIG;

/// Rounds that bring every link up (acquire frames) before measuring.
const WARM_UP_ROUNDS: u32 = 5;
/// Rounds measured; the script reports their mean and maximum.
const MEASURED_ROUNDS: u32 = 8;
/// A receiver's frame period (SBUS high speed), as the rig's fixtures send.
const RECEIVER_PERIOD: Duration = Duration::from_millis(7);
/// One SBUS byte on the wire: 12 bits (start, 8 data, parity, 2 stop) at 100 kbaud.
const BYTE_TIME: Duration = Duration::from_micros(120);
/// Bytes per SBUS frame.
const FRAME_LEN: usize = 25;
/// The firmware's receive queue and status queue sizes (`../samd21/src/main.rs`).
const RX_QUEUE: usize = 64;
const STATUS_QUEUE: usize = 512;

// ---- region markers and the semihosting console ----------------------------

/// Written by the markers, volatile: a marker without a side effect is
/// removed with its calls, and two alike could be merged into one address.
static mut MARK: u32 = 0;

/// Where a measured region starts; ci/cycle-budget.py finds it by name.
#[unsafe(no_mangle)]
#[inline(never)]
pub extern "C" fn cycles_region_start() {
    // SAFETY: single-threaded; nothing else touches MARK.
    unsafe { addr_of_mut!(MARK).write_volatile(1) };
}

/// Where a measured region ends; ci/cycle-budget.py finds it by name.
#[unsafe(no_mangle)]
#[inline(never)]
pub extern "C" fn cycles_region_end() {
    // SAFETY: as above.
    unsafe { addr_of_mut!(MARK).write_volatile(2) };
}

/// Semihosting operations (ARM's semihosting specification).
const SYS_WRITE0: u32 = 0x04;
const SYS_EXIT: u32 = 0x18;
const ADP_STOPPED_APPLICATION_EXIT: u32 = 0x2_0026;
const ADP_STOPPED_RUN_TIME_ERROR: u32 = 0x2_0023;

/// Writes a line to the host's console (QEMU's stdout).
fn say(args: fmt::Arguments) {
    let mut line = heapless::String::<96>::new();
    // A line too long for the buffer is cut, never lost.
    let _ = line.write_fmt(args);
    let _ = line.push('\n');
    while line.push('\0').is_err() {
        line.pop();
    }
    // SAFETY: SYS_WRITE0 reads a NUL-terminated string, which `line` is.
    unsafe { cortex_m::asm::semihosting_syscall(SYS_WRITE0, line.as_ptr() as u32) };
}

/// Ends the emulation: QEMU exits 0 on `ADP_STOPPED_APPLICATION_EXIT`, 1 otherwise.
fn exit(reason: u32) -> ! {
    loop {
        // SAFETY: SYS_EXIT on 32-bit ARM takes the reason itself, not a pointer.
        unsafe { cortex_m::asm::semihosting_syscall(SYS_EXIT, reason) };
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    say(format_args!("panic: {info}"));
    exit(ADP_STOPPED_RUN_TIME_ERROR)
}

/// Runs `work` as a measured region named `name` doing `per` units of work.
fn region<R>(name: &str, per: u32, work: impl FnOnce() -> R) -> R {
    say(format_args!("region {name} per {per}"));
    cycles_region_start();
    let result = work();
    cycles_region_end();
    black_box(result)
}

// ---- a stand-in for the firmware's receive path ----------------------------

/// The firmware's queue entry (`../samd21/src/main.rs`): a byte (or an error
/// marker) and the timer's raw count when the interrupt read it.
#[derive(Clone, Copy)]
struct RxEntry {
    at: u32,
    value: u16,
}
const UART_ERROR: u16 = 0x100;

/// A SERCOM's registers as the interrupt reads them: INTFLAG, STATUS, DATA,
/// and the TC4+TC5 count. Plain memory, read and written volatile as MMIO is.
#[repr(C)]
struct FakeSercom {
    intflag: u8,
    status: u16,
    data: u16,
    count: u32,
}
const RXC: u8 = 1 << 2;
const ERRORS: u16 = 0b111; // PERR, FERR, BUFOVF

static mut SERCOM: FakeSercom = FakeSercom {
    intflag: 0,
    status: 0,
    data: 0,
    count: 0,
};

/// An input owned by its interrupt, as the firmware's `RxPort`.
struct RxPort {
    queue: Producer<'static, RxEntry>,
}

static RX0: Mutex<RefCell<Option<RxPort>>> = Mutex::new(RefCell::new(None));

/// The body of the firmware's `SERCOMn` handler: every received byte, with
/// its stamp, into the queue.
#[inline(never)]
fn rx_interrupt() {
    critical_section::with(|cs| {
        if let Ok(mut slot) = RX0.borrow(cs).try_borrow_mut()
            && let Some(port) = slot.as_mut()
        {
            // SAFETY: single-threaded benchmark; volatile as the registers are.
            unsafe {
                let sercom = addr_of_mut!(SERCOM);
                while addr_of!((*sercom).intflag).read_volatile() & RXC != 0 {
                    let bad = addr_of!((*sercom).status).read_volatile() & ERRORS != 0;
                    if bad {
                        addr_of_mut!((*sercom).status).write_volatile(ERRORS);
                    }
                    let byte = addr_of!((*sercom).data).read_volatile() as u8;
                    // Reading DATA clears RXC on the chip; here the flag is cleared by hand.
                    addr_of_mut!((*sercom).intflag).write_volatile(0);
                    let value = if bad { UART_ERROR } else { byte.into() };
                    let at = addr_of!((*sercom).count).read_volatile();
                    let _ = port.queue.enqueue(RxEntry { at, value });
                }
            }
        }
    });
}

/// A byte arrives: what the SERCOM holds when its interrupt runs.
fn receive(byte: u8, raw_time: u32) {
    // SAFETY: single-threaded benchmark.
    unsafe {
        let sercom = addr_of_mut!(SERCOM);
        addr_of_mut!((*sercom).data).write_volatile(byte.into());
        addr_of_mut!((*sercom).count).write_volatile(raw_time);
        addr_of_mut!((*sercom).intflag).write_volatile(RXC);
    }
}

/// The loop's side for one queued byte, as `../samd21/src/main.rs` gathers a
/// slice: not after `now`, the gap rule, dequeue, gather (raw stamps).
#[inline(always)]
fn gather_one(
    input: &mut Consumer<'static, RxEntry>,
    clock: &Counter32,
    fed: u32,
    slice: &mut heapless::Vec<u8, RX_QUEUE>,
    last: &mut u32,
) -> bool {
    let Some(&entry) = input.peek() else {
        return false;
    };
    if clock.is_after_now(entry.at) || entry.value == UART_ERROR || !joins_slice(fed, entry.at) {
        return false;
    }
    input.dequeue();
    *last = entry.at;
    slice.push(entry.value as u8).is_ok()
}

/// Appends all of `bytes` or none, as the firmware's `push_whole`.
fn push_whole<const N: usize>(queue: &mut Deque<u8, N>, bytes: &[u8]) {
    if queue.capacity() - queue.len() >= bytes.len() {
        for &byte in bytes {
            let _ = queue.push_back(byte);
        }
    }
}

#[entry]
fn main() -> ! {
    let queue = cortex_m::singleton!(: Queue<RxEntry, RX_QUEUE> = Queue::new()).expect("once");
    let (producer, mut consumer) = queue.split();
    critical_section::with(|cs| RX0.replace(cs, Some(RxPort { queue: producer })));

    let mut now = Instant::ZERO;
    let mut mux = Multiplexer::new(CONFIG, now);
    let mut status_queue: Deque<u8, STATUS_QUEUE> = Deque::new();
    let frame = SbusRepr::default().to_bytes();
    let frame_time = BYTE_TIME * (FRAME_LEN as u32 - 1);
    say(format_args!(
        "config receivers {} output_period_us {} receiver_period_us {}",
        CONFIG.receivers,
        CONFIG.frame_period.as_micros(),
        RECEIVER_PERIOD.as_micros()
    ));

    region("empty", 1, || ());

    for round in 0..WARM_UP_ROUNDS + MEASURED_ROUNDS {
        let measured = round >= WARM_UP_ROUNDS;
        let start = Instant::ZERO + RECEIVER_PERIOD * round;

        if mux.poll_timeout().is_some_and(|due| start >= due) {
            now = start;
            let mut work = || {
                mux.handle_timeout(black_box(now));
                let out = mux.poll_transmit();
                while let Some(event) = mux.poll_event() {
                    black_box(event);
                }
                (out, mux.poll_timeout())
            };
            if measured {
                region("output_period", 1, work);
            } else {
                black_box(work());
            }
        }

        // The receivers' frames, 500 µs apart, each fed at its last byte.
        for rx in 0..CONFIG.receivers {
            let first = start + Duration::from_micros(500) * u32::from(rx);
            let last = first + frame_time;
            let bytes = black_box(&frame[..]);
            match (measured, rx) {
                (true, 0) => region("frame_slice_active", 1, || {
                    mux.handle_receiver_bytes(black_box(last), 0, bytes)
                }),
                (true, 1) => region("frame_slice_standby", 1, || {
                    mux.handle_receiver_bytes(black_box(last), 1, bytes)
                }),
                (true, 2) => region("frame_bytes_standby", 1, || {
                    for (i, byte) in bytes.chunks(1).enumerate() {
                        let at = first + BYTE_TIME * i as u32;
                        mux.handle_receiver_bytes(black_box(at), 2, byte);
                    }
                }),
                _ => mux.handle_receiver_bytes(last, rx, bytes),
            }
        }
        while let Some(event) = mux.poll_event() {
            black_box(event);
        }
        if measured && round == WARM_UP_ROUNDS && mux.active() != Some(0) {
            say(format_args!(
                "error: receiver 0 is not in control after warm-up ({:?})",
                mux.active()
            ));
            exit(ADP_STOPPED_RUN_TIME_ERROR);
        }

        if measured {
            // One frame's bytes through the receive path, outside the engine:
            // an interrupt per byte, then the loop gathers them.
            for (i, &byte) in frame.iter().enumerate() {
                receive(byte, BYTE_TIME.as_micros() as u32 * i as u32);
                region("rx_interrupt", 1, rx_interrupt);
            }
            let mut clock = Counter32::starting_at(0);
            clock.now(BYTE_TIME.as_micros() as u32 * FRAME_LEN as u32);
            let mut slice = heapless::Vec::<u8, RX_QUEUE>::new();
            let mut last = 0;
            let fed = black_box(0);
            region("rx_gather", FRAME_LEN as u32, || {
                while gather_one(&mut consumer, &clock, fed, &mut slice, &mut last) {}
                clock.at(last)
            });
            if slice.len() != FRAME_LEN {
                say(format_args!(
                    "error: gathered {} bytes of a frame",
                    slice.len()
                ));
                exit(ADP_STOPPED_RUN_TIME_ERROR);
            }

            let event = TimedEvent {
                at: start,
                event: Event::Link {
                    rx: 5,
                    state: LinkState::Acquiring,
                },
            };
            region("status_line", 1, || {
                let mut line = heapless::String::<48>::new();
                if writeln!(line, "{}", black_box(&event)).is_ok() {
                    push_whole(&mut status_queue, line.as_bytes());
                }
            });
            let boot = BootReport {
                at: start,
                build_id: 0x0123_4567_89ab_cdef,
                config_hash: 0xfedc_ba98_7654_3210,
                reset: ResetCause::PowerOn,
                first_frame: Duration::from_micros(21_345),
            };
            region("boot_line", 1, || {
                let mut line = heapless::String::<128>::new();
                if writeln!(line, "{}", black_box(&boot)).is_ok() {
                    push_whole(&mut status_queue, line.as_bytes());
                }
            });
            status_queue.clear();
        }
    }
    say(format_args!("done"));
    exit(ADP_STOPPED_APPLICATION_EXIT)
}
