//! Reset to 48 MHz without waiting for the crystal, watchdog first.
//!
//! The HAL's `GenericClockController::with_external_32kosc` waits for the
//! 32.768 kHz crystal (its start-up setting alone is 2 s) before anything
//! runs: no SBUS output for ~2 s after every cold start or brown-out, while
//! PX4 declares RC loss after 0.5 s. Here, in order:
//!
//! 1. [`start_watchdog`]: 250 ms from OSCULP32K, before any clock is touched,
//!    so a DFLL that never becomes ready resets the chip instead of hanging;
//!    clocked at the full 32,768 Hz so that its two register
//!    synchronisations at reset take ~0.4 ms rather than ~12 ms (they happen
//!    before the timer `first-frame-us` counts from starts);
//! 2. [`brown_out`]: BOD33 resets the chip below ~2.77 V (48 MHz needs
//!    VDD >= 2.7 V; the fuse default of ~1.7 V lets a sagging rail run
//!    corrupted code);
//! 3. [`start`]: the DFLL48M in closed loop on OSC8M / 256 (31.25 kHz, the
//!    internal 8 MHz RC oscillator: ready in microseconds, about ±2 % over
//!    temperature, inside what SBUS tolerates for the few hundred
//!    milliseconds it is used) and the crystal started without waiting;
//! 4. [`CrystalSwitch::poll`], on loop passes between output frames (the
//!    core's [`multirx_core::clock_switch::quiet_window`]): once the crystal
//!    is ready, the DFLL's reference moves to it, in open loop (the DFLL
//!    holds its frequency) while the reference and multiplier change, then
//!    back to closed loop with a small fine step, so the re-lock moves the
//!    48 MHz of every UART gradually. A dead crystal leaves the board on the
//!    internal reference instead of spinning for ever.
//!
//! No GCLK software reset (the HAL's controllers do one): it would stop the
//! watchdog's clock. Register-level because no HAL constructor does this
//! order; each register is named as in the SAM D21 datasheet.

use atsamd_hal::pac;

/// Generator for the watchdog: OSCULP32K undivided, 32,768 Hz.
const GEN_WDT: u8 = 2;
/// Generator the DFLL starts on: OSC8M / 256 = 31.25 kHz.
const GEN_DFLL_START: u8 = 5;
/// Generator for the crystal, the DFLL's reference once it is ready.
const GEN_CRYSTAL: u8 = 1;
/// Generator for TC4+TC5: DFLL48M / 6 = 8 MHz.
const GEN_TIMER: u8 = 3;

/// DFLL multiplier on OSC8M / 256: 48 MHz / 31.25 kHz.
const MUL_OSC8M: u16 = 1536;
/// DFLL multiplier on the crystal: 48 MHz / 32.768 kHz, rounded (48.005 MHz).
const MUL_CRYSTAL: u16 = 1465;
/// DFLLMUL.FSTEP at start: the DFLL starts from FINE = 512, wherever the
/// lock is, and nothing is being sent yet, so the fastest lock wins.
const FSTEP_START: u16 = 63;
/// DFLLMUL.FSTEP on the crystal: the largest move of DFLLVAL.FINE per
/// comparison with the reference (one 30.5 µs crystal period), halved at
/// each overshoot (datasheet, DFLL48M "Closed-loop operation" and DFLLMUL).
/// 10 is the step the datasheet's DFLL48M closed-loop characteristics give
/// the lock time for (at most 500 µs on a 32.768 kHz crystal); a sixth of
/// the start's 63, so a byte of 120 µs (4 comparisons) sees at most 40 fine
/// steps of drift instead of 252.
const FSTEP_CRYSTAL: u16 = 10;
/// DFLLMUL.CSTEP: unused while the coarse lock is bypassed (BPLCKC), kept
/// within the datasheet's "at most 50 % of the COARSE range".
const CSTEP: u8 = 7;

/// BOD33.LEVEL 39: 2.74–2.80 V falling threshold (SAM D21 datasheet,
/// electrical characteristics, BOD33), above the 2.7 V the 48 MHz operating
/// range needs.
const BOD33_LEVEL: u8 = 39;

