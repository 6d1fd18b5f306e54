use mavlink::MavlinkVersion;
use proptest::prelude::*;

use super::*;
use crate::testutil::{frame, raw_frame};
use crate::wire::ids::{ATTITUDE, GLOBAL_POSITION_INT, HEARTBEAT};
use crate::wire::known;

const S11: StreamId = StreamId {
    system: 1,
    component: 1,
};

/// Feeds `input` in chunks of the given sizes (cycled), then finishes; returns all frames.
fn read_chunked(input: &[u8], chunks: &[usize]) -> (Vec<Received>, ReaderStats) {
    let mut reader = FrameReader::new();
    let mut out = Vec::new();
    let mut rest = input;
    let mut sizes = chunks.iter().copied().cycle();
    while !rest.is_empty() {
        let n = sizes.next().unwrap_or(rest.len()).clamp(1, rest.len());
        reader.push(&rest[..n]);
        rest = &rest[n..];
        while let Some(f) = reader.next_frame() {
            out.push(f);
        }
    }
    reader.finish();
    while let Some(f) = reader.next_frame() {
        out.push(f);
    }
    (out, reader.stats().clone())
}

fn read_all(input: &[u8]) -> (Vec<Received>, ReaderStats) {
    read_chunked(input, &[input.len().max(1)])
}

fn bytes_of(frames: &[Received]) -> Vec<Vec<u8>> {
    frames.iter().map(|r| r.frame.as_bytes().to_vec()).collect()
}

fn three_frames() -> Vec<OwnedFrame> {
    vec![
        frame(HEARTBEAT, 1, 1, 0),
        frame(ATTITUDE, 1, 1, 1),
        frame(GLOBAL_POSITION_INT, 1, 1, 2),
    ]
}

fn concat(parts: &[&[u8]]) -> Vec<u8> {
    parts.concat()
}

#[test]
fn clean_stream_yields_every_frame_checked() {
    let frames = three_frames();
    let input: Vec<u8> = frames.iter().flat_map(|f| f.as_bytes().to_vec()).collect();
    let (out, stats) = read_all(&input);
    assert_eq!(out.len(), 3);
    for (got, want) in out.iter().zip(&frames) {
        assert_eq!(&got.frame, want);
        assert_eq!(got.integrity, Integrity::Checked);
    }
    assert_eq!(stats.frames_checked, 3);
    assert_eq!(stats.lost, 0);
    assert_eq!(stats.garbage_bytes, 0);
}

#[test]
fn v1_frames_are_read() {
    let f = raw_frame(MavlinkVersion::V1, 3, 4, 9, ATTITUDE, &[7; 28]);
    let (out, _) = read_all(f.as_bytes());
    assert_eq!(bytes_of(&out), vec![f.as_bytes().to_vec()]);
    assert_eq!(out[0].integrity, Integrity::Checked);
}

#[test]
fn garbage_between_frames_is_skipped_and_counted() {
    let [a, b, c] = <[OwnedFrame; 3]>::try_from(three_frames()).unwrap();
    // Garbage includes both start bytes, a truncated header and a lone length byte.
    let garbage1 = [0x00, 0xFD, 0x55, 0xFE];
    let garbage2 = [0xFD, 0x09, 0x00];
    let input = concat(&[
        &garbage1,
        a.as_bytes(),
        &garbage2,
        b.as_bytes(),
        c.as_bytes(),
        &[0xFE],
    ]);
    let (out, stats) = read_all(&input);
    let checked: Vec<_> = out
        .iter()
        .filter(|r| r.integrity == Integrity::Checked)
        .collect();
    assert_eq!(checked.len(), 3);
    assert_eq!(checked[0].frame, a);
    assert_eq!(checked[1].frame, b);
    assert_eq!(checked[2].frame, c);
    assert_eq!(stats.lost, 0);
    assert_eq!(
        stats.garbage_bytes,
        (garbage1.len() + garbage2.len() + 1) as u64
    );
}

#[test]
fn split_at_every_byte_gives_the_same_frames() {
    let frames = three_frames();
    let mut input = vec![0xFE, 0x01];
    for f in &frames {
        input.extend_from_slice(f.as_bytes());
        input.extend_from_slice(&[0xFD, 0x20, 0x00]);
    }
    let (whole, whole_stats) = read_all(&input);
    assert_eq!(
        whole
            .iter()
            .filter(|r| r.integrity == Integrity::Checked)
            .count(),
        3
    );
    for split in 1..input.len() {
        let (out, stats) = read_chunked(&input, &[split, input.len()]);
        assert_eq!(bytes_of(&out), bytes_of(&whole), "split at {split}");
        assert_eq!(stats, whole_stats, "split at {split}");
    }
    let (one_by_one, _) = read_chunked(&input, &[1]);
    assert_eq!(bytes_of(&one_by_one), bytes_of(&whole));
}

