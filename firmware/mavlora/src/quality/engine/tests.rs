use mavlink::MavlinkVersion;

use super::*;
use crate::dialect::{MavMessage, RADIO_STATUS_DATA};
use crate::testutil::frame;
use crate::wire::{FrameReader, Sender};

use crate::wire::ids::HEARTBEAT;

/// One report a second, peer missing after 3 s.
fn config() -> LinkQualityConfig {
    LinkQualityConfig {
        period: Duration::from_secs(1),
        peer_timeout: Duration::from_secs(3),
        radio_status: Some(RssiScale::Sik),
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
    })
}

#[test]
fn reports_our_counters_once_per_period() {
    let stats = stats();
    let mut lq = LinkQuality::new(config(), secs(10));
    assert_eq!(lq.poll_timeout(), Some(secs(11)));
    assert!(due_report(&mut lq, Instant::from_millis(10_999), &stats).is_none());
    let r = due_report(&mut lq, secs(11), &stats).unwrap();
    assert_eq!(
        (r.rx_packets, r.rx_lost, r.rx_bad_crc, r.time_boot_ms),
        (4, 1, 1, 1000)
    );
    assert_eq!((r.rssi, r.remote_rssi), (i8::MAX, i8::MAX), "unknown");
    assert!(due_report(&mut lq, secs(11), &stats).is_none());
    assert_eq!(lq.poll_timeout(), Some(secs(12)));
}

#[test]
fn a_stall_gives_one_report_not_a_burst() {
    let stats = ReaderStats::default();
    let mut lq = LinkQuality::new(config(), secs(0));
    assert!(due_report(&mut lq, secs(30), &stats).is_some());
    assert!(due_report(&mut lq, secs(30), &stats).is_none());
    assert_eq!(lq.poll_timeout(), Some(secs(31)));
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
    lq.handle_frame(secs(0), &f);
    let r = due_report(&mut lq, secs(1), &ReaderStats::default()).unwrap();
    assert_eq!((r.rssi, r.remote_rssi), (-77, i8::MAX));

    let config = LinkQualityConfig {
        radio_status: None,
        ..config()
    };
    let mut ignoring = LinkQuality::new(config, secs(0));
    ignoring.handle_frame(secs(0), &f);
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
