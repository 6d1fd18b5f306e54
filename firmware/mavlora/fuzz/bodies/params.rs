//! Packed parameter values (`MAVLORA_PARAM_VALUES`), the router's parser of radio bytes that
//! packing added, and the bridge's packing, on arbitrary input. Invariants, on every input:
//! - reading any frame never panics; what it reads packs again into one frame that reads the
//!   same;
//! - a router fed that frame signed with the link key (so it reaches the parser, as a frame of
//!   a bridge of another version would) never panics, and either refuses it (counted, nothing
//!   to the ground) or gives the ground exactly the values it holds, as `PARAM_VALUE`s of the
//!   component it names;
//! - `PARAM_VALUE`s of any payload the flight controller sends (MAVLink 1 or 2) reach the
//!   ground through bridge and router, signed, byte for byte: nothing changed or made up,
//!   nothing more often than sent, every value that goes raw, and of those that go packed at
//!   least the newest of each index (a newer value of an index still waiting at the bridge
//!   takes the older one's place); the router refuses none of the bridge's frames.
//!
//! Input: `[mode, values, index_lo, index_hi, component, data...]`: the frame's fields and
//! data for the first two; the data's 25-byte chunks as the flight controller's payloads for
//! the third (mode bit 0: MAVLink 1).

use mavlink::{MavHeader, MavlinkVersion};
use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::dialect::{MAVLORA_PARAM_VALUES_DATA, MavMessage};
use mavlora::filter::Profile;
use mavlora::param::{ParamValue, pack};
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::SchedulerConfig;
use mavlora::signing::{SigningConfig, SigningKey, SigningState};
use mavlora::wire::{FrameReader, encode, ids, known};
use mavlora::{Duration, Instant};

/// Signing as `link_id` (1 or 2), from a state that knows the other end: a fresh one takes
/// nothing of a peer before its answer to the freshness challenge.
fn signing(link_id: u8) -> SigningConfig {
    let mut state = SigningState::default();
    state.streams.insert((3 - link_id, 0, 0), 1);
    SigningConfig {
        key: SigningKey([3; 32]),
        link_id,
        epoch: 1_000_000,
        state,
    }
}

fn router() -> Router {
    let mut r = RouterConfig::new(SchedulerConfig::for_radio(3000, 600));
    r.signing = Some(signing(2));
    Router::new(r, Instant::ZERO).expect("router")
}

/// The `PARAM_VALUE` payloads (zero-padded) the router gave the ground, with their senders.
fn at_ground(r: &mut Router) -> Vec<((u8, u8), ParamValue)> {
    let mut reader = FrameReader::new();
    while let Some(f) = r.poll_gcs_transmit() {
        reader.push(f.as_bytes());
    }
    std::iter::from_fn(|| reader.next_frame())
        .filter(|rx| rx.frame.message_id() == ids::PARAM_VALUE)
        .map(|rx| {
            let f = rx.frame;
            let v = ParamValue::from_payload(f.payload()).expect("25 bytes at most");
            ((f.system_id(), f.component_id()), v)
        })
        .collect()
}

fn frame_from(bytes: &[u8]) -> MAVLORA_PARAM_VALUES_DATA {
    let at = |k: usize| bytes.get(k).copied().unwrap_or(0);
    let data = bytes.get(4..).unwrap_or(&[]);
    let data = &data[..data.len().min(pack::MAX_DATA)];
    let mut f = pack::frame(at(3), &[], data);
    f.values = at(0);
    f.param_index = u16::from_le_bytes([at(1), at(2)]);
    f.param_count = u16::from_le_bytes([at(2), at(1)]);
    f
}

/// Reading a frame, and the router's handling of it.
fn read(r: &mut Router, bytes: &[u8]) {
    let f = frame_from(bytes);
    let read = pack::unpack(&f);
    if let Ok(values) = &read {
        assert_eq!(values.len(), usize::from(f.values));
        let (n, again) = pack::pack(values, pack::MAX_DATA);
        assert_eq!(n, values.len(), "what a frame held packs into one again");
        assert_eq!(
            pack::unpack(&pack::frame(f.component, values, &again)).as_ref(),
            Ok(values)
        );
    }
    let header = MavHeader {
        system_id: 7,
        component_id: 191,
        sequence: 0,
    };
    let plain = encode(
        MavlinkVersion::V2,
        header,
        &MavMessage::MAVLORA_PARAM_VALUES(f.clone()),
    );
    let signed = signing(1)
        .signer()
        .sign(&plain, Instant::from_millis(1))
        .expect("a known id signs");
    r.handle_radio_bytes(Instant::from_millis(1), signed.as_bytes());
    let got = at_ground(r);
    match read {
        Ok(values) => {
            let expected: Vec<_> = values.into_iter().map(|v| ((7, f.component), v)).collect();
            assert_eq!(got, expected);
            assert_eq!(r.stats().param_frames_undecodable, 0);
        }
        Err(_) => {
            assert!(got.is_empty(), "a refused frame gave the ground {got:?}");
            assert_eq!(r.stats().param_frames_undecodable, 1);
        }
    }
}

