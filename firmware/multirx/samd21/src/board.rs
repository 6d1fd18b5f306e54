//! The MultiRX board: ATSAMD21G18A pin map, type aliases and constructors.
//!
//! No decisions here: which receiver is in control, what the flight controller
//! gets and which receiver is powered are `multirx_core`'s; `main.rs` moves
//! bytes and power events between this module and the engine.
//!
//! | signal                         | pin  | SERCOM pad (mux)  | chip pin |
//! |--------------------------------|------|-------------------|----------|
//! | receiver 0 SBUS in             | PA11 | SERCOM0 PAD3 (C)  | 16       |
//! | flight controller SBUS out     | PA10 | SERCOM0 PAD2 (C)  | 15       |
//! | receiver 1 SBUS in             | PA19 | SERCOM1 PAD3 (C)  | 28       |
//! | status lines out               | PA18 | SERCOM1 PAD2 (C)  | 27       |
//! | receiver 2 SBUS in             | PA09 | SERCOM2 PAD1 (D)  | 14       |
//! | receiver 3 SBUS in             | PA23 | SERCOM3 PAD1 (C)  | 32       |
//! | receiver 4 SBUS in             | PB09 | SERCOM4 PAD1 (D)  | 8        |
//! | receiver 5 *or* IFS SBUS in    | PB23 | SERCOM5 PAD3 (D)  | 38       |
//! | receiver 0..5 power switch     | PA02, PA03, PA04, PA05, PA06, PA07 | GPIO | 3, 4, 9, 10, 11, 12 |
//! | 32.768 kHz crystal             | PA00, PA01 | XOSC32K     | 1, 2     |
//! | USB (UF2 bootloader)           | PA24, PA25 | USB         | 33, 34   |
//! | SWD (probe-rs)                 | PA30, PA31 | SWCLK/SWDIO | 45, 46   |
//!
//! Every UART runs SBUS framing, 100000 baud 8E2: a SERCOM has one baud rate
//! and frame format for both directions, so the status output on SERCOM1's TX
//! pad shares receiver 1's settings. SBUS lines are inverted and the SAMD21
//! cannot invert a UART: each SBUS input and the flight-controller output go
//! through an external inverter (e.g. 74LVC1G04); the status output is plain
//! 3.3 V TTL serial. The pad choices compile only because the HAL's
//! `uart::Pads` checks each pin/SERCOM/pad/mux combination at the type level.

use atsamd_hal::ehal::digital::{OutputPin, PinState};
use atsamd_hal::gpio::{
    PA02, PA03, PA04, PA05, PA06, PA07, PA09, PA10, PA11, PA18, PA19, PA23, PB09, PB23, Pin, Pins,
    PushPullOutput,
};
use atsamd_hal::pac;
use atsamd_hal::sercom::uart::{
    self, BaudMode, Oversampling, Parity, RxDuplex, StopBits, TxDuplex, ValidPads,
};
use atsamd_hal::sercom::{Sercom0, Sercom1, Sercom2, Sercom3, Sercom4, Sercom5};
use atsamd_hal::time::Hertz;
use multirx_core::Instant;
use multirx_core::boot::ResetCause;
use multirx_core::counter::Counter32;

use crate::clocks::{self, CrystalSwitch};

/// SBUS line rate (8 data bits, even parity, 2 stop bits).
pub const SBUS_BAUD: Hertz = Hertz::from_raw(100_000);

/// GPIO level that powers a receiver. The receivers' supply (typically 5 V) is
/// switched by a P-MOSFET high-side switch whose gate an N-MOSFET pulls low
/// when the GPIO is high: high = on, and a reset (GPIO floating, gate-driver
/// pull-down) leaves every receiver off. Use `PinState::Low` if the P-MOSFET
/// gate is driven straight from the GPIO (only for a 3.3 V receiver supply).
pub const POWER_ON_LEVEL: PinState = PinState::High;

/// Receivers the pin map wires, one per SERCOM; receiver 5's pad is the IFS
/// input when the configuration has an `[ifs]` section. The number is the
/// core's, which the build script and the rig check configs against.
pub const RECEIVER_PORTS: usize = multirx_core::board::SAMD21_UARTS as usize;

/// SERCOM0: receiver 0 in (RX), flight-controller SBUS out (TX).
pub type Sercom0Pads = uart::PadsFromIds<Sercom0, PA11, PA10>;
/// SERCOM1: receiver 1 in (RX), status lines out (TX).
pub type Sercom1Pads = uart::PadsFromIds<Sercom1, PA19, PA18>;
/// SERCOM2..5: receiver 2..5 in (RX only); SERCOM5 is the IFS input instead
/// when the configuration has one.
pub type Sercom2Pads = uart::PadsFromIds<Sercom2, PA09>;
pub type Sercom3Pads = uart::PadsFromIds<Sercom3, PA23>;
pub type Sercom4Pads = uart::PadsFromIds<Sercom4, PB09>;
pub type Sercom5Pads = uart::PadsFromIds<Sercom5, PB23>;

