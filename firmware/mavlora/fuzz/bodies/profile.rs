//! Profile files (TOML, from the operator). Invariants, on every input:
//! - any text either parses into a profile or is refused with an error that names the origin
//!   and a line (`fuzz.toml:N:` for the profile's own checks, the TOML parser's "line N"
//!   otherwise); never a panic;
//! - every rate an accepted profile holds (its default, each message's `radio` and
//!   `stream_hz`) is within `MIN_RATE_HZ..=MAX_RATE_HZ` (`stream_hz` may also be 0, "stop");
//! - an accepted profile can be used: the stream requests it makes for the flight controller
//!   and the radio filter limiting each of its messages at any time never panic (validation
//!   alone does not prove that a value it lets through is safe at run time);
//! - an accepted `[compact]` table is within its documented ranges, and a compactor with it
//!   turns a few seconds of positions into frames without a panic.

use mavlink::{MavHeader, MavlinkVersion, Message as _};
use mavlora::compact::{Compactor, MAX_BATCH_SAMPLES};
use mavlora::dialect::MavMessage;
use mavlora::dialect::{GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA};
use mavlora::filter::{
    COMPACT_BATCH_PERIOD_MS, COMPACT_COALESCE_MS, COMPACT_SAMPLE_HZ, COMPACT_STATUS_PERIOD_MS,
    MAX_RATE_HZ, MIN_RATE_HZ, Profile, RadioFilter, RadioRule, request_data_stream_requests,
    set_message_interval_requests,
};
use mavlora::wire::encode;
use mavlora::{Duration, Instant};

fn rate_ok(hz: f64) -> bool {
    (MIN_RATE_HZ..=MAX_RATE_HZ).contains(&hz)
}

fn check_rule(rule: RadioRule, what: &str) {
    if let RadioRule::MaxRate(hz) = rule {
        assert!(rate_ok(hz), "{what}: radio rate {hz} accepted");
    }
}

/// "fuzz.toml:<digit>" or the TOML parser's "line <digit>".
fn located(message: &str) -> bool {
    let after = |pat: &str| {
        message
            .match_indices(pat)
            .any(|(i, _)| message[i + pat.len()..].starts_with(|c: char| c.is_ascii_digit()))
    };
    after("fuzz.toml:") || after("line ")
}

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let profile = match Profile::parse(text, "fuzz.toml") {
        Ok(profile) => profile,
        Err(e) => {
            let message = e.to_string();
            assert!(
                message.contains("fuzz.toml"),
                "error without its origin: {message}"
            );
            assert!(located(&message), "error without a line: {message}");
            return;
        }
    };
    check_rule(profile.default_radio(), "defaults");
    for (id, rule) in profile.rules() {
        check_rule(rule.radio, &format!("message {id}"));
        if let Some(hz) = rule.stream_hz {
            assert!(
                hz == 0.0 || rate_ok(hz),
                "message {id}: stream_hz {hz} accepted"
            );
        }
    }
    let _ = set_message_interval_requests(&profile, 1, 1);
    let _ = request_data_stream_requests(&profile, 1, 1);
    if let Some(c) = profile.compact() {
        let ms = |d: Duration| d.as_millis() as i64;
        assert!(COMPACT_SAMPLE_HZ.contains(&c.sample_hz), "{c:?}");
        assert!((1..=MAX_BATCH_SAMPLES).contains(&c.batch_samples), "{c:?}");
        assert!(
            COMPACT_BATCH_PERIOD_MS.contains(&ms(c.batch_period)),
            "{c:?}"
        );
        assert!(
            COMPACT_STATUS_PERIOD_MS.contains(&ms(c.status_period)),
            "{c:?}"
        );
        assert!(COMPACT_COALESCE_MS.contains(&ms(c.coalesce)), "{c:?}");
        let mut compactor = Compactor::new(c);
        let mut now = Instant::ZERO;
        for k in 0..40u32 {
            now += Duration::from_millis(100);
            if k % 10 == 0 {
                compactor.observe(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()), now);
            }
            let pos = GLOBAL_POSITION_INT_DATA {
                time_boot_ms: k * 100,
                lat: k as i32 * 50,
                ..Default::default()
            };
            compactor.observe(&MavMessage::GLOBAL_POSITION_INT(pos), now);
            while compactor.poll(now).is_some() {}
            assert!(
                compactor.poll_timeout().is_some(),
                "a compactor that never wakes"
            );
        }
    }

    // Each named message through the filter: twice at once, then far apart (the limiter's
    // interval arithmetic at the profile's extreme rates).
    let ids: Vec<u32> = profile.rules().map(|(id, _)| id).collect();
    let mut filter = RadioFilter::new(profile);
    let header = MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    };
    for id in ids {
        let Some(message) = MavMessage::default_message_from_id(id) else {
            continue;
        };
        let frame = encode(MavlinkVersion::V2, header, &message);
        for at in [
            Instant::ZERO,
            Instant::ZERO,
            Instant::ZERO + Duration::from_secs(86_400 * 365),
        ] {
            let _ = filter.check(&frame, at);
        }
    }
}
