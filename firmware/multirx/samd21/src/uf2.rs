//! Quick boot behind the Arduino/Adafruit UF2 bootloader (the `uf2` layout).
//!
//! After every reset that is not a power-on (watchdog, panic, brown-out, reset
//! pin) that bootloader waits 500 ms for a second tap of the reset button,
//! unless the last RAM word holds its quick-boot value; then it clears the
//! word and starts the application at once (adafruit/uf2-samdx1: `inc/uf2.h`,
//! `DBL_TAP_PTR` = end of RAM − 4 and `DBL_TAP_MAGIC_QUICK_BOOT`; `src/main.c`,
//! `check_start_application`). Without the value every such reset would cost
//! the flight controller half a second of frames. `memory/uf2.x` keeps the
//! word out of the RAM the image and its stack use (`_uf2_double_tap`).
//!
//! When to write it is the core's decision
//! ([`multirx_core::boot::uf2_quick_boot_after`]): at once, except after a
//! reset-pin reset, so the bootloader's drive stays reachable by tapping the
//! button three times. The bare layout has no bootloader: [`QuickBoot`] does
//! nothing there.

use atsamd_hal::pac;
use multirx_core::boot::{ResetCause, uf2_quick_boot_after};
use multirx_core::{Duration, Instant};

/// The value that makes the bootloader start the application without waiting
/// (uf2-samdx1 `DBL_TAP_MAGIC_QUICK_BOOT`).
#[cfg(feature = "uf2")]
const QUICK_BOOT: u32 = 0xf026_69ef;

#[cfg(feature = "uf2")]
unsafe extern "C" {
    /// The bootloader's word, the last of RAM (defined in `memory/uf2.x`).
    static mut _uf2_double_tap: u32;
}

/// Writes the quick-boot value when it is due.
pub struct QuickBoot {
    /// Still to wait, counted from the first [`QuickBoot::poll`] (the timer
    /// does not run yet at reset).
    wait: Option<Duration>,
    due: Option<Instant>,
}

impl QuickBoot {
    /// First thing after reset, before the clocks: reads why the chip reset
    /// and writes the value at once unless the core says to wait.
    pub fn at_reset() -> Self {
        if !cfg!(feature = "uf2") {
            return QuickBoot {
                wait: None,
                due: None,
            };
        }
        // SAFETY: a read of PM.RCAUSE, a read-only register; `Board::new`
        // reads it again through the owned peripheral.
        let pm = unsafe { &*pac::Pm::ptr() };
        let cause = ResetCause::from_samd21_rcause(pm.rcause().read().bits());
        let wait = uf2_quick_boot_after(cause);
        if wait == Duration::ZERO {
            write_quick_boot();
            QuickBoot {
                wait: None,
                due: None,
            }
        } else {
            QuickBoot {
                wait: Some(wait),
                due: None,
            }
        }
    }

    /// Writes the value once its wait, counted from the first call, is over.
    pub fn poll(&mut self, now: Instant) {
        if let Some(wait) = self.wait.take() {
            self.due = Some(now + wait);
        }
        if self.due.is_some_and(|due| now >= due) {
            self.due = None;
            write_quick_boot();
        }
    }
}

#[cfg(feature = "uf2")]
fn write_quick_boot() {
    // SAFETY: the word is outside every section and the stack (memory/uf2.x);
    // nothing else in this image touches it, and a volatile write of an
    // aligned u32 is a single store.
    unsafe { core::ptr::write_volatile(&raw mut _uf2_double_tap, QUICK_BOOT) };
}

#[cfg(not(feature = "uf2"))]
fn write_quick_boot() {}
