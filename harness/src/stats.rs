//! Figures from raw samples, computed in one place: fixtures report what
//! they saw (each command's latency, counts over a window with its bounds)
//! and the rig turns that into percentiles and rates, so every scenario and
//! every fixture means the same thing by "p99" or "B/s".

/// The `p`-quantile (0..=1) of `sorted` samples by nearest rank: the smallest
/// sample with at least `p` of the samples at or below it (rank
/// `max(1, ceil(p × n))`, 1-based). NaN if there are none.
///
/// The same definition the fixtures used before the rig computed it
/// (`math.ceil(p / 100 * len)` in `mavlora_gcs.py`).
pub fn quantile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = (p * sorted.len() as f64).ceil().max(1.0) as usize;
    sorted[rank.min(sorted.len()) - 1]
}

/// Median, 99th percentile and maximum of a set of samples (NaN when empty).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Percentiles {
    pub p50: f64,
    pub p99: f64,
    pub max: f64,
}

impl Percentiles {
    /// Nearest-rank percentiles ([`quantile`]) of `samples`, in any order.
    pub fn of(samples: &[f64]) -> Percentiles {
        let mut sorted = samples.to_vec();
        sorted.sort_by(f64::total_cmp);
        Percentiles {
            p50: quantile(&sorted, 0.50),
            p99: quantile(&sorted, 0.99),
            max: sorted.last().copied().unwrap_or(f64::NAN),
        }
    }
}

/// `count` per second over `seconds`; NaN for an empty or inverted window.
pub fn rate(count: f64, seconds: f64) -> f64 {
    if seconds > 0.0 {
        count / seconds
    } else {
        f64::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_matches_the_fixtures_former_python() {
        // Python: ordered[max(1, math.ceil(p / 100 * len(ordered))) - 1]
        let v: Vec<f64> = (1..=200).map(f64::from).collect();
        assert_eq!(quantile(&v, 0.5), 100.0);
        assert_eq!(quantile(&v, 0.99), 198.0);
        assert!(quantile(&[], 0.5).is_nan());
        assert_eq!(quantile(&[1.0, f64::INFINITY], 0.99), f64::INFINITY);
        // 30 commands, as realtime::c2_latency sends: p99 is the slowest
        // (ceil(29.7) = 30), p50 the 15th.
        let thirty: Vec<f64> = (1..=30).map(|i| f64::from(i) * 10.0).collect();
        assert_eq!(quantile(&thirty, 0.99), 300.0);
        assert_eq!(quantile(&thirty, 0.5), 150.0);
        // Rank 1 at the bottom, not 0.
        assert_eq!(quantile(&[7.0, 8.0], 0.0), 7.0);
    }

    #[test]
    fn percentiles_sort_their_samples() {
        let p = Percentiles::of(&[1510.2, 20.5, 31.0, 18.25, 1600.0, 22.0]);
        // n = 6: p50 rank 3, p99 rank 6
        assert_eq!((p.p50, p.p99, p.max), (22.0, 1600.0, 1600.0));
        let none = Percentiles::of(&[]);
        assert!(none.p50.is_nan() && none.p99.is_nan() && none.max.is_nan());
    }

    #[test]
    fn rates_need_a_window() {
        assert_eq!(rate(600.0, 30.0), 20.0);
        assert!(rate(5.0, 0.0).is_nan());
    }
}
