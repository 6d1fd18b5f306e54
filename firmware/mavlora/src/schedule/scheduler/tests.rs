use std::collections::HashMap;

use mavlink::MavlinkVersion;
use proptest::prelude::*;

use super::*;
use crate::testutil::raw_frame;
use crate::wire::ids::{
    COMMAND_LONG, FILE_TRANSFER_PROTOCOL, GLOBAL_POSITION_INT, HEARTBEAT, PARAM_REQUEST_READ,
    PARAM_VALUE, STATUSTEXT,
};

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
        PARAM_REQUEST_READ => 20,
        FILE_TRANSFER_PROTOCOL => 200,
        STATUSTEXT => 51,
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

/// A status text of `severity` (MAV_SEVERITY) whose text is `n`.
fn text(severity: u8, n: u8) -> OwnedFrame {
    let mut payload = vec![severity];
    payload.extend([b'a' + n % 26; 50]);
    raw_frame(MavlinkVersion::V2, 1, 1, n, STATUSTEXT, &payload)
}

#[test]
fn commands_go_first_in_arrival_order() {
    let mut s = LinkScheduler::new(config(10_000), ms(0)).unwrap();
    s.push(frame(GLOBAL_POSITION_INT, 1, 1, 0), Class::Periodic, ms(0));
    s.push(
        frame(PARAM_REQUEST_READ, 255, 190, 0),
        Class::Protocol,
        ms(0),
    );
    s.push(text(6, 0), Class::Status, ms(0));
    s.push(frame(COMMAND_LONG, 1, 1, 1), Class::Command, ms(0));
    s.push(frame(HEARTBEAT, 1, 1, 2), Class::Command, ms(0));
    let out: Vec<_> = drain(&mut s, ms(0))
        .iter()
        .map(|f| f.message_id())
        .collect();
    assert_eq!(out[..2], [COMMAND_LONG, HEARTBEAT]);
    assert_eq!(out.len(), 5);
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
        s.push(frame(COMMAND_LONG, 1, 1, seq), Class::Command, ms(0));
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
    s.push(f, Class::Command, ms(0));
    assert!(s.poll_transmit(ms(0), len - 1).is_none());
    assert!(s.poll_transmit(ms(0), len).is_some());
}

#[test]
fn a_full_queue_drops_only_its_own_class() {
    let mut c = config(100);
    c.max_queued_bytes = MAX_FRAME_LEN;
    let mut s = LinkScheduler::new(c, ms(0)).unwrap();
    for seq in 0..6 {
        s.push(frame(COMMAND_LONG, 1, 1, seq), Class::Command, ms(0)); // 45 bytes each
    }
    // telemetry far beyond the limit (distinct senders: no replacement)
    for sys in 1..=20 {
        s.push(
            frame(GLOBAL_POSITION_INT, sys, 1, 0),
            Class::Periodic,
            ms(0),
        );
    }
    let st = s.stats();
    assert_eq!((st.dropped_command, st.dropped_periodic), (0, 13), "{st:?}");
    // a seventh command overflows the commands' own queue: the oldest goes
    s.push(frame(COMMAND_LONG, 1, 1, 6), Class::Command, ms(0));
    assert_eq!(s.stats().dropped_command, 1);
    assert!(s.queued_bytes() <= 2 * MAX_FRAME_LEN);
}

/// Regression (issue 22, item 12): another allowed ground station sending 100
/// PARAM_REQUEST_READ a second made 0 of 8 pilot commands run; the transfer queue was one
/// FIFO shared with commands. The pilot's commands leave first, and the pilot's own
/// transfers take turns with the flood instead of waiting behind all of it.
#[test]
fn a_flooding_ground_station_delays_neither_commands_nor_another_stations_transfers() {
    let mut s = LinkScheduler::new(config(300), ms(0)).unwrap();
    let (mut commands_out, mut pilot_reads_out, mut flood_out) = (Vec::new(), 0, 0);
    let mut t = 0;
    while t < 8_000 {
        // the flood: 100 reads a second from system 200
        s.push(
            frame(PARAM_REQUEST_READ, 200, 1, (t / 10) as u8),
            Class::Protocol,
            ms(t),
        );
        if t % 1_000 == 0 {
            // the pilot: a command and a read a second
            s.push(
                frame(COMMAND_LONG, 255, 190, (t / 1000) as u8),
                Class::Command,
                ms(t),
            );
            s.push(
                frame(PARAM_REQUEST_READ, 255, 190, (t / 1000) as u8),
                Class::Protocol,
                ms(t),
            );
        }
        for f in drain(&mut s, ms(t)) {
            match (f.message_id(), f.system_id()) {
                (COMMAND_LONG, _) => commands_out.push((f.sequence(), t)),
                (PARAM_REQUEST_READ, 255) => pilot_reads_out += 1,
                _ => flood_out += 1,
            }
        }
        t += 10;
    }
    // every command left within one frame time of 300 B/s (45 bytes: 150 ms) of its arrival
    assert_eq!(commands_out.len(), 8, "{commands_out:?}");
    for (seq, left) in &commands_out {
        assert!(left - u64::from(*seq) * 1_000 <= 150, "{commands_out:?}");
    }
    // the pilot's reads (1 a second) all left; the flood got the rest
    assert!(pilot_reads_out >= 7, "{pilot_reads_out} pilot reads out");
    assert!(
        flood_out > 0 && s.stats().dropped_protocol > 0,
        "{:?}",
        s.stats()
    );
    assert_eq!(s.stats().dropped_command, 0);
}

