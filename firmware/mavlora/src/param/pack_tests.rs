use mavlink::{MavlinkVersion, MessageData};
use proptest::prelude::*;

use super::*;
use crate::dialect::{MavMessage, PARAM_VALUE_DATA};
use crate::param::param_value_frame;

fn value(name: &[u8], v: [u8; 4], index: u16, t: u8) -> ParamValue {
    let mut n = [0u8; 16];
    n[..name.len()].copy_from_slice(name);
    ParamValue {
        value: v,
        count: 1396,
        index,
        name: n,
        param_type: t,
    }
}

/// Packs all of `values` into frames of `cap` bytes and reads them back.
fn round_trip(values: &[ParamValue], cap: usize) -> (Vec<ParamValue>, usize) {
    let mut rest = values;
    let mut out = Vec::new();
    let mut frames = 0;
    while !rest.is_empty() {
        let (n, data) = pack(rest, cap);
        assert!(n > 0, "{:?} did not pack", rest[0]);
        assert!(data.len() <= cap.clamp(MAX_VALUE_BYTES, MAX_DATA));
        let f = frame(7, &rest[..n], &data);
        // through the dialect's own serialisation, as the radio carries it (trailing zeros
        // trimmed)
        let mut payload = [0u8; 255];
        let len = f.ser(MavlinkVersion::V2, &mut payload);
        let f = MAVLORA_PARAM_VALUES_DATA::deser(MavlinkVersion::V2, &payload[..len]).unwrap();
        out.extend(unpack(&f).unwrap());
        frames += 1;
        rest = &rest[n..];
    }
    (out, frames)
}

#[test]
fn neighbours_share_their_names_and_short_values_cost_little() {
    let list = [
        value(b"ATC_RAT_PIT_D", 0.0036f32.to_le_bytes(), 0, 9),
        value(b"ATC_RAT_PIT_FF", [0; 4], 1, 9),
        value(b"ATC_RAT_PIT_FLTD", 20.0f32.to_le_bytes(), 2, 9),
        value(b"BAT1_N_CELLS", 4i32.to_le_bytes(), 5, 6),
        value(b"BAT1_R_INTERNAL", (-1.0f32).to_le_bytes(), 6, 9),
    ];
    let (n, data) = pack(&list, MAX_DATA);
    assert_eq!(n, 5);
    // headers 2 each; names 13, "FF", "LTD", 12, "R_INTERNAL"; values 4, 0, 2, 1, 2 bytes;
    // the step of 3 one byte
    assert_eq!(data.len(), 19 + 4 + 7 + 16 + 14);
    let (back, frames) = round_trip(&list, MAX_DATA);
    assert_eq!((back.as_slice(), frames), (&list[..], 1));
}

#[test]
fn what_a_frame_cannot_carry_ends_the_run() {
    let a = value(b"A", [1, 2, 3, 4], 4, 9);
    // another count, the same or a lower index, a type above 15, an all-zero name
    for b in [
        ParamValue {
            count: 5,
            ..value(b"B", [0; 4], 5, 9)
        },
        value(b"B", [0; 4], 4, 9),
        value(b"B", [0; 4], 3, 9),
        value(b"B", [0; 4], 5, 16),
        value(b"", [0; 4], 5, 9),
    ] {
        assert_eq!(pack(&[a, b], MAX_DATA).0, 1, "{b:?}");
    }
    assert_eq!(pack(&[value(b"", [0; 4], 0, 9)], MAX_DATA).0, 0);
    // 255 values at most
    let many: Vec<_> = (0..300).map(|i| value(b"X", [0; 4], i, 1)).collect();
    assert_eq!(pack(&many, MAX_DATA).0, 66, "3 bytes each: 200 bytes");
    let tiny: Vec<_> = (0..300).map(|i| value(b"X", [0; 4], i, 1)).collect();
    assert!(pack(&tiny, 1000).1.len() <= MAX_DATA);
}

/// A frame carries whatever bytes an autopilot put in a name: after a terminating zero too.
#[test]
fn names_come_back_to_the_last_byte() {
    let odd = value(b"AB\0junk\xff", [0; 4], 0, 0);
    let full = value(b"SIXTEEN_CHARS_XY", [0x7f, 0xc0, 0x00, 0x01], 1, 15);
    let (back, _) = round_trip(&[odd, full], MAX_DATA);
    assert_eq!(back, vec![odd, full]);
}

