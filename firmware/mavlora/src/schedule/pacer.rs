//! Pacing the radio budget by the radio's own word: a SiK radio (and RFD900, mLRS) reports
//! the free share of its transmit buffer (`txbuf` in `RADIO_STATUS`) about once a second.
//! A configured rate is the radio's nominal one; its real throughput can be half of it
//! (ECC on, a busy channel, a lower air rate than configured), and then whatever the budget
//! offers above it fills the radio's buffer until the radio drops bytes, whole frames lost
//! where nobody counts them.
//!
//! [`TxbufPacer`] is additive increase, multiplicative decrease on that report, with the
//! thresholds ArduPilot paces its streams by (`GCS_MAVLINK::handle_radio_status`): below 20 %
//! free it halves the rate, below 50 % it takes a quarter off, above 95 % it adds 1/16 of the
//! configured rate and above 90 % 1/64; in between it holds. The configured rate stays the
//! ceiling and stands until the radio's first report: a radio that reports nothing keeps
//! the configured budget (a slow start for everyone cost a LoRa link, which reports nothing,
//! a second-long gap in positions at every start). The first report that shows the buffer
//! filling (below 90 % free) halves the rate at once: at twice the real throughput the
//! buffer (1.85 KB on SiK) would overflow within the second to the next report, and a
//! quarter off would still be above the real rate.

/// The budget's rate, paced by the radio's free transmit buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TxbufPacer {
    ceiling: u32,
    floor: u32,
    rate: u32,
    reports: u64,
}

/// The least the pacer goes down to, as a share of the configured rate: a sixteenth still
/// carries commands and acks, and a radio whose buffer stays full below it is broken.
const FLOOR_DIVISOR: u32 = 16;

impl TxbufPacer {
    /// Paces a budget configured at `ceiling` bytes per second.
    pub fn new(ceiling: u32) -> Self {
        Self {
            ceiling,
            floor: (ceiling / FLOOR_DIVISOR).max(1),
            rate: ceiling,
            reports: 0,
        }
    }

    /// The rate the budget should run at now, bytes per second.
    pub fn rate(&self) -> u32 {
        self.rate
    }

    /// Reports taken.
    pub fn reports(&self) -> u64 {
        self.reports
    }

    /// The radio reported `txbuf_pct` % of its transmit buffer free; returns the new rate
    /// when it changed.
    pub fn handle_txbuf(&mut self, txbuf_pct: u8) -> Option<u32> {
        self.reports += 1;
        let rate = self.rate;
        let next = match txbuf_pct {
            // The first sign of a radio slower than configured.
            0..=89 if self.reports == 1 => rate / 2,
            0..20 => rate / 2,
            20..50 => rate - rate / 4,
            91..=95 => rate.saturating_add(self.ceiling / 64),
            96.. => rate.saturating_add(self.ceiling / 16),
            _ => rate,
        }
        .clamp(self.floor, self.ceiling);
        self.rate = next;
        (next != rate).then_some(next)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nothing_reported_keeps_the_configured_rate() {
        assert_eq!(TxbufPacer::new(4000).rate(), 4000);
    }

    #[test]
    fn a_first_report_of_a_filling_buffer_halves_the_rate_at_once() {
        let mut p = TxbufPacer::new(4000);
        assert_eq!(p.handle_txbuf(70), Some(2000));
        assert_eq!(p.handle_txbuf(70), None, "then held between 50 and 90 %");
    }

    #[test]
    fn a_free_buffer_keeps_the_ceiling_and_climbs_back_to_it() {
        let mut p = TxbufPacer::new(4000);
        assert_eq!(p.handle_txbuf(100), None, "never above the ceiling");
        assert_eq!(p.handle_txbuf(10), Some(2000));
        let mut reports = 0;
        while p.rate() < 4000 {
            p.handle_txbuf(100);
            reports += 1;
        }
        assert_eq!(
            reports, 8,
            "half to full in 1/16 steps: 8 reports (about 8 s)"
        );
    }

    #[test]
    fn a_filling_buffer_cuts_the_rate_harder_the_fuller_it_is() {
        let mut p = TxbufPacer::new(4000);
        assert_eq!(p.handle_txbuf(95), None);
        assert_eq!(p.handle_txbuf(40), Some(3000));
        assert_eq!(p.handle_txbuf(10), Some(1500));
        for _ in 0..10 {
            p.handle_txbuf(0);
        }
        assert_eq!(p.rate(), 250, "the floor: a sixteenth");
    }

    #[test]
    fn a_nearly_free_buffer_creeps_up_slowly() {
        let mut p = TxbufPacer::new(6400);
        p.handle_txbuf(0);
        assert_eq!(p.handle_txbuf(93), Some(3300));
        assert_eq!(p.handle_txbuf(90), None, "90 % holds");
    }
}
