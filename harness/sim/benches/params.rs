//! `cargo bench -p harness-sim --bench params`: a whole parameter list downloaded as
//! QGroundControl does it (the list, then reads by index of what is missing after 1 s of
//! quiet; a `PARAM_SET` 2 s in), from the ArduPilot-like autopilot holding ArduCopter 4.6.3's
//! 1,396 parameters and the PX4-like one holding PX4 1.16's 904, through the real bridge and
//! router (compact telemetry, signed) over SiK 64k and LoRa SF7, clean and with the rig's 10 %
//! bursty loss; the list packed (`MAVLORA_PARAM_VALUES`) and raw (one `PARAM_VALUE` per frame,
//! `BridgeConfig::param_pack = None`; the figures before packing, `docs/measurements.md`, were
//! measured with the engines of before, in this same world).
//!
//! Prints one line per autopilot, radio and bridge: the list's time at the ground (worst and
//! median of the seeds), reads by index, the set's echo, position rate and longest position
//! gap while the list was in flight (worst of the seeds), parameter bytes on the radio, bytes
//! the radio dropped, and whether every value arrived byte for byte. `PARAMS_SEEDS` (default
//! 5) seeds per lossy radio; `PARAMS_ONLY=px4|ardupilot`; `PARAMS_PACKED_ONLY=1` skips "raw".

use harness_sim::freshness::{FreshnessRadio, quantile};
use harness_sim::params::{ParamsAutopilot, ParamsFigures, ParamsRun};

fn main() {
    let seeds: u64 = std::env::var("PARAMS_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    let only = std::env::var("PARAMS_ONLY").ok();
    let packed_only = std::env::var("PARAMS_PACKED_ONLY").is_ok();
    println!(
        "{:<10} {:<16} {:<7} {:>8} {:>8} {:>8} {:>7} {:>7} {:>6} {:>8} {:>7} {:>6}",
        "autopilot",
        "radio",
        "bridge",
        "list s",
        "median",
        "rereads",
        "echo s",
        "pos Hz",
        "gap s",
        "param B",
        "drop B",
        "exact"
    );
    for autopilot in ParamsAutopilot::ALL {
        if only.as_deref().is_some_and(|o| o != autopilot.name()) {
            continue;
        }
        for radio in FreshnessRadio::ALL {
            for packed in [false, true] {
                if packed_only && !packed {
                    continue;
                }
                let n = if radio.lossy() { seeds } else { 1 };
                let runs: Vec<ParamsFigures> = (1..=n)
                    .map(|seed| {
                        ParamsRun {
                            seed,
                            packed,
                            ..ParamsRun::new(autopilot, radio)
                        }
                        .measure()
                    })
                    .collect();
                let mut secs: Vec<f64> = runs
                    .iter()
                    .map(|r| r.seconds.unwrap_or(f64::INFINITY))
                    .collect();
                secs.sort_by(f64::total_cmp);
                let worst =
                    |f: fn(&ParamsFigures) -> f64| runs.iter().map(f).fold(f64::MIN, f64::max);
                let least =
                    |f: fn(&ParamsFigures) -> f64| runs.iter().map(f).fold(f64::MAX, f64::min);
                println!(
                    "{:<10} {:<16} {:<7} {:>8.1} {:>8.1} {:>8.0} {:>7.2} {:>7.2} {:>6.2} {:>8.0} {:>7.0} {:>6}",
                    autopilot.name(),
                    radio.name(),
                    if packed { "packed" } else { "raw" },
                    secs.last().copied().unwrap_or(f64::NAN),
                    quantile(&secs, 0.5),
                    worst(|r| r.rereads as f64),
                    worst(|r| r.echo_s.unwrap_or(f64::INFINITY)),
                    least(|r| r.position_hz),
                    worst(|r| r.position_gap_s),
                    worst(|r| r.param_bytes as f64),
                    worst(|r| r.radio_dropped_bytes as f64),
                    runs.iter().all(|r| r.exact && r.missing == 0),
                );
            }
        }
    }
}