/// CPU and SERCOM clock (GCLK0) in Hz.
pub const CPU_HZ: u32 = 48_000_000;
/// TC4+TC5's clock in Hz.
pub const TIMER_HZ: u32 = 8_000_000;

fn sync(gclk: &pac::Gclk) {
    while gclk.status().read().syncbusy().bit_is_set() {}
}

fn dfll_ready(sysctrl: &pac::Sysctrl) {
    while sysctrl.pclksr().read().dfllrdy().bit_is_clear() {}
}

/// Starts the watchdog: 8,192 cycles of 32,768 Hz (250 ms). First thing
/// after reset.
///
/// Undivided on purpose: a WDT register write waits for its synchronisation,
/// at most 6 periods of the watchdog's clock plus 3 of the bus (SAM D21
/// datasheet, 14.3.1.8 "Synchronization Delay"): 6 × 30.5 µs ≈ 0.19 ms at
/// 32,768 Hz, where OSCULP32K / 32 made it 6 × 977 µs ≈ 5.9 ms. Two of them
/// (CONFIG, CTRL) happen here, before the timer `first-frame-us` counts from.
pub fn start_watchdog(gclk: &pac::Gclk, wdt: &pac::Wdt) {
    // SAFETY (all `bits` below): values are in the fields' documented ranges.
    // GENDIV.DIV 0 (with GENCTRL.DIVSEL 0): the source undivided.
    gclk.gendiv()
        .write(|w| unsafe { w.id().bits(GEN_WDT).div().bits(0) });
    sync(gclk);
    gclk.genctrl().write(|w| unsafe {
        w.id().bits(GEN_WDT);
        w.src().osculp32k();
        w.divsel().clear_bit();
        w.genen().set_bit()
    });
    sync(gclk);
    gclk.clkctrl().write(|w| {
        w.id().wdt();
        w.r#gen().gclk2();
        w.clken().set_bit()
    });
    sync(gclk);
    // CONFIG is enable-protected: a watchdog still running with another
    // period (one this generator now runs 32 times faster) is stopped first,
    // unless the fuses made it always-on (then it cannot be changed).
    let ours = wdt.config().read().per().is_8k();
    let running = wdt.ctrl().read().enable().bit_is_set();
    if running && ours {
        return;
    }
    if running && wdt.ctrl().read().alwayson().bit_is_clear() {
        wdt.ctrl().write(|w| w.enable().clear_bit());
        while wdt.status().read().syncbusy().bit_is_set() {}
    }
    // CONFIG.PER 0xA: 8K clock cycles = 8192 / 32768 Hz = 250 ms.
    wdt.config().write(|w| w.per()._8k());
    while wdt.status().read().syncbusy().bit_is_set() {}
    wdt.ctrl().write(|w| w.enable().set_bit());
    while wdt.status().read().syncbusy().bit_is_set() {}
}

/// BOD33: reset (not just flag) below [`BOD33_LEVEL`], with hysteresis so
/// a rail hovering at the threshold does not chatter.
pub fn brown_out(sysctrl: &pac::Sysctrl) {
    // LEVEL may only change while BOD33 is disabled (the fuses enable it at
    // ~1.7 V): disable, wait, set, enable.
    sysctrl.bod33().modify(|_, w| w.enable().clear_bit());
    while sysctrl.pclksr().read().b33srdy().bit_is_clear() {}
    sysctrl.bod33().write(|w| unsafe {
        w.level().bits(BOD33_LEVEL);
        w.action().reset();
        w.hyst().set_bit()
    });
    while sysctrl.pclksr().read().b33srdy().bit_is_clear() {}
    sysctrl.bod33().modify(|_, w| w.enable().set_bit());
    while sysctrl.pclksr().read().b33srdy().bit_is_clear() {}
}

/// Why the chip last reset, as `PM.RCAUSE`'s bits.
pub fn reset_cause_bits(pm: &pac::Pm) -> u8 {
    pm.rcause().read().bits()
}

