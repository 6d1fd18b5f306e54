//! When the board may move its 48 MHz clock onto the crystal: only in a quiet
//! window between two output frames.
//!
//! Every SERCOM's baud clock is the DFLL48M's output. Moving the DFLL's
//! reference (the SAMD21's internal 8 MHz oscillator at start, the 32.768 kHz
//! crystal once it runs) changes that output while the DFLL re-locks; done
//! while an SBUS byte is shifting out to the flight controller, the byte's
//! bit times change mid-byte. So the board switches only when
//! [`quiet_window`] says so: nothing of the flight controller's left to send
//! (queue empty, the UART's shift register empty) and the engine's next
//! deadline far enough away for the switch and the re-lock to finish.
//!
//! With a 7 ms output period and a 25-byte frame taking 3 ms at 100000 baud
//! 8E2, each period has a ~4 ms quiet gap; [`SAMD21_CRYSTAL_SWITCH`] is
//! shorter than that, so the first gap after the crystal is ready is used
//! (tested below with the real engine).

use crate::time::{Duration, Instant};

/// What the SAMD21 board's switch to the crystal takes, from its first
/// register write to the DFLL's fine lock on the crystal. Reasoned from the
/// SAM D21 datasheet (DS40001882), not measured:
///
/// - four GCLK writes (GENDIV, GENCTRL of the crystal's generator, CLKCTRL of
///   the DFLL's reference off and on), each waiting for `STATUS.SYNCBUSY`:
///   at most 6 periods of the slowest clock involved plus 3 APB periods
///   (§14.3.1.8 "Synchronization Delay"), i.e. 6 × 30.5 µs + 3 × 21 ns
///   ≈ 184 µs if the synchronisation runs at the crystal's 32.768 kHz:
///   ≤ 0.74 ms together;
/// - three DFLL writes (DFLLCTRL open loop, DFLLMUL, DFLLCTRL closed loop),
///   each after `PCLKSR.DFLLRDY` (errata: no DFLL write while not ready),
///   synchronised to the 48 MHz DFLL itself: a few µs;
/// - the fine lock on the new reference: the DFLL compares its output with
///   one reference period (30.5 µs) and moves DFLLVAL.FINE by at most
///   DFLLMUL.FSTEP per comparison, halving the step at each overshoot; the
///   datasheet's closed-loop characteristics give a lock time of at most
///   500 µs on a 32.768 kHz crystal starting from FINE = 512 with FSTEP = 10,
///   the step the board uses.
///
/// 0.74 + 0.5 ≈ 1.25 ms; 2 ms leaves margin for a loop pass between the
/// decision and the first write, and is still half the quiet gap of a 7 ms
/// period.
pub const SAMD21_CRYSTAL_SWITCH: Duration = Duration::from_millis(2);

