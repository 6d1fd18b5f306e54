//! The MavLora engines' byte budget for a carrier, so every world sets it the same way.

use harness_radio::{Access, Preset};
use mavlora::schedule::SchedulerConfig;

/// Serial bytes per second one direction of `preset` can carry at best: full packets in its
/// share of the channel (its TDM windows, or half of a half-duplex channel).
pub fn direction_capacity(preset: &Preset) -> f64 {
    let share = match preset.access {
        Access::Tdm(t) => t.window_ms / (2.0 * (t.window_ms + t.silence_ms)),
        Access::Burst(_) => 0.5,
    };
    share * preset.max_data_rate()
}

/// The bridge's and router's byte budget for a radio: 80 % of one direction's capacity, so
/// the radio's buffer does not overflow under the budget; `None`: an ideal wire (a budget
/// that never binds).
pub fn scheduler_for(preset: Option<&Preset>) -> SchedulerConfig {
    match preset {
        Some(p) => {
            let rate = (0.8 * direction_capacity(p)) as u32;
            SchedulerConfig {
                rate_bytes_per_s: rate,
                burst_bytes: (2 * p.max_payload) as u32,
                max_queued_bytes: 8 * p.max_payload,
            }
        }
        None => SchedulerConfig {
            rate_bytes_per_s: 1_000_000,
            burst_bytes: 100_000,
            max_queued_bytes: 1_000_000,
        },
    }
}
