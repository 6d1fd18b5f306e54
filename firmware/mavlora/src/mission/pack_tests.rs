use super::*;
use crate::dialect::{MavCmd, MavFrame};
use proptest::prelude::*;

const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;

/// The simulated ground station's survey: a waypoint every 100 m, climbing 1 m each.
fn survey(n: u16) -> Vec<MISSION_ITEM_INT_DATA> {
    (0..n)
        .map(|seq| MISSION_ITEM_INT_DATA {
            seq,
            target_system: 1,
            target_component: 1,
            command: MavCmd::MAV_CMD_NAV_WAYPOINT,
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            x: 553_700_000 + i32::from(seq) * 1000,
            y: 103_900_000 - i32::from(seq) * 700,
            z: 50.0 + f32::from(seq),
            autocontinue: 1,
            ..Default::default()
        })
        .collect()
}

fn roundtrip(items: &[MISSION_ITEM_INT_DATA], cap: usize) -> Vec<MISSION_ITEM_INT_DATA> {
    let count = items.last().map_or(0, |i| i.seq + 1);
    let mut got = Vec::new();
    for f in frames(7, count, (1, 1), items[0].mission_type, items, cap) {
        let MavMessage::MAVLORA_MISSION_ITEMS(p) = f else {
            panic!("not a packed frame");
        };
        // through the wire: MAVLink 2 trims the unused tail of `data`
        let mut buf = [0u8; 255];
        let len = p.ser(MavlinkVersion::V2, &mut buf);
        let back = MAVLORA_MISSION_ITEMS_DATA::deser(MavlinkVersion::V2, &buf[..len]).unwrap();
        got.extend(unpack(&back).unwrap());
    }
    got
}

#[test]
fn a_survey_round_trips_exactly_in_a_fifth_of_the_bytes() {
    let items = survey(100);
    assert_eq!(roundtrip(&items, MAX_DATA), items);
    let fs = frames(7, 100, (1, 1), items[0].mission_type, &items, MAX_DATA);
    let bytes: usize = fs
        .iter()
        .map(|f| {
            crate::wire::encode(MavlinkVersion::V2, Default::default(), f)
                .as_bytes()
                .len()
        })
        .sum();
    // 49 bytes per MISSION_ITEM_INT frame; measured: 5 frames, 945 bytes
    assert!(bytes * 5 < 100 * 49, "{} frames, {bytes} bytes", fs.len());
    assert!(fs.len() <= 5, "{}", fs.len());
}

#[test]
fn awkward_values_round_trip_bit_for_bit() {
    let mut items = survey(6);
    items[1].param1 = f32::from_bits(0x7FC0_1234); // a NaN with a payload
    items[2].param2 = -0.0;
    items[2].x = i32::MIN;
    items[3].x = i32::MAX;
    items[3].y = i32::MIN;
    items[3].command = MavCmd::MAV_CMD_DO_CHANGE_SPEED;
    items[3].frame = MavFrame::MAV_FRAME_MISSION;
    items[4].current = 1;
    items[4].autocontinue = 0;
    items[5].param4 = f32::INFINITY;
    items[5].z = f32::MIN_POSITIVE / 2.0; // subnormal
    for i in &mut items {
        i.mission_type = FENCE;
    }
    let got = roundtrip(&items, MAX_DATA);
    assert_eq!(got.len(), items.len());
    for (g, i) in got.iter().zip(&items) {
        assert_eq!(g.param1.to_bits(), i.param1.to_bits());
        assert_eq!(g.param2.to_bits(), i.param2.to_bits());
        assert_eq!(g.param4.to_bits(), i.param4.to_bits());
        assert_eq!(g.z.to_bits(), i.z.to_bits());
        assert_eq!(
            (g.x, g.y, g.command, g.frame),
            (i.x, i.y, i.command, i.frame)
        );
        assert_eq!(
            (g.seq, g.current, g.autocontinue),
            (i.seq, i.current, i.autocontinue)
        );
        assert_eq!(g.mission_type, FENCE);
    }
}

#[test]
fn a_small_cap_splits_into_more_frames_each_readable_alone() {
    let items = survey(30);
    let fs = frames(7, 30, (1, 1), items[0].mission_type, &items, 60);
    assert!(fs.len() >= 3, "{}", fs.len());
    // Drop every other frame: the rest still decode, to their own items.
    for f in fs.iter().step_by(2) {
        let MavMessage::MAVLORA_MISSION_ITEMS(p) = f else {
            unreachable!()
        };
        let got = unpack(p).unwrap();
        let span = span(p);
        assert_eq!(got.len(), span.len());
        assert_eq!(got, items[span.start as usize..span.end as usize]);
    }
}

