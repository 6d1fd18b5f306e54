//! A whole parameter list downloaded as QGroundControl does it (the list, then reads by index
//! of what is missing after 1 s of quiet; a `PARAM_SET` 2 s in), through the real engines,
//! signed, compact telemetry flowing, over the rig file's radios (`harness_sim::params`):
//! ArduCopter 4.6.3's 1,396 parameters and PX4 1.16's 904, as the real autopilots send them.
//!
//! Targets (issue 21): all parameters at the ground within 15 s on SiK 64k, 30 s at 10 % bursty
//! loss, 120 s on LoRa SF7; position at the ground at least 2 Hz throughout; a `PARAM_SET`
//! echoed within 1 s while the list is in flight; every value byte for byte the autopilot's.
//! With the engines of before (one `PARAM_VALUE` per frame) every test here fails: the same
//! world measured 24.4 s (ArduPilot) and 15.8 s (PX4) on SiK, as the real SITLs took 24.7 s and
//! 15.8 s, 362 s and 233 s on LoRa SF7, 37.8 s on SiK at 10 % loss, and on LoRa at 10 % loss
//! position at 0.01 Hz and no complete list.
//! `cargo bench -p harness-sim --bench params` prints every figure, before and after.

use harness_sim::freshness::FreshnessRadio;
use harness_sim::params::{ParamsAutopilot, ParamsFigures, ParamsRun};

fn run(autopilot: ParamsAutopilot, radio: FreshnessRadio, seed: u64) -> ParamsFigures {
    let f = ParamsRun {
        seed,
        timeout_s: 300.0,
        ..ParamsRun::new(autopilot, radio)
    }
    .measure();
    eprintln!("{} {} seed {seed}: {f:?}", autopilot.name(), radio.name());
    f
}

fn check(what: &str, f: &ParamsFigures, limit_s: f64) {
    let s = f.seconds.unwrap_or(f64::INFINITY);
    assert!(
        f.missing == 0 && s <= limit_s,
        "{what}: {} missing, {s:.1} s (limit {limit_s} s)",
        f.missing
    );
    assert!(
        f.exact,
        "{what}: a value at the ground is not the autopilot's"
    );
    assert!(
        f.position_hz >= 2.0,
        "{what}: position {:.2} Hz during the list",
        f.position_hz
    );
}

#[test]
fn whole_lists_within_15_s_on_sik_and_120_s_on_lora() {
    for autopilot in ParamsAutopilot::ALL {
        for (radio, limit) in [(FreshnessRadio::Sik, 15.0), (FreshnessRadio::Lora, 120.0)] {
            let f = run(autopilot, radio, 1);
            let what = format!("{} on {}", autopilot.name(), radio.name());
            check(&what, &f, limit);
            let echo = f.echo_s.unwrap_or(f64::INFINITY);
            assert!(echo <= 1.0, "{what}: PARAM_SET echoed after {echo:.2} s");
            assert_eq!(f.rereads, 0, "{what}: a clean radio needs no read by index");
            assert_eq!(
                f.radio_dropped_bytes, 0,
                "{what}: the radio's buffer overflowed"
            );
        }
    }
}

#[test]
fn whole_lists_within_30_s_on_sik_at_ten_percent_bursty_loss() {
    for autopilot in ParamsAutopilot::ALL {
        for seed in 1..=3 {
            let f = run(autopilot, FreshnessRadio::SikBursty, seed);
            let what = format!("{} on sik-64k-bursty seed {seed}", autopilot.name());
            check(&what, &f, 30.0);
            // the echo: printed, not held to 1 s (a set that falls into a fade is sent again
            // after 1 s, and its echo is timed from the first send)
        }
    }
}

/// Regression: on LoRa SF7 at 10 % bursty loss the ground's reads by index (10 in flight,
/// again every second, started by the first fade longer than 1 s) and their answers, sent
/// ahead of everything, wanted twice the radio's budget: position at the ground fell to
/// 0.03 Hz and the list never completed, packed or not. The router now holds reads of what the
/// list in flight brings and repeats of a read in flight, and answers to reads take at most a
/// quarter of the bridge's budget ahead of position. Real ArduCopter also tells of its boot
/// calibrations with index 65535 while it streams its list: those must not make the list look
/// complete to the router (they did, and every read by index went to the radio: 132 s on a
/// clean LoRa SF7 with the real SITL).
#[test]
fn on_lora_at_ten_percent_bursty_loss_position_keeps_2_hz_and_the_list_completes() {
    for autopilot in ParamsAutopilot::ALL {
        let f = run(autopilot, FreshnessRadio::LoraBursty, 1);
        let what = format!("{} on lora-sf7-bursty", autopilot.name());
        check(&what, &f, 300.0);
        assert!(
            f.reads.held_ahead > 0,
            "{what}: no read of what the list brings was held ({:?})",
            f.reads
        );
    }
}