#[test]
fn bad_crc_is_counted_and_the_gap_shows_as_lost() {
    let frames = three_frames();
    let mut corrupted = frames[1].as_bytes().to_vec();
    corrupted[12] ^= 0x40; // a payload byte
    let input = concat(&[frames[0].as_bytes(), &corrupted, frames[2].as_bytes()]);
    let (out, stats) = read_all(&input);
    assert_eq!(out.len(), 2);
    assert_eq!(out[0].frame, frames[0]);
    assert_eq!(out[1].frame, frames[2]);
    assert_eq!(stats.bad_crc, 1);
    let s = stats.stream(S11).unwrap();
    assert_eq!(s.bad_crc, 1);
    assert_eq!(s.lost, 1);
    assert_eq!(s.received, 2);
}

#[test]
fn frame_inside_a_corrupted_candidate_is_recovered() {
    // A corrupted header announcing a long payload, immediately followed by a good frame: the
    // good frame lies inside the bad candidate's span and must still come out.
    let good = frame(ATTITUDE, 1, 1, 5);
    let bad_header = [0xFD, 200, 0, 0, 0, 1, 1, 0, 0, 0]; // HEARTBEAT claiming 200 bytes
    let mut input = concat(&[&bad_header, good.as_bytes()]);
    input.extend(std::iter::repeat_n(0x11, 200));
    let (out, stats) = read_all(&input);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].frame, good);
    assert_eq!(stats.bad_crc, 1);
}

#[test]
fn finish_releases_a_frame_stuck_behind_an_incomplete_candidate() {
    let good = frame(ATTITUDE, 1, 1, 5);
    let input = concat(&[&[0xFD, 250, 0, 0, 0, 1, 1, 0, 0, 0], good.as_bytes()]);
    let mut reader = FrameReader::new();
    reader.push(&input);
    assert!(
        reader.next_frame().is_none(),
        "must wait for the long candidate"
    );
    reader.finish();
    assert_eq!(reader.next_frame().unwrap().frame, good);
    assert!(reader.next_frame().is_none());
    assert_eq!(reader.buffered(), 0);
}

#[test]
fn unknown_ids_are_forwarded_unchecked() {
    assert_eq!(known::crc_extra(60_000), None);
    let unknown = raw_frame(MavlinkVersion::V2, 1, 1, 0, 60_000, &[1, 2, 3]);
    let next = frame(HEARTBEAT, 1, 1, 1);
    let input = concat(&[unknown.as_bytes(), next.as_bytes()]);
    let (out, stats) = read_all(&input);
    assert_eq!(out.len(), 2);
    assert_eq!(out[0].frame, unknown);
    assert_eq!(out[0].integrity, Integrity::Unchecked);
    assert_eq!(out[1].integrity, Integrity::Checked);
    assert_eq!(stats.frames_unchecked, 1);
    assert_eq!(stats.lost, 0, "unchecked frames advance the sequence too");
}

/// Regression: ArduPilot's own messages were unknown ids, so one whose bytes hold a start
/// byte announcing a longer frame (SIMSTATE's floats often do) waited for that many more
/// bytes, or the idle flush, before it came out: HEARTBEATs behind it reached the radio
/// 71 ms late at the median. With ArduPilot's CRC_EXTRAs it is checked, and out at once.
#[test]
fn an_ardupilot_frame_holding_a_start_byte_comes_out_at_once_checked() {
    const SIMSTATE: u32 = 164;
    // 0xFD then a length of 200 inside the payload: a candidate the reader would wait on.
    let mut payload = vec![0x11; 44];
    payload[30] = 0xFD;
    payload[31] = 200;
    let simstate = raw_frame(MavlinkVersion::V2, 1, 1, 0, SIMSTATE, &payload);
    let mut reader = FrameReader::new();
    reader.push(simstate.as_bytes());
    let out = reader
        .next_frame()
        .expect("a whole, checked frame is not held");
    assert_eq!(out.frame, simstate);
    assert_eq!(out.integrity, Integrity::Checked);
    assert_eq!(reader.buffered(), 0);
    // The same bytes with a broken checksum are a bad frame, not one forwarded unchecked.
    let mut broken = simstate.as_bytes().to_vec();
    let last = broken.len() - 1;
    broken[last] ^= 0xFF;
    let mut reader = FrameReader::new();
    reader.push(&broken);
    reader.finish();
    while let Some(r) = reader.next_frame() {
        assert_ne!(r.frame.message_id(), SIMSTATE, "{r:?}");
    }
    assert_eq!(reader.stats().bad_crc, 1);
}