/// Regression (issue 22, item 12): an autopilot sending STATUSTEXT at 20 a second delayed
/// command acks to 1.5 s and lost 2 of 8; the texts queued with the acks. Acks leave first,
/// position keeps its 3 Hz, and a critical text outlives a flood of informational ones.
#[test]
fn a_status_text_flood_delays_neither_acks_nor_position_and_keeps_the_severe() {
    let mut s = LinkScheduler::new(config(251), ms(0)).unwrap();
    let (mut acks, mut positions, mut texts) = (Vec::new(), Vec::new(), Vec::new());
    let mut t = 0;
    while t < 10_000 {
        if t % 50 == 0 {
            let severity = if t == 5_000 { 2 } else { 6 }; // one CRITICAL among INFO
            s.push(text(severity, (t / 50) as u8), Class::Status, ms(t));
        }
        if t % 333 == 0 {
            s.push(
                frame(GLOBAL_POSITION_INT, 1, 1, (t / 333) as u8),
                Class::Periodic,
                ms(t),
            );
        }
        if t % 1_250 == 0 {
            s.push(
                frame(COMMAND_LONG, 1, 1, (t / 1250) as u8),
                Class::Command,
                ms(t),
            );
        }
        for f in drain(&mut s, ms(t)) {
            match f.message_id() {
                COMMAND_LONG => acks.push(t - u64::from(f.sequence()) * 1_250),
                GLOBAL_POSITION_INT => positions.push(t - u64::from(f.sequence()) * 333),
                _ => texts.push(f.payload()[0]),
            }
        }
        t += 1;
    }
    assert_eq!(acks.len(), 8, "every ack left");
    // waiting for at most the frame on the air (a text: 63 bytes, 251 ms at 251 B/s)
    assert!(acks.iter().all(|&d| d <= 260), "ack delays {acks:?} ms");
    // each position left before the next one came: none replaced, none lost
    assert_eq!(s.stats().replaced, 0, "{:?}", s.stats());
    assert!(positions.len() >= 29, "{} positions", positions.len());
    assert!(
        positions.iter().all(|&d| d < 333),
        "position delays {positions:?} ms"
    );
    assert!(texts.contains(&2), "the critical text was dropped");
    assert!(s.stats().dropped_status > 0);
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
        s.push(frame(COMMAND_LONG, 1, 1, seq), Class::Command, ms(0));
    }
    let st = s.stats();
    assert_eq!((st.dropped_command, st.dropped_param), (0, 0), "{st:?}");
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

