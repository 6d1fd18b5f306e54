use mavlink::MavlinkVersion;

use super::*;
use crate::dialect::{MavMessage, RADIO_STATUS_DATA};
use crate::testutil::frame;
use crate::wire::{FrameReader, Sender};

use crate::wire::ids::HEARTBEAT;

/// One report a second, peer missing after 3 s, no early reports (change > 1).
fn config() -> LinkQualityConfig {
    LinkQualityConfig {
        period: Duration::from_secs(1),
        peer_timeout: Duration::from_secs(3),
        change: 2.0,
        quiet_after: Duration::from_secs(3600),
        ..LinkQualityConfig::for_budget(683, false)
    }
}

fn secs(s: u64) -> Instant {
    Instant::from_millis(s * 1000)
}

/// Reader counters after: seq 0, 1, (2 lost), 3, one corrupted frame, 4 => 4 good, 1 lost
/// (seq 4 follows 3; the corrupted one is not counted as a frame), 1 bad CRC.
/// A report due at `now`: the timer, then the queue.
fn due_report(
    lq: &mut LinkQuality,
    now: Instant,
    stats: &ReaderStats,
) -> Option<LINK_QUALITY_DATA> {
    lq.handle_timeout(now, stats);
    lq.poll_report()
}

fn stats() -> ReaderStats {
    let mut reader = FrameReader::new();
    for seq in [0, 1, 3] {
        reader.push(frame(HEARTBEAT, 1, 1, seq).as_bytes());
    }
    let mut bad = frame(HEARTBEAT, 1, 1, 9).into_inner();
    let last = bad.len() - 1;
    bad[last] ^= 0xFF;
    reader.push(&bad);
    reader.push(frame(HEARTBEAT, 1, 1, 4).as_bytes());
    while reader.next_frame().is_some() {}
    reader.stats().clone()
}

fn report(rx: u16, lost: u16) -> MavMessage {
    MavMessage::LINK_QUALITY(LINK_QUALITY_DATA {
        time_boot_ms: 0,
        rx_packets: rx,
        rx_lost: lost,
        rx_bad_crc: 0,
        rssi: i8::MAX,
        remote_rssi: i8::MAX,
        noise: 0,
    })
}

/// A SiK radio's `RADIO_STATUS` frame with its noise floor at `noise_dbm`.
fn sik_status(noise_dbm: i8) -> crate::wire::OwnedFrame {
    let status = MavMessage::RADIO_STATUS(RADIO_STATUS_DATA {
        rssi: RssiScale::Sik.from_dbm(Some(-80)),
        remrssi: 255,
        noise: RssiScale::Sik.from_dbm(Some(noise_dbm)),
        remnoise: 255,
        ..RADIO_STATUS_DATA::default()
    });
    Sender::new(51, 68, MavlinkVersion::V1).frame(&status)
}

#[test]
fn a_noise_floor_that_rises_sends_a_report_early_and_the_reports_carry_it() {
    let stats = ReaderStats::default();
    let config = LinkQualityConfig {
        period: Duration::from_secs(30),
        ..config()
    };
    let mut lq = LinkQuality::new(config, secs(0));
    lq.handle_local_radio(&sik_status(-110));
    let first = due_report(&mut lq, secs(30), &stats).unwrap();
    assert_eq!(first.noise, -110);
    // A 2 dB wobble is a reading's noise, not a change.
    lq.handle_local_radio(&sik_status(-108));
    assert!(due_report(&mut lq, secs(32), &stats).is_none());
    // 12 dB up: out within the next look, not at the 30 s keep-alive.
    lq.handle_local_radio(&sik_status(-98));
    let early = due_report(&mut lq, Instant::from_millis(33_200), &stats).unwrap();
    assert_eq!(early.noise, -98);
    // And back down: restored as fast.
    lq.handle_local_radio(&sik_status(-110));
    assert_eq!(
        due_report(&mut lq, Instant::from_millis(40_200), &stats).map(|r| r.noise),
        Some(-110)
    );
}

