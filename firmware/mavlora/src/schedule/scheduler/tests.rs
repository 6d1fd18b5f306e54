use mavlink::MavlinkVersion;
use proptest::prelude::*;

use super::*;
use crate::testutil::raw_frame;
use crate::wire::ids::{COMMAND_LONG, GLOBAL_POSITION_INT, HEARTBEAT, PARAM_VALUE};

const ROOM: usize = usize::MAX;

fn config(rate: u32) -> SchedulerConfig {
    SchedulerConfig {
        rate_bytes_per_s: rate,
        burst_bytes: MAX_FRAME_LEN as u32,
        max_queued_bytes: 4096,
    }
}

/// A frame of message `id` with a full-length, non-zero payload (MAVLink 2 would truncate an
/// all-zero default message to one byte).
fn frame(id: u32, sysid: u8, compid: u8, seq: u8) -> OwnedFrame {
    let len = match id {
        GLOBAL_POSITION_INT => 28,
        COMMAND_LONG => 33,
        HEARTBEAT => 9,
        PARAM_VALUE => 25,
        _ => unreachable!("test uses only the ids above"),
    };
    raw_frame(MavlinkVersion::V2, sysid, compid, seq, id, &vec![0x55; len])
}

fn ms(t: u64) -> Instant {
    Instant::from_millis(t)
}

/// Drains everything the scheduler releases at `now`.
fn drain(s: &mut LinkScheduler, now: Instant) -> Vec<OwnedFrame> {
    std::iter::from_fn(|| s.poll_transmit(now, ROOM)).collect()
}

#[test]
fn invalid_configs_are_rejected() {
    let mut c = config(100);
    c.burst_bytes = 100;
    assert_eq!(
        LinkScheduler::new(c, ms(0)).unwrap_err(),
        ScheduleError::BurstTooSmall(100)
    );
    assert_eq!(
        LinkScheduler::new(config(0), ms(0)).unwrap_err(),
        ScheduleError::ZeroRate
    );
}

#[test]
fn priority_goes_before_periodic_in_arrival_order() {
    let mut s = LinkScheduler::new(config(10_000), ms(0)).unwrap();
    s.push(frame(GLOBAL_POSITION_INT, 1, 1, 0), Class::Periodic, ms(0));
    s.push(frame(COMMAND_LONG, 1, 1, 1), Class::Priority, ms(0));
    s.push(frame(HEARTBEAT, 1, 1, 2), Class::Priority, ms(0));
    let out: Vec<_> = drain(&mut s, ms(0))
        .iter()
        .map(|f| f.message_id())
        .collect();
    assert_eq!(out, vec![COMMAND_LONG, HEARTBEAT, GLOBAL_POSITION_INT]);
}

#[test]
fn newest_periodic_sample_replaces_the_queued_one_in_place() {
    let mut s = LinkScheduler::new(config(10_000), ms(0)).unwrap();
    s.push(frame(GLOBAL_POSITION_INT, 1, 1, 0), Class::Periodic, ms(0));
    s.push(frame(HEARTBEAT, 1, 1, 1), Class::Periodic, ms(0));
    s.push(frame(GLOBAL_POSITION_INT, 1, 1, 2), Class::Periodic, ms(0));
    // another sender's position is a different stream
    s.push(frame(GLOBAL_POSITION_INT, 2, 1, 0), Class::Periodic, ms(0));
    assert_eq!(s.queued_frames(), (0, 3));
    assert_eq!(s.stats().replaced, 1);
    let out: Vec<_> = drain(&mut s, ms(0))
        .iter()
        .map(|f| (f.system_id(), f.message_id(), f.sequence()))
        .collect();
    assert_eq!(
        out,
        vec![
            (1, GLOBAL_POSITION_INT, 2),
            (1, HEARTBEAT, 1),
            (2, GLOBAL_POSITION_INT, 0)
        ]
    );
    assert_eq!(s.queued_bytes(), 0);
}