pub type Rx0 = uart::Uart<uart::Config<Sercom0Pads>, RxDuplex>;
pub type Rx1 = uart::Uart<uart::Config<Sercom1Pads>, RxDuplex>;
pub type Rx2 = uart::Uart<uart::Config<Sercom2Pads>, uart::Rx>;
pub type Rx3 = uart::Uart<uart::Config<Sercom3Pads>, uart::Rx>;
pub type Rx4 = uart::Uart<uart::Config<Sercom4Pads>, uart::Rx>;
pub type Rx5 = uart::Uart<uart::Config<Sercom5Pads>, uart::Rx>;
/// SBUS towards the flight controller.
pub type FcOut = uart::Uart<uart::Config<Sercom0Pads>, TxDuplex>;
/// Status lines (`multirx_core::TimedEvent`'s `Display`, one a line).
pub type StatusOut = uart::Uart<uart::Config<Sercom1Pads>, TxDuplex>;

/// Everything `main` drives, configured and enabled; the watchdog already
/// running (started before the clocks, see [`clocks`]).
pub struct Board {
    pub receivers: Receivers,
    pub fc_out: FcOut,
    pub status_out: StatusOut,
    pub power: PowerSwitches,
    pub clock: MicrosClock,
    pub watchdog: Watchdog,
    /// Moves the 48 MHz clock onto the crystal once it is ready; poll it.
    pub crystal: CrystalSwitch,
    /// Why the chip last reset (`PM.RCAUSE`).
    pub reset_cause: ResetCause,
}

/// The six SBUS inputs, receiver i on SERCOMi's RX pad.
pub struct Receivers {
    pub rx0: Rx0,
    pub rx1: Rx1,
    pub rx2: Rx2,
    pub rx3: Rx3,
    pub rx4: Rx4,
    pub rx5: Rx5,
}

impl Board {
    /// Watchdog first, brown-out detector, then 48 MHz on the internal
    /// reference (the crystal takes over later, [`CrystalSwitch::poll`]), then
    /// every peripheral. Takes well under a millisecond: nothing waits for the
    /// crystal.
    pub fn new(mut dp: pac::Peripherals) -> Self {
        clocks::start_watchdog(&dp.gclk, &dp.wdt);
        let reset_cause = ResetCause::from_samd21_rcause(clocks::reset_cause_bits(&dp.pm));
        clocks::brown_out(&dp.sysctrl);
        let crystal = clocks::start(dp.gclk, dp.sysctrl, &dp.nvmctrl, &dp.pm);
        let pins = Pins::new(dp.port);
        let pm = &dp.pm;
        let freq = Hertz::from_raw(clocks::CPU_HZ);

        let pads = uart::Pads::default().rx(pins.pa11).tx(pins.pa10);
        let (rx0, fc_out) = sbus(uart::Config::new(pm, dp.sercom0, pads, freq))
            .enable()
            .split();

        let pads = uart::Pads::default().rx(pins.pa19).tx(pins.pa18);
        let (rx1, status_out) = sbus(uart::Config::new(pm, dp.sercom1, pads, freq))
            .enable()
            .split();

        let pads = uart::Pads::default().rx(pins.pa09);
        let rx2 = sbus(uart::Config::new(pm, dp.sercom2, pads, freq)).enable();
        let pads = uart::Pads::default().rx(pins.pa23);
        let rx3 = sbus(uart::Config::new(pm, dp.sercom3, pads, freq)).enable();
        let pads = uart::Pads::default().rx(pins.pb09);
        let rx4 = sbus(uart::Config::new(pm, dp.sercom4, pads, freq)).enable();
        let pads = uart::Pads::default().rx(pins.pb23);
        let rx5 = sbus(uart::Config::new(pm, dp.sercom5, pads, freq)).enable();

        let power = PowerSwitches {
            rx0: pins.pa02.into_push_pull_output(),
            rx1: pins.pa03.into_push_pull_output(),
            rx2: pins.pa04.into_push_pull_output(),
            rx3: pins.pa05.into_push_pull_output(),
            rx4: pins.pa06.into_push_pull_output(),
            rx5: pins.pa07.into_push_pull_output(),
        }
        .all_off();

        let clock = MicrosClock::new(dp.tc4, dp.tc5, &mut dp.pm);
        let watchdog = Watchdog { wdt: dp.wdt };

        Board {
            receivers: Receivers {
                rx0,
                rx1,
                rx2,
                rx3,
                rx4,
                rx5,
            },
            fc_out,
            status_out,
            power,
            clock,
            watchdog,
            crystal,
            reset_cause,
        }
    }
}

/// SBUS framing: 100000 baud, 8 data bits (the HAL default), even parity,
/// 2 stop bits. 48 MHz / 16 / 100 kHz = 30: the baud rate is exact.
fn sbus<P: ValidPads>(config: uart::Config<P>) -> uart::Config<P> {
    config
        .baud(SBUS_BAUD, BaudMode::Fractional(Oversampling::Bits16))
        .parity(Parity::Even)
        .stop_bits(StopBits::TwoBits)
}