#[test]
fn the_peer_noise_rise_is_over_its_quietest_floor_and_restarts_its_loss_estimate() {
    let mut lq = LinkQuality::new(config(), secs(0));
    let mut sender = Sender::new(1, 191, MavlinkVersion::V2);
    let with_noise = |rx: u16, lost: u16, noise: i8| match report(rx, lost) {
        MavMessage::LINK_QUALITY(r) => MavMessage::LINK_QUALITY(LINK_QUALITY_DATA { noise, ..r }),
        _ => unreachable!(),
    };
    lq.handle_frame(secs(1), &sender.frame(&with_noise(10, 0, -108)));
    lq.handle_frame(secs(2), &sender.frame(&with_noise(14, 6, -110)));
    assert_eq!(lq.peer_loss(secs(2)), Some(0.6));
    assert_eq!(lq.peer_noise_rise_db(secs(2)), Some(0.0));
    // 14 dB up: a new channel; the loss counted before it no longer stands.
    lq.handle_frame(secs(3), &sender.frame(&with_noise(15, 6, -96)));
    assert_eq!(lq.peer_noise_rise_db(secs(3)), Some(14.0));
    assert_eq!(lq.peer_loss(secs(3)), None);
    // A peer without the field (an older bridge) is unknown, not 0 dB.
    lq.handle_frame(secs(4), &sender.frame(&report(16, 6)));
    assert_eq!(lq.peer_noise_rise_db(secs(4)), None);
    // A report gone stale says nothing about now.
    lq.handle_frame(secs(5), &sender.frame(&with_noise(17, 6, -96)));
    assert_eq!(lq.peer_noise_rise_db(secs(9)), None);
}

#[test]
fn reports_our_counters_once_per_period() {
    let stats = stats();
    let mut lq = LinkQuality::new(config(), secs(10));
    // The first at once (a restarted end says so before anything else), then each period.
    assert_eq!(lq.poll_timeout(), Some(secs(10)));
    assert_eq!(
        due_report(&mut lq, secs(10), &stats).unwrap().time_boot_ms,
        0
    );
    assert!(due_report(&mut lq, Instant::from_millis(10_999), &stats).is_none());
    let r = due_report(&mut lq, secs(11), &stats).unwrap();
    assert_eq!(
        (r.rx_packets, r.rx_lost, r.rx_bad_crc, r.time_boot_ms),
        (4, 1, 1, 1000)
    );
    assert_eq!((r.rssi, r.remote_rssi), (i8::MAX, i8::MAX), "unknown");
    assert!(due_report(&mut lq, secs(11), &stats).is_none());
    assert!(due_report(&mut lq, Instant::from_millis(11_999), &stats).is_none());
    assert!(due_report(&mut lq, secs(12), &stats).is_some());
}

#[test]
fn a_stall_gives_one_report_not_a_burst() {
    let stats = ReaderStats::default();
    let mut lq = LinkQuality::new(config(), secs(0));
    assert!(due_report(&mut lq, secs(30), &stats).is_some());
    assert!(due_report(&mut lq, secs(30), &stats).is_none());
    assert!(due_report(&mut lq, Instant::from_millis(30_999), &stats).is_none());
    assert!(due_report(&mut lq, secs(31), &stats).is_some());
}

#[test]
fn counters_wrap_at_16_bits() {
    let mut reader = FrameReader::new();
    for k in 0..70_000u32 {
        reader.push(frame(HEARTBEAT, 1, 1, k as u8).as_bytes());
        while reader.next_frame().is_some() {}
    }
    let mut lq = LinkQuality::new(config(), secs(0));
    let r = due_report(&mut lq, secs(1), reader.stats()).unwrap();
    assert_eq!(r.rx_packets, (70_000 - 65_536) as u16);
}

#[test]
fn sik_radio_status_sets_rssi() {
    let status = MavMessage::RADIO_STATUS(RADIO_STATUS_DATA {
        rssi: 95,
        remrssi: 255,
        ..RADIO_STATUS_DATA::default()
    });
    let f = Sender::new(51, 68, MavlinkVersion::V1).frame(&status);
    let mut lq = LinkQuality::new(config(), secs(0));
    lq.handle_local_radio(&f);
    let r = due_report(&mut lq, secs(1), &ReaderStats::default()).unwrap();
    assert_eq!((r.rssi, r.remote_rssi), (-77, i8::MAX));

    let config = LinkQualityConfig {
        radio_status: None,
        ..config()
    };
    let mut ignoring = LinkQuality::new(config, secs(0));
    ignoring.handle_local_radio(&f);
    let r = due_report(&mut ignoring, secs(1), &ReaderStats::default()).unwrap();
    assert_eq!(r.rssi, i8::MAX);
}

