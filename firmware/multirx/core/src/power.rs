//! Receiver power-on, staggered: every receiver switched on in the same pass
//! draws its inrush current from the shared rail at the same instant, and a
//! rail that sags below the brown-out level resets the board (and with it
//! every receiver). The engine decides *whether* a receiver is powered; this
//! decides *when* the switch closes: switch-offs at once, switch-ons at least
//! [`POWER_ON_STAGGER`] apart, in the order they were asked for.
//!
//! Sans-IO like the engine: `now` is an argument, [`PowerSequencer::poll_timeout`]
//! says when the next switch-on is due.

use crate::config::MAX_RECEIVERS;
use crate::time::{Duration, Instant};

/// Between two receiver switch-ons: a receiver's inrush (charging its input
/// capacitance, typically 10–100 µF at 5 V) settles within a few milliseconds;
/// 20 ms leaves margin and still powers six receivers within 100 ms, well
/// inside a receiver's own boot time (hundreds of milliseconds).
pub const POWER_ON_STAGGER: Duration = Duration::from_millis(20);

/// Switch changes waiting for their turn.
#[derive(Debug, Clone)]
pub struct PowerSequencer {
    /// Per receiver: the state asked for and not yet applied.
    pending: [Option<bool>; MAX_RECEIVERS],
    /// Order in which receivers asked to be switched on.
    queue: heapless::Deque<u8, MAX_RECEIVERS>,
    last_on: Option<Instant>,
    stagger: Duration,
}

impl PowerSequencer {
    pub fn new(stagger: Duration) -> Self {
        PowerSequencer {
            pending: [None; MAX_RECEIVERS],
            queue: heapless::Deque::new(),
            last_on: None,
            stagger,
        }
    }

    /// The engine wants receiver `rx` powered (`on`) or not; a later request
    /// for the same receiver replaces an earlier one still waiting.
    pub fn request(&mut self, rx: u8, on: bool) {
        let Some(slot) = self.pending.get_mut(usize::from(rx)) else {
            return;
        };
        *slot = Some(on);
        if on && !self.queue.iter().any(|&q| q == rx) {
            // Room for every receiver: each is queued at most once.
            let _ = self.queue.push_back(rx);
        }
    }

    /// The next switch change to apply at `now`, if one is due.
    pub fn poll(&mut self, now: Instant) -> Option<(u8, bool)> {
        if let Some(rx) = (0..MAX_RECEIVERS).find(|&i| self.pending[i] == Some(false)) {
            self.pending[rx] = None;
            return Some((rx as u8, false));
        }
        // Drop queue entries whose request was withdrawn (switched off meanwhile).
        while let Some(&rx) = self.queue.front() {
            if self.pending[usize::from(rx)] == Some(true) {
                break;
            }
            self.queue.pop_front();
        }
        let &rx = self.queue.front()?;
        if self.last_on.is_some_and(|t| now < t + self.stagger) {
            return None;
        }
        self.queue.pop_front();
        self.pending[usize::from(rx)] = None;
        self.last_on = Some(now);
        Some((rx, true))
    }

    /// When [`Self::poll`] next has something, if anything waits.
    pub fn poll_timeout(&self) -> Option<Instant> {
        if self.pending.contains(&Some(false)) {
            return Some(Instant::ZERO);
        }
        self.queue
            .iter()
            .any(|&rx| self.pending[usize::from(rx)] == Some(true))
            .then(|| self.last_on.map_or(Instant::ZERO, |t| t + self.stagger))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drain(s: &mut PowerSequencer, now: Instant) -> Vec<(u8, bool)> {
        core::iter::from_fn(|| s.poll(now)).collect()
    }

    #[test]
    fn switch_ons_are_staggered_in_request_order() {
        let mut s = PowerSequencer::new(POWER_ON_STAGGER);
        for rx in [2, 0, 1] {
            s.request(rx, true);
        }
        let t0 = Instant::from_millis(5);
        assert_eq!(drain(&mut s, t0), [(2, true)]);
        assert_eq!(s.poll_timeout(), Some(t0 + POWER_ON_STAGGER));
        assert_eq!(drain(&mut s, t0 + Duration::from_millis(19)), []);
        assert_eq!(drain(&mut s, t0 + POWER_ON_STAGGER), [(0, true)]);
        let t2 = t0 + POWER_ON_STAGGER + POWER_ON_STAGGER;
        assert_eq!(drain(&mut s, t2), [(1, true)]);
        assert_eq!(s.poll_timeout(), None);
    }

    #[test]
    fn switch_offs_are_never_held_back() {
        let mut s = PowerSequencer::new(POWER_ON_STAGGER);
        s.request(0, true);
        s.request(1, true);
        let t0 = Instant::from_millis(1);
        assert_eq!(drain(&mut s, t0), [(0, true)]);
        s.request(0, false);
        assert_eq!(s.poll_timeout(), Some(Instant::ZERO));
        assert_eq!(drain(&mut s, t0), [(0, false)]);
    }

    #[test]
    fn a_withdrawn_switch_on_never_happens() {
        // Scan mode moving on before a receiver's turn came.
        let mut s = PowerSequencer::new(POWER_ON_STAGGER);
        s.request(0, true);
        s.request(1, true);
        let t0 = Instant::from_millis(1);
        assert_eq!(drain(&mut s, t0), [(0, true)]);
        s.request(1, false);
        s.request(2, true);
        let later = t0 + POWER_ON_STAGGER;
        assert_eq!(drain(&mut s, later), [(1, false), (2, true)]);
        assert_eq!(s.poll_timeout(), None);
    }

    #[test]
    fn out_of_range_receivers_are_ignored() {
        let mut s = PowerSequencer::new(POWER_ON_STAGGER);
        s.request(MAX_RECEIVERS as u8, true);
        assert_eq!(s.poll_timeout(), None);
        assert_eq!(drain(&mut s, Instant::from_millis(1)), []);
    }
}