fn one_frame(items: &[MISSION_ITEM_INT_DATA]) -> MAVLORA_MISSION_ITEMS_DATA {
    match frames(7, 100, (1, 1), items[0].mission_type, items, MAX_DATA).remove(0) {
        MavMessage::MAVLORA_MISSION_ITEMS(p) => p,
        _ => unreachable!(),
    }
}

#[test]
fn damaged_frames_are_refused_not_misread() {
    let items = survey(3);
    let good = one_frame(&items);
    // A mask of 0 is an item equal to the one before (zeros are items, not padding): the
    // 200th item's mask runs past the data's end.
    let mut p = good.clone();
    p.count = 300;
    p.items = 200;
    p.data = [0; MAX_DATA];
    p.data[MAX_DATA - 1] = 0x81;
    assert_eq!(unpack(&p), Err(PackError::Truncated(199)));
    let mut p = good.clone();
    p.seq = 99; // past the plan's 100
    assert!(matches!(unpack(&p), Err(PackError::Range { .. })));
    let mut p = good.clone();
    p.items = 0;
    assert!(matches!(unpack(&p), Err(PackError::Range { .. })));
    let mut p = good.clone();
    p.data[0] = 0x80; // mask varint continues...
    p.data[1] = 0x40; // ...into bit 13: no such field
    assert!(matches!(
        unpack(&p),
        Err(PackError::UnknownFields { item: 0, .. })
    ));
    let mut p = good.clone();
    p.data[..6].copy_from_slice(&[0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x01]);
    assert!(matches!(unpack(&p), Err(PackError::Overflow(0))));
    // A command number the dialect does not know: refused as a MISSION_ITEM_INT would be.
    let mut p = one_frame(&[MISSION_ITEM_INT_DATA::default()]);
    let mut data = Vec::new();
    put_varint(&mut data, COMMAND);
    put_varint(&mut data, zigzag(65_000));
    p.data = [0; MAX_DATA];
    p.data[..data.len()].copy_from_slice(&data);
    assert_eq!(unpack(&p), Err(PackError::Invalid(0)));
}

const COMMANDS: [MavCmd; 5] = [
    MavCmd::MAV_CMD_NAV_WAYPOINT,
    MavCmd::MAV_CMD_NAV_LOITER_TIME,
    MavCmd::MAV_CMD_NAV_LAND,
    MavCmd::MAV_CMD_DO_CHANGE_SPEED,
    MavCmd::MAV_CMD_DO_SET_SERVO,
];
const FRAMES: [MavFrame; 3] = [
    MavFrame::MAV_FRAME_GLOBAL,
    MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
    MavFrame::MAV_FRAME_MISSION,
];

fn any_item() -> impl Strategy<Value = MISSION_ITEM_INT_DATA> {
    (
        any::<[u32; 5]>(),
        any::<(i32, i32)>(),
        0..COMMANDS.len(),
        0..FRAMES.len(),
        any::<(u8, u8)>(),
    )
        .prop_map(
            |(f, (x, y), c, fr, (current, autocontinue))| MISSION_ITEM_INT_DATA {
                param1: f32::from_bits(f[0]),
                param2: f32::from_bits(f[1]),
                param3: f32::from_bits(f[2]),
                param4: f32::from_bits(f[3]),
                z: f32::from_bits(f[4]),
                x,
                y,
                command: COMMANDS[c],
                frame: FRAMES[fr],
                current,
                autocontinue,
                target_system: 1,
                target_component: 1,
                ..Default::default()
            },
        )
}

proptest! {
    #[test]
    fn any_plan_round_trips_bit_for_bit(mut items in prop::collection::vec(any_item(), 1..60)) {
        for (seq, i) in items.iter_mut().enumerate() {
            i.seq = seq as u16;
        }
        let got = roundtrip(&items, MAX_DATA);
        prop_assert_eq!(got.len(), items.len());
        for (g, i) in got.iter().zip(&items) {
            let bits = |i: &MISSION_ITEM_INT_DATA| {
                [i.param1, i.param2, i.param3, i.param4, i.z].map(f32::to_bits)
            };
            prop_assert_eq!(bits(g), bits(i));
            prop_assert_eq!((g.x, g.y, g.seq, g.command, g.frame), (i.x, i.y, i.seq, i.command, i.frame));
            prop_assert_eq!((g.current, g.autocontinue), (i.current, i.autocontinue));
        }
    }

    #[test]
    fn arbitrary_data_is_read_or_refused_never_a_panic(
        data in prop::collection::vec(any::<u8>(), 0..MAX_DATA),
        items in 0u8..=255,
        seq in 0u16..300,
    ) {
        let mut p = MAVLORA_MISSION_ITEMS_DATA { count: 300, seq, items, ..Default::default() };
        p.data[..data.len()].copy_from_slice(&data);
        if let Ok(got) = unpack(&p) {
            prop_assert_eq!(got.len(), usize::from(items));
        }
    }
}