/// A `PARAM_VALUE` frame from the flight controller built from raw bytes (any type byte,
/// any value bits).
fn fc_frame(v1: bool, seq: u8, payload: &[u8; 25]) -> Vec<u8> {
    let mut bytes = if v1 {
        let mut b = vec![0xFE, 25, seq, 1, 1, 22];
        b.extend_from_slice(payload);
        b
    } else {
        let len = payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
        let mut b = vec![0xFD, len as u8, 0, 0, seq, 1, 1, 22, 0, 0];
        b.extend_from_slice(&payload[..len]);
        b
    };
    let crc = mavlink::calculate_crc(&bytes[1..], known::crc_extra(22).expect("known"));
    bytes.extend_from_slice(&crc.to_le_bytes());
    bytes
}

/// The flight controller's values through bridge and router (a fresh one: its counters and
/// its stream numbering start afresh).
fn relay(v1: bool, bytes: &[u8]) {
    let budget = SchedulerConfig::for_radio(3000, 600);
    let mut b = BridgeConfig::new(Profile::parse("", "fuzz").expect("empty profile"), budget);
    b.signing = Some(signing(1));
    let mut bridge = Bridge::new(b, Instant::ZERO).expect("bridge");
    let mut r = router();
    let mut sent: Vec<ParamValue> = Vec::new();
    let mut expected = 0;
    let mut now = Instant::ZERO;
    for (k, chunk) in bytes.chunks(25).enumerate() {
        let mut payload = [0u8; 25];
        payload[..chunk.len()].copy_from_slice(chunk);
        sent.push(ParamValue::from_payload(&payload).expect("25 bytes"));
        bridge.handle_fc_bytes(now, &fc_frame(v1, k as u8, &payload));
    }
    // at least: every value that goes raw, the newest packed one of each index
    for (k, v) in sent.iter().enumerate() {
        expected += usize::from(!v.packable() || !newer(&sent[k + 1..], v));
    }
    let mut got = Vec::new();
    // until every value came and 300 ms more (a value made up would come with them), or for
    // as long as every value takes at the budget (3000 B/s, 50 bytes a value at worst)
    let until = now + Duration::from_millis(500 + 25 * sent.len() as u64);
    let mut all_at = None;
    while now <= until && all_at.is_none_or(|t| now < t + Duration::from_millis(300)) {
        bridge.handle_timeout(now);
        while let Some(f) = bridge.poll_radio_transmit(now, 4096) {
            r.handle_radio_bytes(now, f.as_bytes());
        }
        r.handle_timeout(now);
        got.extend(at_ground(&mut r));
        if all_at.is_none() && got.len() >= expected {
            all_at = Some(now);
        }
        let next = [bridge.poll_timeout(), r.poll_timeout()]
            .into_iter()
            .flatten()
            .min()
            .unwrap_or(until);
        now = next.max(now + Duration::from_millis(5));
    }
    assert!(
        got.iter().all(|(from, _)| *from == (1, 1)),
        "not as the autopilot: {got:?}"
    );
    let got: Vec<ParamValue> = got.into_iter().map(|(_, v)| v).collect();
    // nothing made up or changed, nothing more often than sent
    let count = |list: &[ParamValue], v: &ParamValue| list.iter().filter(|w| *w == v).count();
    for v in &got {
        assert!(
            count(&got, v) <= count(&sent, v),
            "the ground got {v:?} {} times, the autopilot sent it {} times",
            count(&got, v),
            count(&sent, v)
        );
    }
    // what goes raw, each time; of what goes packed, at least the newest of each index
    for (k, v) in sent.iter().enumerate() {
        if !v.packable() {
            assert_eq!(count(&got, v), count(&sent, v), "raw {v:?} lost");
        } else if !newer(&sent[k + 1..], v) {
            assert!(
                got.contains(v),
                "the newest value of index {} lost: {v:?}",
                v.index
            );
        }
    }
    assert_eq!(r.stats().param_frames_undecodable, 0);
}

/// Whether `later` holds a packable value of `v`'s index (and count), which takes its place
/// while both wait at the bridge.
fn newer(later: &[ParamValue], v: &ParamValue) -> bool {
    later
        .iter()
        .any(|w| (w.index, w.count) == (v.index, v.count) && w.packable())
}

pub fn run(data: &[u8]) {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    read(&mut router(), rest);
    // a list of a few hundred values at most: the run stays short
    relay(mode & 1 == 1, &rest[..rest.len().min(25 * 300)]);
}