/// Whether now is a safe moment to change the clock the flight controller's
/// UART runs on: its bytes are all out (`tx_idle`: nothing queued and the
/// UART's transmit-complete flag set) and the engine's next deadline
/// (`Multiplexer::poll_timeout`, which is never later than the next output
/// frame) is at least `needs` away. No deadline, or an overdue one, is never
/// quiet: the engine is late or has nothing to say, and either way the
/// moment is not known to be free.
pub fn quiet_window(
    now: Instant,
    next_deadline: Option<Instant>,
    tx_idle: bool,
    needs: Duration,
) -> bool {
    tx_idle
        && next_deadline.is_some_and(|due| due > now && due.saturating_duration_since(now) >= needs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Config, Mode};
    use crate::mux::Multiplexer;

    /// SBUS: 25 bytes of 12 bits (start, 8 data, parity, 2 stop) at 100000 baud.
    const FRAME_ON_WIRE: Duration = Duration::from_micros(25 * 120);

    fn us(n: u64) -> Instant {
        Instant::from_micros(n)
    }

    #[test]
    fn a_busy_uart_is_never_a_window() {
        let due = Some(us(10_000));
        assert!(!quiet_window(us(0), due, false, SAMD21_CRYSTAL_SWITCH));
        assert!(quiet_window(us(0), due, true, SAMD21_CRYSTAL_SWITCH));
    }

    #[test]
    fn a_deadline_closer_than_the_switch_needs_is_not_a_window() {
        let needs = SAMD21_CRYSTAL_SWITCH;
        let now = us(5_000);
        assert!(
            quiet_window(now, Some(now + needs), true, needs),
            "exactly enough"
        );
        assert!(!quiet_window(
            now,
            Some(now + needs - Duration::from_micros(1)),
            true,
            needs
        ));
        // Overdue or due now: the engine is late, not idle.
        assert!(!quiet_window(now, Some(now), true, needs));
        assert!(!quiet_window(now, Some(us(4_000)), true, needs));
        assert!(!quiet_window(now, None, true, needs));
    }

    /// The board's loop with the real engine under a virtual clock: every
    /// `step`, the engine's due work, its frame queued for a UART that takes
    /// [`FRAME_ON_WIRE`] to send it, and the window asked. Returns when the
    /// first window came, counted from `ready` (the crystal reporting ready).
    fn first_window(
        config: Config,
        ready: Instant,
        step: Duration,
        needs: Duration,
    ) -> Option<Duration> {
        let period = config.frame_period;
        let mut mux = Multiplexer::new(config, Instant::ZERO);
        let mut tx_busy_until = Instant::ZERO;
        let mut now = Instant::ZERO;
        let give_up = ready + period * 10;
        while now < give_up {
            if mux.poll_timeout().is_some_and(|due| now >= due) {
                mux.handle_timeout(now);
            }
            while mux.poll_transmit().is_some() {
                tx_busy_until = tx_busy_until.max(now) + FRAME_ON_WIRE;
            }
            while mux.poll_event().is_some() {}
            let tx_idle = now >= tx_busy_until;
            if now >= ready && quiet_window(now, mux.poll_timeout(), tx_idle, needs) {
                // The switch itself must end before the next frame is due.
                let due = mux.poll_timeout().expect("a window has a deadline");
                assert!(now + needs <= due);
                assert!(now >= tx_busy_until);
                return Some(now.saturating_duration_since(ready));
            }
            now += step;
        }
        None
    }

    #[test]
    fn a_window_comes_within_two_periods_whenever_the_crystal_gets_ready() {
        for mode in [Mode::Parallel, Mode::Scan] {
            for receivers in [1, 2, 6] {
                let config = Config::new(mode, receivers);
                let period = config.frame_period;
                assert_eq!(
                    period,
                    Duration::from_millis(7),
                    "the period this test is about"
                );
                // The crystal gets ready at every phase of the output period.
                for phase_us in (0..period.as_micros()).step_by(250) {
                    let ready = Instant::from_millis(2_000) + Duration::from_micros(phase_us);
                    // A loop pass every 50 µs (a busy loop at 48 MHz comes
                    // round far more often; slower passes only delay it).
                    let waited = first_window(
                        config.clone(),
                        ready,
                        Duration::from_micros(50),
                        SAMD21_CRYSTAL_SWITCH,
                    )
                    .unwrap_or_else(|| panic!("{mode:?} {receivers} rx: no window in 10 periods"));
                    assert!(
                        waited <= period * 2,
                        "{mode:?} {receivers} rx, ready at {phase_us} µs into a period: waited {waited:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_slower_output_period_leaves_windows_too() {
        let mut config = Config::new(Mode::Parallel, 2);
        config.frame_period = Duration::from_millis(14);
        let waited = first_window(
            config,
            Instant::from_millis(1_000),
            Duration::from_micros(50),
            SAMD21_CRYSTAL_SWITCH,
        )
        .expect("a window");
        assert!(waited <= Duration::from_millis(28), "{waited:?}");
    }

    #[test]
    fn a_switch_longer_than_the_quiet_gap_finds_no_window() {
        // 7 ms period - 3 ms on the wire = 4 ms: a switch needing more never
        // fits, which is what makes the bound above mean something.
        let config = Config::new(Mode::Parallel, 2);
        let needs = config.frame_period - FRAME_ON_WIRE + Duration::from_micros(100);
        let found = first_window(
            config,
            Instant::from_millis(1_000),
            Duration::from_micros(50),
            needs,
        );
        assert_eq!(found, None);
    }
}
