use mavlink::MavlinkVersion;

use super::*;
use crate::dialect::{LINK_QUALITY_DATA, MavMessage};
use crate::quality::LinkQualityConfig;
use crate::testutil::frame;
use crate::wire::Sender;
use crate::wire::ids::HEARTBEAT;

fn secs(s: u64) -> Instant {
    Instant::from_millis(s * 1000)
}

fn quality() -> LinkQuality {
    let config = LinkQualityConfig {
        period: Duration::from_secs(2),
        window: Duration::from_secs(4),
        quiet_after: Duration::from_secs(3),
        peer_timeout: Duration::from_secs(10),
        ..LinkQualityConfig::for_budget(683, false)
    };
    LinkQuality::new(config, secs(0))
}

fn report(rx: u16, lost: u16) -> MavMessage {
    MavMessage::LINK_QUALITY(LINK_QUALITY_DATA {
        rx_packets: rx,
        rx_lost: lost,
        rssi: i8::MAX,
        remote_rssi: i8::MAX,
        ..Default::default()
    })
}

/// A drone that reports every second: `loss(s)` of 10 frames lost in second `s`; it also
/// sends telemetry, so the downlink is heard. Returns the texts with their times.
fn fly(
    q: &mut LinkQuality,
    m: &mut LinkMonitor,
    range: std::ops::Range<u64>,
    loss: impl Fn(u64) -> u16,
    totals: &mut (u16, u16),
) -> Vec<(u64, String)> {
    fly_with(q, m, range, |s| (loss(s), 0), totals)
}

/// [`fly`] with the drone's noise floor in its reports: `second(s)` is (frames lost of 10,
/// noise floor dBm or 0 unknown) in second `s`.
fn fly_with(
    q: &mut LinkQuality,
    m: &mut LinkMonitor,
    range: std::ops::Range<u64>,
    second: impl Fn(u64) -> (u16, i8),
    totals: &mut (u16, u16),
) -> Vec<(u64, String)> {
    let mut sender = Sender::new(1, 191, MavlinkVersion::V2);
    let mut out = Vec::new();
    for s in range {
        let (lost, noise) = second(s);
        totals.0 = totals.0.wrapping_add(10 - lost);
        totals.1 = totals.1.wrapping_add(lost);
        let lq = MavMessage::LINK_QUALITY(LINK_QUALITY_DATA {
            rx_packets: totals.0,
            rx_lost: totals.1,
            rssi: i8::MAX,
            remote_rssi: i8::MAX,
            noise,
            ..Default::default()
        });
        q.handle_frame(secs(s), &frame(HEARTBEAT, 1, 1, s as u8));
        q.handle_frame(secs(s), &sender.frame(&lq));
        m.handle_timeout(secs(s), q);
        while let Some(n) = m.poll_notice() {
            assert!(n.text().len() <= 50);
            out.push((s, n.text()));
        }
    }
    out
}

#[test]
fn degraded_then_restored_once_each_with_direction_and_figure() {
    let (mut q, mut m) = (quality(), LinkMonitor::new(MonitorConfig::default()));
    let mut totals = (0, 0);
    let texts = fly(
        &mut q,
        &mut m,
        0..30,
        |s| if (10..18).contains(&s) { 4 } else { 0 },
        &mut totals,
    );
    assert_eq!(texts.len(), 2, "{texts:?}");
    assert!(
        texts[0].1.starts_with("Uplink GCS>UAV degraded: "),
        "{texts:?}"
    );
    assert!(texts[0].0 <= 11, "{texts:?}");
    assert!(texts[1].1.starts_with("Uplink GCS>UAV restored: 0% lost"));
    // the 4 s window forgets the loss 4 s after the last lossy second (17 s)
    assert!(texts[1].0 <= 22, "{texts:?}");
}

#[test]
fn a_flapping_link_gives_one_message_per_change_at_most_one_per_hold() {
    let config = MonitorConfig::default();
    let (mut q, mut m) = (quality(), LinkMonitor::new(config));
    let mut totals = (0, 0);
    // bad and good every other second for a minute
    let texts = fly(
        &mut q,
        &mut m,
        0..60,
        |s| if s % 2 == 0 { 10 } else { 0 },
        &mut totals,
    );
    for pair in texts.windows(2) {
        assert_ne!(pair[0].1, pair[1].1, "same message twice: {texts:?}");
        assert!(pair[1].0 - pair[0].0 >= config.hold.as_secs(), "{texts:?}");
    }
    assert!(texts.len() <= 60 / config.hold.as_secs() as usize);
    // a 50 % windowed loss stays degraded: one message, not a stream
    assert_eq!(texts.len(), 1, "{texts:?}");
}