#[test]
fn malformed_frames_are_refused() {
    let good = frame(1, &[value(b"AB", [0; 4], 0, 9)], &[0x10, b'A', b'B', 0x09]);
    assert!(unpack(&good).is_ok());
    let with = |values: u8, bytes: &[u8]| {
        let mut f = good.clone();
        f.values = values;
        f.data = [0; MAX_DATA];
        f.data[..bytes.len()].copy_from_slice(bytes);
        unpack(&f)
    };
    assert_eq!(with(0, &[]), Err(ParamPackError::Empty));
    // the first value keeps a character of nothing
    assert_eq!(with(1, &[0x11, b'A', 9]), Err(ParamPackError::Name(0)));
    // keep 15 + 2 new: 17 characters
    assert_eq!(
        with(
            2,
            &[
                0xF0, b'A', b'B', b'C', b'D', b'E', b'F', b'G', b'H', b'I', b'J', b'K', b'L', b'M',
                b'N', b'O', b'P', 9, 0x1F, b'Q', b'R', 9
            ]
        ),
        Err(ParamPackError::Name(1))
    );
    // a name ending in a zero byte
    assert_eq!(
        with(1, &[0x10, b'A', 0, 9, 1]),
        Err(ParamPackError::Name(0))
    );
    // an index step on the first value
    assert_eq!(
        with(1, &[0x00, b'A', 0x89, 0]),
        Err(ParamPackError::Index(0))
    );
    // an index past 65535
    let mut last = good.clone();
    last.param_index = u16::MAX;
    last.values = 2;
    last.data[..7].copy_from_slice(&[0x10, b'A', b'B', 0x09, 0x00, b'C', 0x09]);
    assert_eq!(unpack(&last), Err(ParamPackError::Index(1)));
    // a step varint too long
    assert_eq!(
        with(2, &[0x00, b'A', 9, 0x00, b'B', 0x89, 0xFF, 0xFF, 0x7F]),
        Err(ParamPackError::Overflow(1))
    );
    // data claimed past the array's end: 22 bytes a value, the tenth cut at 200
    let mut long = vec![0xF0];
    long.extend([b'x'; 16]);
    long.extend([0x49, 1, 1, 1, 1]); // all four value bytes
    let mut bytes = long.repeat(10);
    bytes.truncate(MAX_DATA);
    assert_eq!(with(10, &bytes), Err(ParamPackError::Truncated(9)));
    // bytes after the last value
    assert_eq!(
        with(1, &[0x00, b'A', 9, 0, 7]),
        Err(ParamPackError::Trailing)
    );
}

#[test]
fn a_standard_frame_is_built_from_the_bytes_alone() {
    let v = value(b"SYSID_THISMAV", [0x00, 0x00, 0x80, 0x3f], 1, 9);
    let f = param_value_frame(1, 1, 7, &v);
    let expected = crate::wire::encode(
        MavlinkVersion::V2,
        crate::testutil::header(1, 1, 7),
        &MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: 1.0,
            param_count: 1396,
            param_index: 1,
            param_id: (*b"SYSID_THISMAV\0\0\0").into(),
            param_type: crate::dialect::MavParamType::MAV_PARAM_TYPE_REAL32,
        }),
    );
    assert_eq!(f.as_bytes(), expected.as_bytes());
    assert!(f.crc_matches(PARAM_VALUE_DATA::EXTRA_CRC));
    // an all-zero payload keeps its first byte
    let zero = ParamValue::from_payload(&[]).unwrap();
    assert_eq!(param_value_frame(1, 1, 0, &zero).payload_len(), 1);
    assert_eq!(ParamValue::from_payload(&[0; 26]), None);
}

fn arb_value() -> impl Strategy<Value = (Vec<u8>, u32, u8, u16)> {
    (
        // names of 1..=16 bytes, any bytes (zeros inside too), never ending in zero
        proptest::collection::vec(any::<u8>(), 0..=15).prop_flat_map(|head| {
            (Just(head), 1u8..=255).prop_map(|(mut h, last)| {
                h.push(last);
                h
            })
        }),
        prop_oneof![
            any::<u32>(),
            // NaNs with any payload, signalling ones included
            (any::<bool>(), 1u32..0x0080_0000, any::<bool>()).prop_map(|(s, payload, quiet)| {
                (u32::from(s) << 31) | 0x7F80_0000 | (u32::from(quiet) << 22) | payload
            }),
            (0u32..256).prop_map(|v| v << 24),
            (0u32..256),
            Just(0),
            Just(u32::MAX),
        ],
        0u8..=MAX_TYPE,
        // index steps: mostly 1, sometimes a skip of any size
        prop_oneof![4 => Just(1u16), 1 => 2u16..3, 1 => 1u16..=2000],
    )
}

proptest! {
    /// Any run of values comes back exactly: every name byte, every value bit (NaNs too),
    /// type, count and index; whatever the frame size.
    #[test]
    fn any_list_comes_back_exactly(
        first in 0u16..1000,
        count in any::<u16>(),
        parts in proptest::collection::vec(arb_value(), 1..120),
        cap in 0usize..260,
    ) {
        let mut index = u32::from(first);
        let mut list = Vec::new();
        for (name, v, t, step) in parts {
            if index > u32::from(u16::MAX) {
                break;
            }
            let mut n = [0u8; 16];
            n[..name.len()].copy_from_slice(&name);
            list.push(ParamValue {
                value: v.to_le_bytes(),
                count,
                index: index as u16,
                name: n,
                param_type: t,
            });
            index += u32::from(step);
        }
        let (back, _) = round_trip(&list, cap);
        prop_assert_eq!(&back, &list);
        for v in &list {
            let f = param_value_frame(3, 1, 0, v);
            let payload = ParamValue::from_payload(f.payload()).unwrap();
            prop_assert_eq!(payload, *v);
        }
    }

    /// Whatever a frame holds, reading it never panics, and what it reads packs again into
    /// a frame that reads the same.
    #[test]
    fn any_frame_reads_or_is_refused(
        values in any::<u8>(),
        index in any::<u16>(),
        data in proptest::collection::vec(any::<u8>(), 0..=MAX_DATA),
    ) {
        let mut f = frame(1, &[], &data);
        f.values = values;
        f.param_index = index;
        if let Ok(read) = unpack(&f) {
            prop_assert_eq!(read.len(), usize::from(values));
            let (n, again) = pack(&read, MAX_DATA);
            prop_assert_eq!(n, read.len());
            prop_assert_eq!(unpack(&frame(1, &read, &again)).unwrap(), read);
        }
    }
}
