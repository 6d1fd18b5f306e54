//! When the board may feed its watchdog: only while the engine keeps its
//! deadlines **and** the flight controller's bytes actually leave. Feeding on
//! the engine alone kept a board with a wedged TX (a UART that stopped taking
//! bytes) alive and silent forever; a reset restarts the UART and the frames.
//!
//! The board tells [`FeedGate::note_tx`] after each pass how many bytes left
//! for the flight controller and how many still wait; bytes that wait a whole
//! output period without one leaving mean the TX is wedged (at SBUS's 100000
//! baud a 25-byte frame leaves in 3 ms, well inside a 7 or 14 ms period).

use crate::config::Config;
use crate::time::{Duration, Instant};

/// Decides whether this pass may feed the watchdog.
#[derive(Debug, Clone)]
pub struct FeedGate {
    /// How long bytes may wait with none leaving: one output period.
    stall_limit: Duration,
    /// Since when bytes have waited with none leaving.
    stalled_since: Option<Instant>,
}

impl FeedGate {
    pub fn new(config: &Config) -> Self {
        FeedGate {
            stall_limit: config.frame_period,
            stalled_since: None,
        }
    }

    /// After a pass at `now`: `sent` bytes left for the flight controller in
    /// it, `queued` still wait for its UART.
    pub fn note_tx(&mut self, now: Instant, sent: usize, queued: usize) {
        if queued == 0 || sent > 0 {
            self.stalled_since = (queued > 0).then_some(now);
        } else if self.stalled_since.is_none() {
            self.stalled_since = Some(now);
        }
    }

    /// Whether to feed the watchdog at `now`, given the engine's next
    /// deadline (`Multiplexer::poll_timeout`): none overdue, and the
    /// flight controller's bytes moving.
    pub fn may_feed(&self, now: Instant, engine_due: Option<Instant>) -> bool {
        let on_time = engine_due.is_some_and(|due| now < due);
        let moving = self
            .stalled_since
            .is_none_or(|since| now - since <= self.stall_limit);
        on_time && moving
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Mode;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    #[test]
    fn a_wedged_tx_stops_the_feeding_and_a_moving_one_does_not() {
        let config = Config::new(Mode::Parallel, 2);
        let period = config.frame_period;
        let mut gate = FeedGate::new(&config);
        let due = |now: Instant| Some(now + Duration::from_millis(1));

        // Healthy: each frame queued, drained over a few passes.
        gate.note_tx(ms(0), 4, 21);
        assert!(gate.may_feed(ms(0), due(ms(0))));
        gate.note_tx(ms(1), 21, 0);
        assert!(gate.may_feed(ms(1), due(ms(1))));
        // Idle between frames: nothing waits, nothing to send.
        gate.note_tx(ms(5), 0, 0);
        assert!(gate.may_feed(ms(5), due(ms(5))));

        // Wedged: bytes wait and none leave, pass after pass.
        gate.note_tx(ms(7), 0, 25);
        let mut now = ms(7);
        while now - ms(7) <= period {
            assert!(gate.may_feed(now, due(now)), "fed until a period passed");
            now += Duration::from_millis(1);
            gate.note_tx(now, 0, 50);
        }
        assert!(!gate.may_feed(now, due(now)), "a wedged TX is still fed");
        // A byte leaving again lets it feed.
        gate.note_tx(now, 1, 49);
        assert!(gate.may_feed(now, due(now)));
    }

    #[test]
    fn an_overdue_engine_is_never_fed() {
        let gate = FeedGate::new(&Config::new(Mode::Scan, 2));
        assert!(!gate.may_feed(ms(10), Some(ms(10))));
        assert!(!gate.may_feed(ms(10), Some(ms(9))));
        assert!(!gate.may_feed(ms(10), None));
        assert!(gate.may_feed(ms(10), Some(ms(11))));
    }
}