#[test]
fn peer_loss_ratio_from_wrapping_counter_differences() {
    let mut sender = Sender::new(1, 191, MavlinkVersion::V2);
    let mut lq = LinkQuality::new(config(), secs(0));
    assert_eq!(lq.peer_state(secs(0)), PeerState::Unknown);
    lq.handle_frame(secs(1), &sender.frame(&report(65_530, 10)));
    assert_eq!(
        lq.peer_state(secs(1)),
        PeerState::Reporting { loss_ratio: None }
    );
    // +10 received (across the wrap), +10 lost
    lq.handle_frame(secs(2), &sender.frame(&report(4, 20)));
    assert_eq!(
        lq.peer_state(secs(2)),
        PeerState::Reporting {
            loss_ratio: Some(0.5)
        }
    );
    assert_eq!(lq.peer().unwrap().received_at, secs(2));
    assert_eq!(
        lq.peer_state(secs(5)),
        PeerState::Reporting {
            loss_ratio: Some(0.5)
        }
    );
    assert_eq!(
        lq.peer_state(Instant::from_millis(5_001)),
        PeerState::Missing { since: secs(2) }
    );
}

#[test]
fn air_and_ground_learn_what_the_other_hears() {
    // The air side hears the ground badly (its noise floor); the ground hears it well.
    let mut air = LinkQuality::new(config(), secs(0));
    let mut ground = LinkQuality::new(config(), secs(0));
    let mut air_sender = Sender::new(1, 191, MavlinkVersion::V2);
    let mut ground_reader = FrameReader::new();

    let air_hears = stats(); // 4 received, 1 lost, 1 bad CRC
    let r = due_report(&mut air, secs(1), &air_hears).unwrap();
    ground_reader.push(air_sender.frame(&MavMessage::LINK_QUALITY(r)).as_bytes());
    let received = ground_reader.next_frame().unwrap();
    ground.handle_frame(secs(1), &received.frame);

    let seen = &ground.peer().unwrap().report;
    assert_eq!((seen.rx_packets, seen.rx_lost, seen.rx_bad_crc), (4, 1, 1));
}

#[test]
fn budget_sets_the_steady_cost() {
    // 3 B/s of LoRa SF7's 683 B/s at most (the monitoring budget), signed or not.
    for signed in [false, true] {
        let c = LinkQualityConfig::for_budget(683, signed);
        let bytes = if signed {
            REPORT_BYTES_SIGNED
        } else {
            REPORT_BYTES
        };
        let cost = f64::from(bytes) / c.period.as_secs_f64();
        assert!(cost <= 3.0, "{cost} B/s");
    }
    // A fast radio reports more often, never more than twice a second.
    assert_eq!(
        LinkQualityConfig::for_budget(1_000_000, false).period,
        Duration::from_millis(500)
    );
}

/// Frames from the peer, one per second from `from` s, every `lost_every`-th missing.
fn peer_frames(reader: &mut FrameReader, seqs: std::ops::Range<u8>, skip: impl Fn(u8) -> bool) {
    for seq in seqs {
        if !skip(seq) {
            reader.push(frame(HEARTBEAT, 255, 190, seq).as_bytes());
        }
    }
    while reader.next_frame().is_some() {}
}