/// The receivers' power switches (see [`POWER_ON_LEVEL`]).
pub struct PowerSwitches {
    rx0: Pin<PA02, PushPullOutput>,
    rx1: Pin<PA03, PushPullOutput>,
    rx2: Pin<PA04, PushPullOutput>,
    rx3: Pin<PA05, PushPullOutput>,
    rx4: Pin<PA06, PushPullOutput>,
    rx5: Pin<PA07, PushPullOutput>,
}

impl PowerSwitches {
    /// Switches receiver `rx` on or off; indices past the sixth are ignored.
    pub fn set(&mut self, rx: u8, on: bool) {
        let level = if on { POWER_ON_LEVEL } else { !POWER_ON_LEVEL };
        let result = match rx {
            0 => self.rx0.set_state(level),
            1 => self.rx1.set_state(level),
            2 => self.rx2.set_state(level),
            3 => self.rx3.set_state(level),
            4 => self.rx4.set_state(level),
            5 => self.rx5.set_state(level),
            _ => Ok(()),
        };
        let Ok(()) = result;
    }

    fn all_off(mut self) -> Self {
        for rx in 0..RECEIVER_PORTS as u8 {
            self.set(rx, false);
        }
        self
    }
}

/// Microseconds since start: TC4+TC5 as one 32-bit counter at 1 MHz, read
/// continuously synchronised (`READREQ.RCONT`) so that RX interrupts can
/// stamp bytes with [`timer_raw`] at any time, extended to 64 bits by the
/// core's [`Counter32`] (the counter wraps every 71.6 minutes; the main loop
/// reads it every pass, and the watchdog resets the chip if a pass takes
/// longer than 250 ms). No interrupt involved.
pub struct MicrosClock {
    /// Owned so nothing else reconfigures it ([`timer_raw`] only reads).
    _tc4: pac::Tc4,
    /// Slave half of the 32-bit counter.
    _tc5: pac::Tc5,
    counter: Counter32,
}

impl MicrosClock {
    fn new(tc4: pac::Tc4, tc5: pac::Tc5, pm: &mut pac::Pm) -> Self {
        const _: () = assert!(clocks::TIMER_HZ == 8_000_000, "prescaler div8 makes 1 MHz");
        pm.apbcmask()
            .modify(|_, w| w.tc4_().set_bit().tc5_().set_bit());
        let count = tc4.count32();
        count.ctrla().write(|w| w.swrst().set_bit());
        while count.status().read().syncbusy().bit_is_set() {}
        count
            .ctrla()
            .write(|w| w.mode().count32().wavegen().nfrq().prescaler().div8());
        while count.status().read().syncbusy().bit_is_set() {}
        count.ctrla().modify(|_, w| w.enable().set_bit());
        while count.status().read().syncbusy().bit_is_set() {}
        // COUNT lives in the 8 MHz timer clock domain: keep a synchronised
        // copy (offset 0x10) refreshed continuously, so a read never waits.
        // SAFETY: 0x10 is COUNT's offset in the COUNT32 register map.
        count
            .readreq()
            .write(|w| unsafe { w.rcont().set_bit().rreq().set_bit().addr().bits(0x10) });
        while count.status().read().syncbusy().bit_is_set() {}
        MicrosClock {
            _tc4: tc4,
            _tc5: tc5,
            counter: Counter32::starting_at(timer_raw()),
        }
    }

    /// Now, in microseconds since [`Board::new`] started the timer.
    pub fn now(&mut self) -> Instant {
        self.counter.now(timer_raw())
    }

    /// When the timer read `raw` (a byte's stamp), near the last [`Self::now`].
    pub fn at(&self, raw: u32) -> Instant {
        self.counter.at(raw)
    }

    /// Whether the timer read `raw` after the last [`Self::now`].
    pub fn is_after_now(&self, raw: u32) -> bool {
        self.counter.is_after_now(raw)
    }
}

/// The 1 MHz timer's raw count; callable from interrupts.
pub fn timer_raw() -> u32 {
    // SAFETY: a read of COUNT, kept synchronised by READREQ.RCONT; the
    // register block is owned by [`MicrosClock`], which never reconfigures
    // it after start.
    let tc4 = unsafe { &*pac::Tc4::ptr() };
    tc4.count32().count().read().bits()
}

/// The watchdog, clocked at 32,768 Hz (OSCULP32K undivided); resets the chip
/// after 8,192 cycles (250 ms) without [`feed`](Self::feed). Started by
/// [`clocks::start_watchdog`] before anything else. Written here rather than
/// taken from the HAL because its `feed` writes CLEAR even while the
/// previous clear is still crossing into the watchdog's clock domain, which
/// stalls the bus (and every interrupt) until it has.
pub struct Watchdog {
    wdt: pac::Wdt,
}

impl Watchdog {
    /// Restarts the countdown without waiting: skipped while the previous
    /// restart is still synchronising, which means it was at most ~0.19 ms
    /// ago (6 watchdog clock periods, datasheet 14.3.1.8).
    pub fn feed(&mut self) {
        if self.wdt.status().read().syncbusy().bit_is_clear() {
            self.wdt.clear().write(|w| w.clear().key());
        }
    }
}
