//! The paper's flight scenarios A–D (§VI-B) and a six-pilot route, under a
//! virtual clock, in both modes.

mod sim;

use multirx_core::{Config, Duration, Mode};
use sim::{Loss, Sim, SimReceiver, cue, ms};

fn sim(mode: Mode, n: u8, loss: Loss, boot_ms: u64) -> Sim {
    let config = Config::new(mode, n);
    let receivers = (0..n)
        .map(|i| SimReceiver::new(7, boot_ms, loss, 300 + u16::from(i) * 100))
        .collect();
    Sim::new(config, receivers)
}

fn pilot(s: &Sim, rx: u8) -> u16 {
    s.mux.config().pilot_values[usize::from(rx)]
}

#[test]
fn a_idle_pilot_switching_on_gains_no_control() {
    for mode in [Mode::Parallel, Mode::Scan] {
        let mut s = sim(mode, 2, Loss::Failsafe, 200);
        s.run(ms(10_000), &[cue(0, 0, true), cue(3_000, 1, true)]);
        assert_eq!(s.mux.active(), Some(0), "{mode:?}");
        assert_eq!(s.idle_takeovers, 0);
        let after = s.first_pilot_value(ms(3_000), pilot(&s, 1));
        assert_eq!(
            after, None,
            "{mode:?}: pilot 2 appeared at the flight controller"
        );
    }
}

#[test]
fn b_active_off_other_on_hands_over() {
    // Parallel: the other receiver is already up, so handover is one input
    // frame (to see the failsafe flag) plus at most one output period.
    let mut s = sim(Mode::Parallel, 2, Loss::Failsafe, 200);
    s.run(
        ms(5_000),
        &[cue(0, 0, true), cue(1_000, 1, true), cue(3_000, 0, false)],
    );
    let at = s.first_pilot_value(ms(3_000), pilot(&s, 1)).unwrap();
    assert!(
        at - ms(3_000) <= Duration::from_millis(14),
        "{}",
        at - ms(3_000)
    );
    assert_eq!(s.idle_takeovers, 0);

    // Silent receivers: the silence timeout bounds it instead.
    let mut s = sim(Mode::Parallel, 2, Loss::Silent, 200);
    s.run(
        ms(5_000),
        &[cue(0, 0, true), cue(1_000, 1, true), cue(3_000, 0, false)],
    );
    let at = s.first_pilot_value(ms(3_000), pilot(&s, 1)).unwrap();
    assert!(
        at - ms(3_000) <= Duration::from_millis(60 + 14),
        "{}",
        at - ms(3_000)
    );

    // Scan: power the next receiver, wait for it to boot and acquire.
    let mut s = sim(Mode::Scan, 2, Loss::Failsafe, 200);
    s.run(
        ms(8_000),
        &[cue(0, 0, true), cue(1_000, 1, true), cue(3_000, 0, false)],
    );
    let at = s.first_pilot_value(ms(3_000), pilot(&s, 1)).unwrap();
    let took = at - ms(3_000);
    assert!(
        took >= Duration::from_millis(200),
        "cannot beat the boot time: {took}"
    );
    assert!(took <= Duration::from_millis(2_000 * 2 + 100), "{took}");
}

#[test]
fn c_both_off_means_auto_loiter_and_no_rc_loss() {
    for mode in [Mode::Parallel, Mode::Scan] {
        let mut s = sim(mode, 2, Loss::Silent, 200);
        s.run(
            ms(10_000),
            &[
                cue(0, 0, true),
                cue(0, 1, true),
                cue(4_000, 0, false),
                cue(4_000, 1, false),
            ],
        );
        let config = s.mux.config().clone();
        let fm = usize::from(config.flight_mode_channel);
        let loiter = s
            .outputs
            .iter()
            .find(|o| o.at >= ms(4_000) && o.frame.channels[fm] == config.auto_loiter_value)
            .unwrap();
        assert!(
            loiter.at - ms(4_000) <= Duration::from_millis(60 + 14),
            "{mode:?}"
        );
        assert_eq!(
            loiter.frame.channels[usize::from(config.pilot_channel)],
            config.no_receiver_value
        );
        assert!(s.outputs.iter().all(|o| !o.frame.flags.failsafe));
        assert_eq!(s.max_output_gap(), config.frame_period, "{mode:?}");
        assert!(s.outputs.last().unwrap().at >= ms(10_000 - 7));
    }
}

#[test]
fn d_mission_flight_pilot_takes_over_without_mode_change() {
    // All transmitters have the flight-mode switch at auto-loiter, so the
    // channel never changes while control moves and the mission continues.
    for mode in [Mode::Parallel, Mode::Scan] {
        let config = Config::new(mode, 2);
        let loiter = config.auto_loiter_value;
        let fm = usize::from(config.flight_mode_channel);
        let mut receivers: Vec<_> = (0..2)
            .map(|i| SimReceiver::new(7, 200, Loss::Failsafe, 300 + i * 100))
            .collect();
        for r in &mut receivers {
            r.sticks[fm] = loiter;
        }
        let mut s = Sim::new(config, receivers);
        s.run(ms(9_000), &[cue(5_000, 1, true)]);
        let values: std::collections::BTreeSet<u16> =
            s.outputs.iter().map(|o| o.frame.channels[fm]).collect();
        assert_eq!(
            values.into_iter().collect::<Vec<_>>(),
            vec![loiter],
            "{mode:?}"
        );
        assert_eq!(s.mux.active(), Some(1), "{mode:?}");
    }
}

#[test]
fn six_pilots_hand_over_along_a_route() {
    for (mode, bound_ms) in [(Mode::Parallel, 14), (Mode::Scan, 2_000 * 6 + 300)] {
        let mut s = sim(mode, 6, Loss::Failsafe, 200);
        // Pilot k+1 switches on before pilot k switches off, every 15 s.
        let mut cues = vec![cue(0, 0, true)];
        for k in 0..5u8 {
            let t = 15_000 * (u64::from(k) + 1);
            cues.push(cue(t - 5_000, k + 1, true));
            cues.push(cue(t, k, false));
        }
        s.run(ms(90_000), &cues);
        for k in 0..5u8 {
            let t = ms(15_000 * (u64::from(k) + 1));
            let at = s.first_pilot_value(t, pilot(&s, k + 1)).unwrap();
            assert!(
                at - t <= Duration::from_millis(bound_ms),
                "{mode:?} {k}: {}",
                at - t
            );
        }
        assert_eq!(s.mux.active(), Some(5));
        assert_eq!(s.idle_takeovers, 0);
    }
}

#[test]
fn scan_powers_one_receiver_at_a_time() {
    let mut s = sim(Mode::Scan, 3, Loss::Failsafe, 200);
    s.run(ms(20_000), &[cue(9_000, 2, true)]);
    let mut powered = [false; 3];
    for e in &s.events {
        if let multirx_core::Event::Power { rx, on } = e.event {
            powered[usize::from(rx)] = on;
            assert!(
                powered.iter().filter(|p| **p).count() <= 1,
                "{:?}",
                s.events
            );
        }
    }
    assert_eq!(s.mux.active(), Some(2));
}
