//! Loss over a sliding time window, from cumulative counters sampled as they change.

use std::collections::VecDeque;

use crate::time::{Duration, Instant};

/// Share of frames lost over the last `window`, from cumulative (received, lost) counters.
///
/// The estimate spans from the newest sample at least `window` old (or the oldest one kept)
/// to the newest sample, so it covers at least the window once enough history exists, and a
/// loss leaves it one window after it was counted.
#[derive(Debug, Clone)]
pub struct LossWindow {
    window: Duration,
    /// (when, received, lost), cumulative and unwrapped, oldest first.
    samples: VecDeque<(Instant, u64, u64)>,
}

impl LossWindow {
    /// An empty window of `window`.
    pub fn new(window: Duration) -> Self {
        Self {
            window,
            samples: VecDeque::new(),
        }
    }

    /// Records the cumulative counters at `now`; a sample equal to the last is not kept.
    pub fn push(&mut self, now: Instant, received: u64, lost: u64) {
        if let Some(&(_, r, l)) = self.samples.back()
            && (r, l) == (received, lost)
        {
            return;
        }
        self.samples.push_back((now, received, lost));
        // Keep one sample at or before the window's start, drop older ones.
        let start = window_start(now, self.window);
        while let (Some(start), Some(&(second, ..))) = (start, self.samples.get(1))
            && second <= start
        {
            self.samples.pop_front();
        }
    }

    /// Lost / (received + lost) over the window as of `now`; `None` when nothing was counted.
    pub fn estimate(&self, now: Instant) -> Option<f64> {
        let &(_, r1, l1) = self.samples.back()?;
        let start = window_start(now, self.window);
        // The newest sample at or before the start, else the oldest one.
        let base = self
            .samples
            .iter()
            .rev()
            .find(|(t, ..)| start.is_some_and(|s| *t <= s))
            .or(self.samples.front())?;
        let (received, lost) = (r1 - base.1, l1 - base.2);
        let total = received + lost;
        (total > 0).then(|| lost as f64 / total as f64)
    }

    /// The first moment after `now` at which [`estimate`](Self::estimate) can change with no
    /// new sample: when the window's start passes the next sample after the current base.
    /// `None`: only a new sample can change it.
    pub fn next_change(&self, now: Instant) -> Option<Instant> {
        let start = window_start(now, self.window);
        self.samples
            .iter()
            .skip(1)
            .map(|(t, ..)| *t)
            .find(|t| start.is_none_or(|s| *t > s))
            .map(|t| t + self.window)
    }

    /// Frames (received + lost) counted within the estimate's span as of `now`.
    pub fn events(&self, now: Instant) -> u64 {
        let Some(&(_, r1, l1)) = self.samples.back() else {
            return 0;
        };
        let start = window_start(now, self.window);
        let base = self
            .samples
            .iter()
            .rev()
            .find(|(t, ..)| start.is_some_and(|s| *t <= s))
            .or(self.samples.front());
        base.map_or(0, |b| (r1 - b.1) + (l1 - b.2))
    }
}

/// `now - window`, or `None` before the clock has run that long.
fn window_start(now: Instant, window: Duration) -> Option<Instant> {
    now.since_epoch()
        .checked_sub(window)
        .map(|d| Instant::from_micros(d.as_micros()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    #[test]
    fn next_change_is_when_the_start_passes_the_next_sample() {
        let mut w = LossWindow::new(Duration::from_millis(1000));
        assert_eq!(w.next_change(at(0)), None);
        w.push(at(100), 10, 0);
        // One sample: it stays the base whatever the time.
        assert_eq!(w.next_change(at(150)), None);
        w.push(at(300), 10, 5);
        w.push(at(600), 20, 5);
        assert_eq!(w.next_change(at(700)), Some(at(1300)));
        // Checked against the estimate itself: unchanged just before, changed at the time.
        let before = w.estimate(at(1299));
        assert_ne!(w.estimate(at(1300)), before);
        assert_eq!(w.next_change(at(1300)), Some(at(1600)));
        assert_ne!(w.estimate(at(1600)), w.estimate(at(1599)));
        // Past the last sample's window nothing changes any more.
        assert_eq!(w.next_change(at(1600)), None);
        assert_eq!(w.estimate(at(5000)), w.estimate(at(1600)));
    }

    #[test]
    fn estimate_covers_the_window_and_forgets_old_loss() {
        let mut w = LossWindow::new(Duration::from_secs(4));
        assert_eq!(w.estimate(at(0)), None);
        w.push(at(0), 0, 0);
        w.push(at(1_000), 8, 0);
        w.push(at(2_000), 8, 2); // two lost
        assert_eq!(w.estimate(at(2_000)), Some(0.2));
        w.push(at(5_000), 16, 2);
        // base: the sample at 1 s (newest at or before 5 - 4 = 1 s): 8 received, 2 lost
        assert_eq!(w.estimate(at(5_000)), Some(0.2));
        w.push(at(7_000), 24, 2);
        // base: 2 s (8, 2) → 16 received, 0 lost
        assert_eq!(w.estimate(at(7_000)), Some(0.0));
        assert_eq!(w.events(at(7_000)), 16);
    }

    #[test]
    fn nothing_counted_is_no_estimate() {
        let mut w = LossWindow::new(Duration::from_secs(4));
        w.push(at(0), 5, 1);
        assert_eq!(w.estimate(at(10_000)), None);
        w.push(at(10_000), 5, 1);
        assert_eq!(w.estimate(at(10_000)), None);
    }
}
