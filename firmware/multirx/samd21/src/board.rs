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

use atsamd_hal::clock::{ClockGenId, ClockSource, GenericClockController, Tc4Tc5Clock};
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

/// Everything `main` drives, configured and enabled (the watchdog is clocked
/// but not started).
pub struct Board {
    pub receivers: Receivers,
    pub fc_out: FcOut,
    pub status_out: StatusOut,
    pub power: PowerSwitches,
    pub clock: MicrosClock,
    pub watchdog: Watchdog,
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
    /// Clocks the chip at 48 MHz (DFLL48M locked to the 32.768 kHz crystal,
    /// as `GenericClockController` does) and builds every peripheral.
    pub fn new(mut dp: pac::Peripherals) -> Self {
        // The crystal, not the internal OSC32K: SBUS at 100 kbaud 8E2 wants
        // the baud rate within about ±2 %, which the DFLL's open-loop
        // calibration does not promise over temperature. A crystal-less board
        // would use `with_internal_32kosc` here.
        let mut clocks = GenericClockController::with_external_32kosc(
            dp.gclk,
            &mut dp.pm,
            &mut dp.sysctrl,
            &mut dp.nvmctrl,
        );
        let pins = Pins::new(dp.port);
        let gclk0 = clocks.gclk0();
        let pm = &dp.pm;

        let sercom0 = clocks.sercom0_core(&gclk0).expect("SERCOM0 clock set once");
        let pads = uart::Pads::default().rx(pins.pa11).tx(pins.pa10);
        let (rx0, fc_out) = sbus(uart::Config::new(pm, dp.sercom0, pads, sercom0.freq()))
            .enable()
            .split();

        let sercom1 = clocks.sercom1_core(&gclk0).expect("SERCOM1 clock set once");
        let pads = uart::Pads::default().rx(pins.pa19).tx(pins.pa18);
        let (rx1, status_out) = sbus(uart::Config::new(pm, dp.sercom1, pads, sercom1.freq()))
            .enable()
            .split();

        let sercom2 = clocks.sercom2_core(&gclk0).expect("SERCOM2 clock set once");
        let pads = uart::Pads::default().rx(pins.pa09);
        let rx2 = sbus(uart::Config::new(pm, dp.sercom2, pads, sercom2.freq())).enable();

        let sercom3 = clocks.sercom3_core(&gclk0).expect("SERCOM3 clock set once");
        let pads = uart::Pads::default().rx(pins.pa23);
        let rx3 = sbus(uart::Config::new(pm, dp.sercom3, pads, sercom3.freq())).enable();

        let sercom4 = clocks.sercom4_core(&gclk0).expect("SERCOM4 clock set once");
        let pads = uart::Pads::default().rx(pins.pb09);
        let rx4 = sbus(uart::Config::new(pm, dp.sercom4, pads, sercom4.freq())).enable();

        let sercom5 = clocks.sercom5_core(&gclk0).expect("SERCOM5 clock set once");
        let pads = uart::Pads::default().rx(pins.pb23);
        let rx5 = sbus(uart::Config::new(pm, dp.sercom5, pads, sercom5.freq())).enable();

        let power = PowerSwitches {
            rx0: pins.pa02.into_push_pull_output(),
            rx1: pins.pa03.into_push_pull_output(),
            rx2: pins.pa04.into_push_pull_output(),
            rx3: pins.pa05.into_push_pull_output(),
            rx4: pins.pa06.into_push_pull_output(),
            rx5: pins.pa07.into_push_pull_output(),
        }
        .all_off();

        // 8 MHz (DFLL48M / 6) for TC4+TC5; their prescaler makes 1 MHz.
        let gclk_timer = clocks
            .configure_gclk_divider_and_source(ClockGenId::Gclk3, 6, ClockSource::Dfll48m, false)
            .expect("GCLK3 free");
        let timer_clock = clocks.tc4_tc5(&gclk_timer).expect("TC4/TC5 clock set once");
        let clock = MicrosClock::new(dp.tc4, dp.tc5, &mut dp.pm, &timer_clock);

        // 1024 Hz (OSCULP32K / 32) for the watchdog.
        let gclk_wdt = clocks
            .configure_gclk_divider_and_source(ClockGenId::Gclk4, 32, ClockSource::Osculp32k, false)
            .expect("GCLK4 free");
        clocks.wdt(&gclk_wdt).expect("WDT clock set once");
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

/// Microseconds since start: TC4+TC5 as one 32-bit counter at 1 MHz, extended
/// to 64 bits in software. The counter wraps every 2^32 µs (71.6 min);
/// [`now`](Self::now) adds the wrapping difference since its last call, which
/// is right as long as calls are less than 71 minutes apart: the main loop
/// calls it every pass, and the watchdog resets the chip if a pass takes
/// longer than 250 ms. No interrupt involved.
pub struct MicrosClock {
    tc4: pac::Tc4,
    /// Slave half of the 32-bit counter; owned so nothing else uses it.
    _tc5: pac::Tc5,
    last: u32,
    micros: u64,
}

impl MicrosClock {
    fn new(tc4: pac::Tc4, tc5: pac::Tc5, pm: &mut pac::Pm, clock: &Tc4Tc5Clock) -> Self {
        debug_assert_eq!(clock.freq().to_Hz(), 8_000_000);
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
        MicrosClock {
            tc4,
            _tc5: tc5,
            last: 0,
            micros: 0,
        }
    }

    /// Now, in microseconds since [`Board::new`].
    pub fn now(&mut self) -> Instant {
        // COUNT lives in the 8 MHz timer clock domain: request a synchronised
        // copy (offset 0x10) and wait the few cycles it takes (< 1 µs).
        let count = self.tc4.count32();
        // SAFETY: 0x10 is COUNT's offset in the COUNT32 register map.
        count
            .readreq()
            .write(|w| unsafe { w.rreq().set_bit().addr().bits(0x10) });
        while count.status().read().syncbusy().bit_is_set() {}
        let raw = count.count().read().bits();
        self.micros += u64::from(raw.wrapping_sub(self.last));
        self.last = raw;
        Instant::from_micros(self.micros)
    }
}

/// The watchdog, clocked at 1024 Hz; reset after 256 cycles (250 ms) without
/// [`feed`](Self::feed) once [`start`](Self::start)ed. Written here rather
/// than taken from the HAL because its `feed` writes CLEAR even while the
/// previous clear is still crossing into the 1 kHz clock domain, which stalls
/// the bus (and every interrupt) for milliseconds.
pub struct Watchdog {
    wdt: pac::Wdt,
}

impl Watchdog {
    /// Starts it; there is no stopping it short of a reset.
    pub fn start(&mut self) {
        self.wdt.config().write(|w| w.per()._256());
        while self.wdt.status().read().syncbusy().bit_is_set() {}
        self.wdt.ctrl().write(|w| w.enable().set_bit());
        while self.wdt.status().read().syncbusy().bit_is_set() {}
    }

    /// Restarts the countdown without waiting: skipped while the previous
    /// restart is still synchronising, which means it was at most ~3 ms ago.
    pub fn feed(&mut self) {
        if self.wdt.status().read().syncbusy().bit_is_clear() {
            self.wdt.clear().write(|w| w.clear().key());
        }
    }
}