/// Every lane kept busy gets at least its weight's share of the bytes; an idle lane's share
/// goes to the busy ones.
#[test]
fn busy_classes_get_their_shares() {
    let shares = |busy: &[Class]| {
        let mut s = LinkScheduler::new(config(400), ms(0)).unwrap();
        let mut bytes = [0usize; 4];
        for t in (0..60_000).step_by(10) {
            for (i, &class) in busy.iter().enumerate() {
                let seq = (t / 10) as u8;
                let f = match class {
                    Class::Periodic => frame(GLOBAL_POSITION_INT, 1 + (seq % 3), 1, seq),
                    Class::Protocol => frame(FILE_TRANSFER_PROTOCOL, 255, 190, seq),
                    Class::Status => text(6, seq),
                    _ => frame(PARAM_VALUE, 1, 1, seq),
                };
                if class != Class::Periodic || t % 30 == 0 || i == 0 {
                    s.push(f, class, ms(t));
                }
            }
            for f in drain(&mut s, ms(t)) {
                let lane = match Class::of(f.message_id()) {
                    Class::Periodic => 0,
                    Class::Protocol => 1,
                    Class::Status => 2,
                    _ => 3,
                };
                bytes[lane] += f.as_bytes().len();
            }
        }
        let total: usize = bytes.iter().sum();
        bytes.map(|b| b as f64 / total as f64)
    };
    let all = shares(&[
        Class::Periodic,
        Class::Protocol,
        Class::Status,
        Class::Param,
    ]);
    for (lane, weight) in WEIGHTS.iter().enumerate() {
        let due = *weight as f64 / WEIGHTS.iter().sum::<u64>() as f64;
        assert!(all[lane] >= 0.95 * due, "lane {lane}: {all:?}");
    }
    // parameters against telemetry alone: 1 of 9
    let two = shares(&[Class::Periodic, Class::Param]);
    assert!(two[3] >= 0.95 / 9.0, "{two:?}");
}

// ---------------------------------------------------------------------------------------------

#[derive(Debug, Clone)]
enum Event {
    /// After `gap_ms`, push a frame of `payload` bytes.
    Push {
        gap_ms: u64,
        class: u8,
        sender: u8,
        msgid: u32,
        payload: usize,
    },
    /// After `gap_ms`, drain with this much room.
    Poll { gap_ms: u64, room: usize },
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        (0u64..200, 0u8..5, 1u8..3, 0u32..6, 0usize..=255).prop_map(
            |(gap_ms, class, sender, msgid, payload)| Event::Push {
                gap_ms,
                class,
                sender,
                msgid: 42_000 + msgid,
                payload
            }
        ),
        (0u64..300, prop_oneof![Just(usize::MAX), 0usize..400])
            .prop_map(|(gap_ms, room)| Event::Poll { gap_ms, room }),
    ]
}