#[test]
fn unknown_id_garbage_does_not_swallow_a_valid_frame() {
    // Garbage that parses as an unknown-id candidate whose span covers a valid frame.
    let good = frame(GLOBAL_POSITION_INT, 1, 1, 0);
    let fake = [0xFD, 60, 0, 0, 0, 9, 9, 0x60, 0xEA, 0x00]; // msgid 60000, 60-byte payload
    let mut input = concat(&[&fake, good.as_bytes()]);
    input.extend(std::iter::repeat_n(0x22, 60));
    for chunks in [vec![input.len()], vec![1], vec![7, 3]] {
        let (out, _) = read_chunked(&input, &chunks);
        let checked: Vec<_> = out
            .iter()
            .filter(|r| r.integrity == Integrity::Checked)
            .collect();
        assert_eq!(checked.len(), 1, "chunks {chunks:?}");
        assert_eq!(checked[0].frame, good);
    }
}

#[test]
fn unsupported_incompat_flags_are_skipped() {
    let good = frame(HEARTBEAT, 1, 1, 0);
    let mut flagged = good.as_bytes().to_vec();
    flagged[2] = 0x04;
    let input = concat(&[&flagged, good.as_bytes()]);
    let (out, _) = read_all(&input);
    assert_eq!(bytes_of(&out), vec![good.as_bytes().to_vec()]);
}

#[test]
fn signed_frames_keep_their_signature() {
    let unsigned = frame(HEARTBEAT, 1, 1, 0);
    let mut signed = unsigned.as_bytes().to_vec();
    signed[2] = crate::wire::IFLAG_SIGNED; // the flags are covered by the checksum
    let end = signed.len() - 2;
    let crc = Frame::new_unchecked(&signed[..]).compute_checksum(known::crc_extra(0).unwrap());
    signed[end..].copy_from_slice(&crc.to_le_bytes());
    signed.extend_from_slice(&[0x5A; 13]);
    let (out, _) = read_all(&signed);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].frame.as_bytes(), &signed[..]);
    assert_eq!(out[0].frame.signature(), Some(&[0x5A; 13][..]));
}

// ---------------------------------------------------------------------------------------------
// Property: garbage never makes the reader lose a valid frame it does not overlap.

#[derive(Debug, Clone)]
enum Segment {
    /// A valid frame of a known id (the ones that must all come out).
    Known(OwnedFrame),
    /// A valid frame of an id the dialect does not know.
    Unknown(OwnedFrame),
    /// Random bytes, rich in start bytes.
    Garbage(Vec<u8>),
    /// The first bytes of a valid frame, cut short.
    Truncated(Vec<u8>),
}

fn garbage_byte() -> impl Strategy<Value = u8> {
    prop_oneof![3 => any::<u8>(), 1 => Just(0xFD), 1 => Just(0xFE)]
}

fn known_frame() -> impl Strategy<Value = OwnedFrame> {
    let ids = prop::sample::select(vec![0u32, 1, 24, 30, 33, 74, 76, 77, 15, 16]);
    (ids, any::<bool>(), any::<u8>(), any::<u8>(), any::<u8>())
        .prop_flat_map(|(id, v1, sys, comp, seq)| {
            let msg = <crate::dialect::MavMessage as mavlink::Message>::default_message_from_id(id)
                .expect("known id");
            let full = mavlink::Message::ser(&msg, MavlinkVersion::V1, &mut [0u8; 255]);
            // v1 carries the full payload; v2 may be truncated.
            let len = if v1 {
                Just(full).boxed()
            } else {
                (1..=full).boxed()
            };
            let payload = len.prop_flat_map(|l| prop::collection::vec(any::<u8>(), l));
            (Just((id, v1, sys, comp, seq)), payload)
        })
        .prop_map(
            |((id, v1, sys, comp, seq), payload): ((u32, bool, u8, u8, u8), Vec<u8>)| {
                let version = if v1 {
                    MavlinkVersion::V1
                } else {
                    MavlinkVersion::V2
                };
                raw_frame(version, sys, comp, seq, id, &payload)
            },
        )
}