/// Regression: eight GPS_RTCM_DATA fragments of one correction became one, because a newer
/// frame of the same (sender, message) replaced the queued one; the FC cannot rebuild the
/// correction from the last fragment. Parts of a sequence all leave, in order.
#[test]
fn sequence_fragments_are_never_replaced() {
    use crate::wire::ids::{GPS_RTCM_DATA, SERIAL_CONTROL};
    let mut s = LinkScheduler::new(config(100_000), ms(0)).unwrap();
    for k in 0..8u8 {
        let fragment = raw_frame(MavlinkVersion::V2, 255, 190, k, GPS_RTCM_DATA, &[k + 1; 60]);
        s.push(fragment, Class::Periodic, ms(0));
    }
    for k in 0..3u8 {
        let console = raw_frame(MavlinkVersion::V2, 1, 1, k, SERIAL_CONTROL, &[k + 1; 30]);
        s.push(console, Class::Unlisted, ms(0));
    }
    assert_eq!(s.stats().replaced, 0);
    let out: Vec<_> = (0..100)
        .flat_map(|t| drain(&mut s, ms(10 * t)))
        .map(|f| (f.message_id(), f.sequence()))
        .collect();
    let rtcm: Vec<u8> = out
        .iter()
        .filter(|(id, _)| *id == GPS_RTCM_DATA)
        .map(|&(_, seq)| seq)
        .collect();
    assert_eq!(rtcm, (0..8).collect::<Vec<_>>(), "every fragment, in order");
    assert_eq!(
        out.iter().filter(|(id, _)| *id == SERIAL_CONTROL).count(),
        3
    );
}

#[test]
fn rate_is_enforced_and_poll_timeout_says_when() {
    let mut s = LinkScheduler::new(config(100), ms(0)).unwrap();
    // The burst (280 bytes) lets 6 frames of 45 bytes go at once.
    for seq in 0..10 {
        s.push(frame(COMMAND_LONG, 1, 1, seq), Class::Priority, ms(0));
    }
    let first = drain(&mut s, ms(0));
    let burst_frames = 280 / first[0].as_bytes().len();
    assert_eq!((first.len(), burst_frames), (6, 6));
    let len = first[0].as_bytes().len() as u64;
    // The next frame needs `len` more bytes at 100 B/s.
    let leftover = 280 - burst_frames as u64 * len;
    let wait_ms = ((len - leftover) * 1000).div_ceil(100);
    assert_eq!(s.poll_timeout(), Some(ms(wait_ms)));
    assert!(s.poll_transmit(ms(wait_ms - 1), ROOM).is_none());
    assert!(s.poll_transmit(ms(wait_ms), ROOM).is_some());
}

#[test]
fn the_budget_counts_the_signature_the_radio_leg_adds() {
    // 1,000 B/s, one second of a signed parameter burst: 37-byte frames are 50 bytes on air
    let rate = 1_000;
    let mut s = LinkScheduler::new(config(rate), ms(0))
        .unwrap()
        .with_frame_extra(13);
    for seq in 0..100 {
        s.push(frame(PARAM_VALUE, 1, 1, seq), Class::Param, ms(0));
    }
    let mut on_air = 0;
    for t in (0..=1_000).step_by(10) {
        on_air += drain(&mut s, ms(t))
            .iter()
            .map(|f| f.as_bytes().len() + 13)
            .sum::<usize>();
    }
    let bound = rate as usize + MAX_FRAME_LEN;
    assert!(
        on_air <= bound,
        "{on_air} bytes on air in 1 s, budget {bound}"
    );
    assert!(on_air > bound - 2 * 50, "the budget is used: {on_air}");
    assert_eq!(s.stats().sent_bytes, on_air as u64);
}

#[test]
fn frame_larger_than_the_room_waits() {
    let mut s = LinkScheduler::new(config(10_000), ms(0)).unwrap();
    let f = frame(COMMAND_LONG, 1, 1, 0);
    let len = f.as_bytes().len();
    s.push(f, Class::Priority, ms(0));
    assert!(s.poll_transmit(ms(0), len - 1).is_none());
    assert!(s.poll_transmit(ms(0), len).is_some());
}

#[test]
fn full_queue_drops_periodic_before_priority() {
    let mut c = config(100);
    c.max_queued_bytes = MAX_FRAME_LEN;
    let mut s = LinkScheduler::new(c, ms(0)).unwrap();
    let periodic = frame(GLOBAL_POSITION_INT, 1, 1, 0); // 40 bytes
    s.push(periodic, Class::Periodic, ms(0));
    for seq in 0..6 {
        s.push(frame(COMMAND_LONG, 1, 1, seq), Class::Priority, ms(0)); // 45 bytes each
    }
    // 40 + 6*45 = 310 > 280: the periodic one goes first.
    assert_eq!(s.stats().dropped_periodic, 1);
    assert_eq!(s.stats().dropped_priority, 0);
    s.push(frame(COMMAND_LONG, 1, 1, 6), Class::Priority, ms(0));
    assert_eq!(s.stats().dropped_priority, 1);
    assert!(s.queued_bytes() <= MAX_FRAME_LEN);
}