/// 48 MHz on the internal reference, the crystal starting in the background.
/// Returns the switch that moves the DFLL to the crystal once it is ready.
pub fn start(
    gclk: pac::Gclk,
    sysctrl: pac::Sysctrl,
    nvmctrl: &pac::Nvmctrl,
    pm: &pac::Pm,
) -> CrystalSwitch {
    // One flash wait state at 48 MHz and 3.3 V; no writes through pointers.
    nvmctrl
        .ctrlb()
        .modify(|_, w| w.rws().half().manw().set_bit());

    // OSC8M at 8 MHz (reset: /8), always on.
    sysctrl.osc8m().modify(|_, w| {
        w.presc()._0();
        w.ondemand().clear_bit()
    });
    while sysctrl.pclksr().read().osc8mrdy().bit_is_clear() {}

    // The crystal: started, not waited for.
    sysctrl.xosc32k().write(|w| unsafe {
        w.startup().bits(6);
        w.ondemand().clear_bit();
        w.en32k().set_bit();
        w.xtalen().set_bit();
        w.runstdby().set_bit()
    });
    sysctrl.xosc32k().modify(|_, w| w.enable().set_bit());

    // DFLL reference: OSC8M / 256 (DIVSEL: 2^(7+1)).
    gclk.gendiv()
        .write(|w| unsafe { w.id().bits(GEN_DFLL_START).div().bits(7) });
    sync(&gclk);
    gclk.genctrl().write(|w| unsafe {
        w.id().bits(GEN_DFLL_START);
        w.src().osc8m();
        w.divsel().set_bit();
        w.genen().set_bit()
    });
    sync(&gclk);
    gclk.clkctrl().write(|w| {
        w.id().dfll48();
        w.r#gen().gclk5();
        w.clken().set_bit()
    });
    sync(&gclk);

    // DFLL48M, closed loop, starting from the factory coarse value so its
    // output is near 48 MHz at once (coarse lock bypassed), fine lock
    // running. Errata: ONDEMAND cleared and DFLLRDY awaited before any write.
    sysctrl.dfllctrl().write(|w| w.ondemand().clear_bit());
    dfll_ready(&sysctrl);
    let coarse = atsamd_hal::calibration::dfll48m_coarse_cal();
    sysctrl
        .dfllval()
        .write(|w| unsafe { w.coarse().bits(coarse).fine().bits(512) });
    dfll_ready(&sysctrl);
    sysctrl.dfllmul().write(|w| unsafe {
        w.cstep().bits(CSTEP);
        w.fstep().bits(FSTEP_START);
        w.mul().bits(MUL_OSC8M)
    });
    dfll_ready(&sysctrl);
    sysctrl.dfllctrl().write(|w| {
        w.ondemand().clear_bit();
        w.mode().set_bit();
        w.bplckc().set_bit()
    });
    dfll_ready(&sysctrl);
    sysctrl.dfllctrl().modify(|_, w| w.enable().set_bit());
    dfll_ready(&sysctrl);

    // GCLK0 (CPU, buses, SERCOMs) on the DFLL.
    gclk.gendiv()
        .write(|w| unsafe { w.id().bits(0).div().bits(1) });
    sync(&gclk);
    gclk.genctrl().write(|w| unsafe {
        w.id().bits(0);
        w.src().dfll48m();
        w.idc().set_bit();
        w.genen().set_bit()
    });
    sync(&gclk);
    pm.cpusel().write(|w| w.cpudiv().div1());
    pm.apbasel().write(|w| w.apbadiv().div1());
    pm.apbbsel().write(|w| w.apbbdiv().div1());
    pm.apbcsel().write(|w| w.apbcdiv().div1());

    // TC4+TC5 at 8 MHz.
    gclk.gendiv()
        .write(|w| unsafe { w.id().bits(GEN_TIMER).div().bits(6) });
    sync(&gclk);
    gclk.genctrl().write(|w| unsafe {
        w.id().bits(GEN_TIMER);
        w.src().dfll48m();
        w.genen().set_bit()
    });
    sync(&gclk);
    gclk.clkctrl().write(|w| {
        w.id().tc4_tc5();
        w.r#gen().gclk3();
        w.clken().set_bit()
    });
    sync(&gclk);

    // Every SERCOM's core clock on GCLK0.
    for id in 0..6u8 {
        gclk.clkctrl().write(|w| {
            match id {
                0 => w.id().sercom0_core(),
                1 => w.id().sercom1_core(),
                2 => w.id().sercom2_core(),
                3 => w.id().sercom3_core(),
                4 => w.id().sercom4_core(),
                _ => w.id().sercom5_core(),
            };
            w.r#gen().gclk0();
            w.clken().set_bit()
        });
        sync(&gclk);
    }

    CrystalSwitch {
        gclk,
        sysctrl,
        on_crystal: false,
    }
}