fn segment() -> impl Strategy<Value = Segment> {
    prop_oneof![
        4 => known_frame().prop_map(Segment::Known),
        1 => (prop::collection::vec(any::<u8>(), 0..40), any::<u8>())
            .prop_map(|(p, seq)| Segment::Unknown(raw_frame(MavlinkVersion::V2, 1, 1, seq, 60_000, &p))),
        3 => prop::collection::vec(garbage_byte(), 1..40).prop_map(Segment::Garbage),
        1 => (known_frame(), any::<prop::sample::Index>()).prop_map(|(f, i)| {
            let b = f.as_bytes();
            Segment::Truncated(b[..i.index(b.len() - 1) + 1].to_vec())
        }),
    ]
}

/// True if a start byte at a position outside the known frames begins a checksum-valid
/// known-id frame: a 1-in-65536 false frame, the only way garbage can hide a valid frame.
fn garbage_forms_a_valid_frame(input: &[u8], known_spans: &[std::ops::Range<usize>]) -> bool {
    (0..input.len()).any(|pos| {
        if known_spans.iter().any(|s| s.contains(&pos)) {
            return false;
        }
        let Ok(Some(len)) = announced_len(&input[pos..]) else {
            return false;
        };
        if pos + len > input.len() {
            return false;
        }
        let f = Frame::new_unchecked(&input[pos..pos + len]);
        known::crc_extra(f.message_id()).is_some_and(|x| f.crc_matches(x))
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn garbage_never_loses_a_valid_frame(
        segments in prop::collection::vec(segment(), 1..12),
        chunks in prop::collection::vec(1usize..64, 1..8),
    ) {
        let mut input = Vec::new();
        let mut expected = Vec::new();
        let mut spans = Vec::new();
        for s in &segments {
            match s {
                Segment::Known(f) => {
                    spans.push(input.len()..input.len() + f.as_bytes().len());
                    expected.push(f.as_bytes().to_vec());
                    input.extend_from_slice(f.as_bytes());
                }
                Segment::Unknown(f) => input.extend_from_slice(f.as_bytes()),
                Segment::Garbage(b) | Segment::Truncated(b) => input.extend_from_slice(b),
            }
        }
        prop_assume!(!garbage_forms_a_valid_frame(&input, &spans));

        let (whole, _) = read_all(&input);
        let checked: Vec<Vec<u8>> = whole
            .iter()
            .filter(|r| r.integrity == Integrity::Checked)
            .map(|r| r.frame.as_bytes().to_vec())
            .collect();
        prop_assert_eq!(checked, expected);

        let (chunked, _) = read_chunked(&input, &chunks);
        prop_assert_eq!(bytes_of(&chunked), bytes_of(&whole));
    }
}

#[test]
fn flush_partial_releases_a_frame_held_behind_a_lost_tail() {
    // The first 10 bytes of a frame announcing 255 payload bytes, then a whole heartbeat:
    // the reader takes the heartbeat for the long frame's tail and waits.
    let hb = frame(HEARTBEAT, 1, 1, 0);
    let partial = [0xFD, 0xFF, 0, 0, 7, 1, 1, 0x30, 0, 0];
    let mut reader = FrameReader::new();
    reader.push(&partial);
    reader.push(hb.as_bytes());
    assert!(reader.next_frame().is_none());
    assert!(reader.flush_partial());
    // An empty push (no new bytes) does not cancel the flush.
    reader.push(&[]);
    let out = reader.next_frame().expect("the heartbeat comes out");
    assert_eq!(out.frame.as_bytes(), hb.as_bytes());
    assert!(reader.next_frame().is_none());
    assert_eq!(reader.buffered(), 0);
    let stats = reader.stats();
    assert_eq!(stats.partials_dropped, 1);
    assert_eq!(stats.garbage_bytes, partial.len() as u64);
    // Nothing buffered: nothing to flush, nothing counted.
    assert!(!reader.flush_partial());
    assert_eq!(reader.stats().partials_dropped, 1);
    // New bytes start a new input: a frame split across pushes is reassembled again.
    let (a, b) = hb.as_bytes().split_at(5);
    reader.push(a);
    assert!(reader.next_frame().is_none());
    reader.push(b);
    assert!(reader.next_frame().is_some());
}