#[test]
fn named_telemetry_goes_before_unlisted_whatever_the_arrival_order() {
    let mut s = LinkScheduler::new(config(1000), ms(0)).unwrap();
    // an autopilot flooding unnamed messages (distinct senders: no replacement)
    for sys in 1..=5 {
        s.push(frame(HEARTBEAT, sys, 1, 0), Class::Unlisted, ms(0));
    }
    s.push(frame(GLOBAL_POSITION_INT, 1, 1, 0), Class::Periodic, ms(0));
    let first = s.poll_transmit(ms(0), ROOM).unwrap();
    assert_eq!(first.message_id(), GLOBAL_POSITION_INT);
}

#[test]
fn spare_traffic_leaves_a_reserve_for_named_telemetry() {
    let mut c = config(100);
    c.burst_bytes = MAX_FRAME_LEN as u32 + SPARE_RESERVE_BYTES as u32;
    let mut s = LinkScheduler::new(c, ms(0)).unwrap();
    for sys in 1..=20 {
        s.push(frame(HEARTBEAT, sys, 1, 0), Class::Unlisted, ms(0));
    }
    drain(&mut s, ms(0));
    // the unlisted flood stopped short of the reserve: a position that arrives now leaves now
    s.push(frame(GLOBAL_POSITION_INT, 1, 1, 0), Class::Periodic, ms(0));
    let out = s
        .poll_transmit(ms(0), ROOM)
        .expect("reserve kept for named telemetry");
    assert_eq!(out.message_id(), GLOBAL_POSITION_INT);
}

#[test]
fn parameter_burst_neither_evicts_commands_nor_is_dropped() {
    // regression: a PARAM_VALUE burst at boot filled the priority queue, which then dropped
    // priority frames (commands, acks) and parameters alike
    let mut c = config(300);
    c.max_queued_bytes = MAX_FRAME_LEN;
    let mut s = LinkScheduler::new(c, ms(0)).unwrap();
    for i in 0..1000u32 {
        s.push(frame(PARAM_VALUE, 1, 1, i as u8), Class::Param, ms(0));
    }
    for seq in 0..5 {
        s.push(frame(COMMAND_LONG, 1, 1, seq), Class::Priority, ms(0));
    }
    let st = s.stats();
    assert_eq!((st.dropped_priority, st.dropped_param), (0, 0), "{st:?}");
    assert_eq!(s.queued_params(), 1000);
    // commands leave first; then every parameter, in order, paced by the budget
    let mut t = 0;
    let mut out = Vec::new();
    while out.len() < 1005 && t < 1_000_000 {
        out.extend(drain(&mut s, ms(t)));
        t += 100;
    }
    assert_eq!(out.len(), 1005);
    assert!(out[..5].iter().all(|f| f.message_id() == COMMAND_LONG));
    let seqs: Vec<u8> = out[5..].iter().map(|f| f.sequence()).collect();
    assert!(seqs.iter().enumerate().all(|(i, &q)| q == i as u8));
}

#[test]
fn waiting_parameters_get_their_share_against_saturating_named_telemetry() {
    let mut s = LinkScheduler::new(config(400), ms(0)).unwrap();
    for i in 0..200u32 {
        s.push(frame(PARAM_VALUE, 1, 1, i as u8), Class::Param, ms(0));
    }
    let (mut params, mut bytes, mut param_bytes) = (0, 0, 0);
    for t in (0..60_000).step_by(10) {
        // named telemetry offered far above the budget (fresh samples from many senders)
        for sys in 1..=3 {
            s.push(
                frame(GLOBAL_POSITION_INT, sys, 1, 0),
                Class::Periodic,
                ms(t),
            );
        }
        for f in drain(&mut s, ms(t)) {
            bytes += f.as_bytes().len();
            if f.message_id() == PARAM_VALUE {
                params += 1;
                param_bytes += f.as_bytes().len();
            }
        }
    }
    let share = param_bytes as f64 / bytes as f64;
    assert!(
        params > 0 && share >= 0.95 / PARAM_SHARE_DIVISOR as f64,
        "{params} params, share {share:.3}"
    );
}

