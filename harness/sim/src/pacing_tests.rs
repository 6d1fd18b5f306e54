//! Issue 23, flow control from the radio: engines budgeted for a radio's nominal rate over one
//! whose real throughput is half of it (SiK with ECC on: Golay coding halves the data each
//! packet carries). The radio's `RADIO_STATUS` (`txbuf`, its free buffer) paces the budget;
//! the invariant is nothing dropped by the radio, and the target ≥ 75 % of its real
//! throughput used (mLRS aims at 75-85 % of its link).

use harness_radio::{Preset, RadioSetup};
use mavlora::Instant;
use mavlora::bridge::BridgeConfig;
use mavlora::filter::Profile;
use mavlora::router::RouterConfig;

use crate::params::ParamsAutopilot;
use crate::profiles::PX4_NORMAL_TOML;
use crate::{
    Direction, PX4_NORMAL, PX4_PARAM_RATE, Px4Fc, World, direction_capacity, scheduler_for, secs,
};

/// Downlink bytes the radio dropped and the delivered rate (B/s) from 20 s to 80 s, with the
/// radio's reports on or off, while the vehicle streams PX4's Normal profile and the ground
/// downloads the parameter list again and again.
fn fly(reports: bool) -> (u64, f64) {
    let nominal = Preset::sik_64k();
    let budget = scheduler_for(Some(&nominal));
    let profile = Profile::parse(PX4_NORMAL_TOML, "px4-normal").unwrap();
    let b = BridgeConfig::new(profile, budget);
    let r = RouterConfig::new(budget);
    let table = ParamsAutopilot::Px4.table();
    let fc = Px4Fc::new(PX4_NORMAL, Instant::ZERO, 1).with_params(table, PX4_PARAM_RATE);
    let ecc = RadioSetup::builtin("sik-64k-ecc").unwrap();
    let mut w = World::new(fc, Some((b, r)), Some(&ecc)).unwrap();
    w.set_radio_status(reports);
    let mut at20 = 0;
    for s in (2..=80).step_by(2) {
        if s % 10 == 2 {
            w.gcs.download_params(w.now);
        }
        w.run_until(secs(f64::from(s)));
        if s == 20 {
            at20 = w.link_stats(Direction::Downlink).unwrap().bytes_delivered;
        }
    }
    let d = w.link_stats(Direction::Downlink).unwrap();
    (d.bytes_dropped, (d.bytes_delivered - at20) as f64 / 60.0)
}

#[test]
fn the_radios_free_buffer_paces_engines_budgeted_for_twice_its_throughput() {
    let real = direction_capacity(&Preset::sik_64k_ecc());
    let budget = scheduler_for(Some(&Preset::sik_64k())).rate_bytes_per_s as f64;
    assert!(
        budget > 1.4 * real,
        "budget {budget} B/s against {real:.0} B/s real"
    );
    let (dropped_blind, rate_blind) = fly(false);
    assert!(
        dropped_blind > 0,
        "without reports the budget must overflow the radio, else this proves nothing \
         (delivered {rate_blind:.0} B/s of {real:.0})"
    );
    let (dropped, rate) = fly(true);
    println!(
        "real throughput {real:.0} B/s, budget {budget:.0} B/s; paced: {rate:.0} B/s \
         ({:.0} %), {dropped} B dropped; unpaced: {rate_blind:.0} B/s, {dropped_blind} B dropped",
        100.0 * rate / real
    );
    assert_eq!(
        dropped, 0,
        "bytes the radio dropped with its reports pacing the budget"
    );
    assert!(
        rate >= 0.75 * real,
        "{rate:.0} B/s is under 75 % of {real:.0}"
    );
}