const CLASSES: [Class; 5] = [
    Class::Command,
    Class::Protocol,
    Class::Status,
    Class::Param,
    Class::Periodic,
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn budget_order_and_accounting_hold_for_random_arrivals(
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
        // message frames (never replaced) by (class, sender), in arrival order
        let mut messages_in: HashMap<(usize, u8), Vec<Vec<u8>>> = HashMap::new();
        let mut messages_out: HashMap<(usize, u8), Vec<Vec<u8>>> = HashMap::new();
        let mut class_of: HashMap<Vec<u8>, usize> = HashMap::new();
        let (mut commands_in, mut commands_out) = (0u64, 0u64);
        let mut next_seq = 0u8;
        for e in events {
            match e {
                Event::Push { gap_ms, class, sender, msgid, payload } => {
                    now += gap_ms;
                    next_seq = next_seq.wrapping_add(1);
                    let f = raw_frame(MavlinkVersion::V2, sender, 1, next_seq, msgid, &vec![0x33; payload]);
                    let c = usize::from(class);
                    if CLASSES[c] != Class::Periodic {
                        messages_in.entry((c, sender)).or_default().push(f.as_bytes().to_vec());
                        class_of.insert(f.as_bytes().to_vec(), c);
                    }
                    commands_in += u64::from(CLASSES[c] == Class::Command);
                    s.push(f, CLASSES[c], ms(now));
                    prop_assert!(s.queued_bytes() <= 3 * queue_limit + (queue_limit / 4).max(MAX_FRAME_LEN));
                }
                Event::Poll { gap_ms, room } => {
                    now += gap_ms;
                    let mut left = room;
                    while let Some(f) = s.poll_transmit(ms(now), left) {
                        let len = f.as_bytes().len();
                        prop_assert!(len <= left);
                        left -= len;
                        released.push((now * 1000, len));
                        let c = class_of.get(f.as_bytes()).copied();
                        if c == Some(0) {
                            commands_out += 1;
                        } else {
                            // nothing else leaves while a command waits
                            prop_assert_eq!(commands_in, commands_out + s.stats().dropped_command);
                        }
                        if let Some(c) = c {
                            messages_out.entry((c, f.system_id())).or_default().push(f.as_bytes().to_vec());
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
        // Each origin's messages of a class leave in their order: what left is an ordered
        // subsequence of what came in; nothing went missing uncounted.
        for (key, out) in &messages_out {
            let mut it = messages_in[key].iter();
            for f in out {
                prop_assert!(it.any(|x| x == f), "{:?}: frame out of order", key);
            }
        }
        let st = s.stats();
        let total_in: usize = messages_in.values().map(Vec::len).sum();
        let total_out: usize = messages_out.values().map(Vec::len).sum();
        prop_assert_eq!(
            total_in as u64,
            total_out as u64
                + st.dropped_command
                + st.dropped_protocol
                + st.dropped_status
                + st.dropped_param
                + s.queued_frames().0 as u64
                + s.queued_params() as u64
        );
    }
}

/// Issue 21: on LoRa SF7 the burst (280 bytes, half a second on air) went into the radio at
/// once, and a command or a mode change queued after it waited there, where nothing
/// overtakes. With a backlog limit the radio gets at most the limit and one frame; the rest
/// waits here, and a command pushed later leaves first.
#[test]
fn with_a_radio_backlog_limit_a_burst_waits_here_and_a_later_command_overtakes_it() {
    let mut c = config(250);
    c.burst_bytes = 600;
    let telemetry = |s: &mut LinkScheduler| {
        for sys in 1..=6 {
            s.push(
                frame(GLOBAL_POSITION_INT, sys, 1, 0),
                Class::Periodic,
                ms(0),
            );
        }
    };
    // without a limit the whole burst goes at once (six frames of 40 bytes)
    let mut s = LinkScheduler::new(c, ms(0)).unwrap();
    telemetry(&mut s);
    assert_eq!(drain(&mut s, ms(0)).len(), 6);

    // 200 ms at 250 B/s: 50 bytes
    let mut s = LinkScheduler::new(c, ms(0))
        .unwrap()
        .with_radio_backlog(Some(crate::time::Duration::from_millis(200)), ms(0));
    telemetry(&mut s);
    let first: usize = drain(&mut s, ms(0))
        .iter()
        .map(|f| f.as_bytes().len())
        .sum();
    // the limit and the frame that crossed it: two of 40 bytes, not six
    assert_eq!(first, 80, "{first} bytes at once");
    s.push(frame(COMMAND_LONG, 255, 190, 0), Class::Command, ms(10));
    let at = s.poll_timeout().unwrap();
    assert!(at > ms(10), "it waits for the radio: {at:?}");
    let next = drain(&mut s, at);
    assert_eq!(next[0].message_id(), COMMAND_LONG, "the command goes first");
    // and the average rate still holds: the six frames and the command by ~1.2 s
    let mut now = at;
    let mut left = s.queued_frames().1;
    while left > 0 {
        now = s.poll_timeout().unwrap();
        drain(&mut s, now);
        left = s.queued_frames().1;
    }
    assert!(now <= ms(1300), "{now:?}");
}

#[test]
fn a_waiting_frame_is_found_replaced_in_place_or_taken_out() {
    let mut s = LinkScheduler::new(config(100), ms(0)).unwrap();
    // parts of a sequence: never replaced by push, only by replace_waiting
    let id = crate::wire::ids::MAVLORA_COMPACT;
    let compact =
        |seq: u8, len: usize| raw_frame(MavlinkVersion::V2, 1, 191, seq, id, &vec![0x55; len]);
    s.push(frame(GLOBAL_POSITION_INT, 1, 1, 0), Class::Periodic, ms(0));
    s.push(compact(1, 30), Class::Periodic, ms(0));
    s.push(frame(HEARTBEAT, 1, 1, 0), Class::Periodic, ms(0));
    assert_eq!(s.waiting(1, 191, id), Some(Class::Periodic));
    assert_eq!(s.waiting(1, 192, id), None);
    let before = s.queued_bytes();
    s.replace_waiting(compact(2, 60)).unwrap();
    assert_eq!(s.queued_bytes(), before + 30);
    assert_eq!(s.queued_frames().1, 3, "replaced, not added");
    // taken out, the others stay in their order
    let taken = s.take_telemetry(1, 191, id);
    assert_eq!((taken.len(), taken[0].sequence()), (1, 2));
    assert_eq!(s.queued_bytes(), before - 42, "the 72 bytes it took");
    assert!(s.replace_waiting(compact(3, 30)).is_err());
    // with the commands
    s.push(compact(4, 30), Class::Command, ms(0));
    assert_eq!(s.waiting(1, 191, id), Some(Class::Command));
    s.replace_waiting(compact(5, 40)).unwrap();
    let out = drain(&mut s, ms(10_000));
    assert_eq!(out[0].message_id(), id);
    assert_eq!(out[0].sequence(), 5);
    assert_eq!(out.len(), 3);
}