// ---------------------------------------------------------------------------------------------

#[derive(Debug, Clone)]
enum Event {
    /// After `gap_ms`, push a frame of `payload` bytes.
    Push {
        gap_ms: u64,
        priority: bool,
        sender: u8,
        msgid: u32,
        payload: usize,
    },
    /// After `gap_ms`, drain with this much room.
    Poll { gap_ms: u64, room: usize },
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        (0u64..200, any::<bool>(), 1u8..3, 0u32..6, 0usize..=255).prop_map(
            |(gap_ms, priority, sender, msgid, payload)| Event::Push {
                gap_ms,
                priority,
                sender,
                msgid: 42_000 + msgid,
                payload
            }
        ),
        (0u64..300, prop_oneof![Just(usize::MAX), 0usize..400])
            .prop_map(|(gap_ms, room)| Event::Poll { gap_ms, room }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn budget_and_priority_hold_for_random_arrivals(
        events in prop::collection::vec(event(), 1..200),
        rate in 20u32..2_000,
        extra_burst in 0u32..300,
        queue_limit in MAX_FRAME_LEN..3_000,
    ) {
        let burst = MAX_FRAME_LEN as u32 + extra_burst;
        let cfg = SchedulerConfig { rate_bytes_per_s: rate, burst_bytes: burst, max_queued_bytes: queue_limit };
        let mut s = LinkScheduler::new(cfg, Instant::ZERO).unwrap();
        let mut now = 0u64; // ms
        let mut released: Vec<(u64, usize)> = Vec::new(); // (µs, bytes)
        let mut priority_in = Vec::new();
        let mut priority_out = Vec::new();
        let mut next_seq = 0u8;
        for e in events {
            match e {
                Event::Push { gap_ms, priority, sender, msgid, payload } => {
                    now += gap_ms;
                    next_seq = next_seq.wrapping_add(1);
                    let f = raw_frame(MavlinkVersion::V2, sender, 1, next_seq, msgid, &vec![0x33; payload]);
                    let class = if priority { Class::Priority } else { Class::Periodic };
                    if priority {
                        priority_in.push(f.as_bytes().to_vec());
                    }
                    let before = s.stats();
                    s.push(f, class, ms(now));
                    let after = s.stats();
                    if after.dropped_priority > before.dropped_priority {
                        prop_assert_eq!(s.queued_frames().1, 0, "priority dropped while periodic queued");
                    }
                    prop_assert!(s.queued_bytes() <= queue_limit);
                }
                Event::Poll { gap_ms, room } => {
                    now += gap_ms;
                    let mut left = room;
                    while let Some(f) = s.poll_transmit(ms(now), left) {
                        let len = f.as_bytes().len();
                        prop_assert!(len <= left);
                        left -= len;
                        released.push((now * 1000, len));
                        if priority_in.contains(&f.as_bytes().to_vec()) {
                            priority_out.push(f.as_bytes().to_vec());
                        }
                    }
                    // A deadline still ahead means the budget holds nothing back before it.
                    if let Some(t) = s.poll_timeout() && t > ms(now) {
                        prop_assert!(s.poll_transmit(ms(now), usize::MAX).is_none());
                    }
                }
            }
        }
        // Budget: for every window between two release instants.
        for i in 0..released.len() {
            let mut bytes = 0u64;
            for (t, len) in &released[i..] {
                bytes += *len as u64;
                let window_us = t - released[i].0;
                let allowed = (u64::from(rate) * window_us).div_ceil(1_000_000) + u64::from(burst);
                prop_assert!(bytes <= allowed, "{} bytes in {} µs (allowed {})", bytes, window_us, allowed);
            }
        }
        // Priority frames leave in order: what left is a prefix-ordered subsequence of what
        // came in, and nothing was dropped unless counted.
        let mut it = priority_in.iter();
        for out in &priority_out {
            prop_assert!(it.any(|x| x == out), "priority frame out of order");
        }
        let st = s.stats();
        prop_assert_eq!(
            priority_in.len() as u64,
            priority_out.len() as u64 + st.dropped_priority + s.queued_frames().0 as u64
        );
    }
}