#[test]
fn a_bridge_that_stops_reporting_is_flagged_by_silence() {
    let (mut q, mut m) = (quality(), LinkMonitor::new(MonitorConfig::default()));
    let mut totals = (0, 0);
    assert!(fly(&mut q, &mut m, 0..5, |_| 0, &mut totals).is_empty());
    // telemetry keeps coming, reports do not
    let mut texts = Vec::new();
    for s in 5..30 {
        q.handle_frame(secs(s), &frame(HEARTBEAT, 1, 1, s as u8));
        m.handle_timeout(secs(s), &q);
        while let Some(n) = m.poll_notice() {
            texts.push((s, n.text(), n.health));
        }
    }
    assert_eq!(texts.len(), 1, "{texts:?}");
    assert_eq!(texts[0].2, Health::Silent);
    assert_eq!(
        texts[0].0, 15,
        "peer timeout (10 s) after the last report at 4 s"
    );
    assert_eq!(texts[0].1, "Uplink GCS>UAV unknown: no drone report 11s");
}

#[test]
fn a_deaf_drone_is_uplink_lost_and_a_silent_one_is_downlink_lost() {
    let (mut q, mut m) = (quality(), LinkMonitor::new(MonitorConfig::default()));
    let mut totals = (0, 0);
    fly(&mut q, &mut m, 0..5, |_| 0, &mut totals);
    let mut sender = Sender::new(1, 191, MavlinkVersion::V2);
    for ms in (5_000..8_000).step_by(500) {
        q.sent_frame(Instant::from_millis(ms));
    }
    // its report: nothing received since the last one
    q.handle_frame(secs(9), &sender.frame(&report(totals.0, totals.1)));
    m.handle_timeout(secs(9), &q);
    let n = m.poll_notice().unwrap();
    assert_eq!(
        (n.health, n.text().as_str()),
        (Health::Lost, "Uplink GCS>UAV lost: drone hears nothing")
    );
    assert_eq!(n.severity(), MavSeverity::MAV_SEVERITY_CRITICAL);
    // then nothing at all from the drone
    m.handle_timeout(secs(13), &q);
    let n = m.poll_notice().unwrap();
    assert_eq!(n.text(), "Downlink UAV>GCS lost: nothing heard 4s");
    assert!(m.poll_notice().is_none());
}

#[test]
fn radio_status_once_a_second_with_the_drones_rssi() {
    let (mut q, mut m) = (quality(), LinkMonitor::new(MonitorConfig::default()));
    m.handle_timeout(secs(0), &q);
    assert!(m.poll_radio_status(&q).is_none(), "nothing heard yet");
    let mut sender = Sender::new(1, 191, MavlinkVersion::V2);
    let lq = MavMessage::LINK_QUALITY(LINK_QUALITY_DATA {
        rssi: -77,
        remote_rssi: i8::MAX,
        ..Default::default()
    });
    q.handle_frame(secs(1), &sender.frame(&lq));
    let mut got = 0;
    for ms in (1_000..11_000).step_by(100) {
        m.handle_timeout(Instant::from_millis(ms), &q);
        if let Some(s) = m.poll_radio_status(&q) {
            got += 1;
            assert_eq!((s.remrssi, s.rssi, s.noise), (95, 255, 255));
        }
    }
    assert_eq!(got, 10);
}

#[test]
fn a_drone_noise_floor_up_6_db_degrades_the_uplink_before_any_loss_and_its_end_restores_it() {
    let (mut q, mut m) = (quality(), LinkMonitor::new(MonitorConfig::default()));
    let mut totals = (0, 0);
    // 4 dB of wobble above the quietest floor: below the 6 dB alarm, no message.
    let wobble = |s: u64| (0, if s.is_multiple_of(2) { -110 } else { -106 });
    let quiet = fly_with(&mut q, &mut m, 0..10, wobble, &mut totals);
    assert!(quiet.is_empty(), "{quiet:?}");
    let deaf = fly_with(&mut q, &mut m, 10..20, |_| (0, -98), &mut totals);
    assert_eq!(
        deaf,
        vec![(10, "Uplink GCS>UAV degraded: drone noise +12dB".to_string())]
    );
    assert_eq!(m.health(Direction::Uplink), Some(Health::Degraded));
    // The ground's RADIO_STATUS shows the drone's floor as remnoise (SiK scale).
    let status = m.poll_radio_status(&q).unwrap();
    assert_eq!(status.remnoise, RssiScale::Sik.from_dbm(Some(-98)));
    let back = fly_with(&mut q, &mut m, 20..25, |_| (0, -110), &mut totals);
    assert_eq!(
        back,
        vec![(20, "Uplink GCS>UAV restored: drone noise +0dB".to_string())]
    );
}