#[test]
fn a_loss_change_sends_a_report_early_and_a_steady_link_stays_sparse() {
    let config = LinkQualityConfig {
        period: Duration::from_secs(10),
        window: Duration::from_secs(4),
        ..LinkQualityConfig::for_budget(683, false)
    };
    let mut lq = LinkQuality::new(config, secs(0));
    let mut reader = FrameReader::new();
    let mut reports = Vec::new();
    let mut now = secs(0);
    // 30 s of a clean link, one peer frame a second: only the keep-alives.
    for s in 0..30u8 {
        peer_frames(&mut reader, s..s + 1, |_| false);
        let t = secs(u64::from(s));
        lq.handle_frame(t, &frame(HEARTBEAT, 255, 190, s));
        lq.observe(t, reader.stats());
        while now <= t {
            if let Some(r) = due_report(&mut lq, now, reader.stats()) {
                reports.push((now, r));
            }
            now = lq
                .poll_timeout()
                .unwrap()
                .max(now + Duration::from_millis(1));
        }
    }
    assert_eq!(
        reports.iter().map(|(t, _)| *t).collect::<Vec<_>>(),
        vec![secs(0), secs(10), secs(20)],
        "the start's and the keep-alives only"
    );
    // Then half of the frames go missing: a report within 2 s of the first counted loss.
    let before = reports.len();
    for s in 30..40u8 {
        peer_frames(&mut reader, s..s + 1, |q| q % 2 == 1);
        let t = secs(u64::from(s));
        if s % 2 == 0 {
            lq.handle_frame(t, &frame(HEARTBEAT, 255, 190, s));
        }
        lq.observe(t, reader.stats());
        while now <= t {
            if let Some(r) = due_report(&mut lq, now, reader.stats()) {
                reports.push((now, r));
            }
            now = lq
                .poll_timeout()
                .unwrap()
                .max(now + Duration::from_millis(1));
        }
    }
    // first loss counted when seq 32 arrives (31 missing); the keep-alive is due at 40 s
    let first = reports[before..].iter().find(|(_, r)| r.rx_lost >= 1);
    let (at, _) = first.expect("a report with the loss");
    assert!(*at <= secs(33), "early report at {at}");
}

#[test]
fn a_quiet_peer_is_reported_once_per_spell() {
    let config = LinkQualityConfig {
        period: Duration::from_secs(30),
        quiet_after: Duration::from_secs(3),
        ..LinkQualityConfig::for_budget(683, false)
    };
    let mut lq = LinkQuality::new(config, secs(0));
    let stats = ReaderStats::default();
    lq.handle_frame(secs(1), &frame(HEARTBEAT, 255, 190, 0));
    let mut got = Vec::new();
    let mut now = secs(1);
    while now < secs(20) {
        if due_report(&mut lq, now, &stats).is_some() {
            got.push(now);
        }
        now = lq
            .poll_timeout()
            .unwrap()
            .max(now + Duration::from_millis(1));
    }
    // The first at once, then once, exactly 3 s after the last frame (the engine wakes for
    // it: no periodic look).
    assert_eq!(got, [secs(1), secs(4)]);
    assert!(lq.peer_quiet(secs(20)));
}

#[test]
fn a_report_of_nothing_received_while_we_sent_reads_as_a_deaf_peer() {
    let mut sender = Sender::new(1, 191, MavlinkVersion::V2);
    let mut lq = LinkQuality::new(config(), secs(0));
    lq.handle_frame(secs(1), &sender.frame(&report(100, 0)));
    for ms in [1_500, 2_000, 2_500, 3_000] {
        lq.sent_frame(Instant::from_millis(ms));
    }
    // the peer received nothing new: 4 of ours sent, all older than the in-flight second
    lq.handle_frame(secs(5), &sender.frame(&report(100, 0)));
    assert_eq!(lq.peer().unwrap().unheard, 4);
    assert_eq!(lq.peer_loss(secs(5)), Some(1.0));
    // reports of "nothing new" a second apart still add up
    lq.handle_frame(Instant::from_millis(5_500), &sender.frame(&report(100, 0)));
    assert_eq!(lq.peer().unwrap().unheard, 4);
    // it hears us again, and counts the outage's 30 frames as lost: that was the outage,
    // announced as such; the channel after it is judged from this report on
    lq.handle_frame(secs(6), &sender.frame(&report(101, 30)));
    assert_eq!(lq.peer().unwrap().unheard, 0);
    assert_eq!(lq.peer_loss(secs(6)), None);
    lq.handle_frame(secs(7), &sender.frame(&report(105, 30)));
    assert_eq!(lq.peer_loss(secs(7)), Some(0.0));
    lq.handle_frame(secs(8), &sender.frame(&report(108, 31)));
    assert_eq!(lq.peer_loss(secs(8)), Some(1.0 / 8.0));
}

#[test]
fn loss_counted_while_the_peer_still_hears_us_stays_in_the_window() {
    let mut sender = Sender::new(1, 191, MavlinkVersion::V2);
    let mut lq = LinkQuality::new(config(), secs(0));
    lq.handle_frame(secs(1), &sender.frame(&report(100, 0)));
    lq.sent_frame(Instant::from_millis(1_500));
    lq.handle_frame(secs(2), &sender.frame(&report(101, 9)));
    assert_eq!(lq.peer_loss(secs(2)), Some(0.9));
}