/// Moves the DFLL's reference to the crystal once it is ready.
pub struct CrystalSwitch {
    gclk: pac::Gclk,
    sysctrl: pac::Sysctrl,
    on_crystal: bool,
}

impl CrystalSwitch {
    /// Whether the switch is still to come: the loop asks the core for a
    /// quiet window only while it is.
    pub fn pending(&self) -> bool {
        !self.on_crystal
    }

    /// Switches to the crystal if it has become ready; returns true on the
    /// pass it switched. Call it only in a quiet window between output
    /// frames ([`multirx_core::clock_switch::quiet_window`] with
    /// [`multirx_core::clock_switch::SAMD21_CRYSTAL_SWITCH`], which is what
    /// this takes at most, reasoned from the datasheet). Never waits for the
    /// crystal.
    pub fn poll(&mut self) -> bool {
        if self.on_crystal || self.sysctrl.pclksr().read().xosc32krdy().bit_is_clear() {
            return false;
        }
        let (gclk, sysctrl) = (&self.gclk, &self.sysctrl);
        // The crystal's generator: touches nothing that runs yet.
        gclk.gendiv()
            .write(|w| unsafe { w.id().bits(GEN_CRYSTAL).div().bits(1) });
        sync(gclk);
        gclk.genctrl().write(|w| unsafe {
            w.id().bits(GEN_CRYSTAL);
            w.src().xosc32k();
            w.genen().set_bit()
        });
        sync(gclk);

        // Open loop: DFLLCTRL.MODE cleared, the output set by DFLLVAL alone.
        // Its value is read first and written back in open loop (and again
        // after DFLLMUL, whose write the datasheet says loses the locks), so
        // the 48 MHz stays where the closed loop had it while the reference
        // and the multiplier change. In closed loop DFLLVAL reads the tuner's
        // current value only after DFLLSYNC.READREQ and DFLLRDY. Errata:
        // DFLLRDY before every DFLL access.
        dfll_ready(sysctrl);
        sysctrl.dfllsync().write(|w| w.readreq().set_bit());
        dfll_ready(sysctrl);
        let held = sysctrl.dfllval().read();
        let (coarse, fine) = (held.coarse().bits(), held.fine().bits());
        let hold = || {
            dfll_ready(sysctrl);
            sysctrl
                .dfllval()
                .write(|w| unsafe { w.coarse().bits(coarse).fine().bits(fine) });
            dfll_ready(sysctrl);
        };
        dfll_ready(sysctrl);
        sysctrl.dfllctrl().modify(|_, w| w.mode().clear_bit());
        hold();

        // Reference off, the crystal's multiplier and a small fine step,
        // then the crystal's generator as the reference.
        gclk.clkctrl().write(|w| {
            w.id().dfll48();
            w.r#gen().gclk5();
            w.clken().clear_bit()
        });
        sync(gclk);
        dfll_ready(sysctrl);
        sysctrl.dfllmul().write(|w| unsafe {
            w.cstep().bits(CSTEP);
            w.fstep().bits(FSTEP_CRYSTAL);
            w.mul().bits(MUL_CRYSTAL)
        });
        hold();
        gclk.clkctrl().write(|w| {
            w.id().dfll48();
            w.r#gen().gclk1();
            w.clken().set_bit()
        });
        sync(gclk);

        // Closed loop again (coarse lock still bypassed, BPLCKC): the fine
        // lock starts from the held value and moves at most FSTEP_CRYSTAL
        // fine steps per crystal period.
        dfll_ready(sysctrl);
        sysctrl.dfllctrl().modify(|_, w| w.mode().set_bit());
        dfll_ready(sysctrl);
        self.on_crystal = true;
        true
    }
}
