//! A plan's identity on the radio leg: `MISSION_COUNT.opaque_id` and `MISSION_ACK.opaque_id`
//! (MAVLink 2 extension fields) carry a transfer id, so the bridge can prove the items it
//! assembled are the plan the router sent (no item of an earlier plan mixed in), and the
//! router gives the ground ACCEPTED only for an ack that names its current plan.

use crate::dialect::{MISSION_ITEM_INT_DATA, MavMissionType};

/// Transfer id: the transfer's generation in the top 8 bits (a new `MISSION_COUNT` from the
/// ground is a new transfer even for the same plan), a CRC-32 of the plan in the low 24.
/// Never 0 (the field's "invalid" value).
pub fn transfer_id(generation: u8, plan_hash: u32) -> u32 {
    let id = (u32::from(generation) << 24) | (plan_hash & 0x00FF_FFFF);
    if id == 0 { 1 } else { id }
}

/// The plan part of a transfer id.
pub fn plan_part(id: u32) -> u32 {
    id & 0x00FF_FFFF
}

/// CRC-32 of a plan: its type, count, and every field of every item except the targets
/// (which each leg rewrites). `crc32fast` rather than a hand-rolled hash.
pub fn plan_hash(mission_type: MavMissionType, items: &[MISSION_ITEM_INT_DATA]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(&[mission_type as u8]);
    h.update(&(items.len() as u32).to_le_bytes());
    for i in items {
        for p in [i.param1, i.param2, i.param3, i.param4, i.z] {
            h.update(&p.to_bits().to_le_bytes());
        }
        h.update(&i.x.to_le_bytes());
        h.update(&i.y.to_le_bytes());
        h.update(&i.seq.to_le_bytes());
        h.update(&(i.command as u32).to_le_bytes());
        h.update(&[
            i.frame as u8,
            i.current,
            i.autocontinue,
            i.mission_type as u8,
        ]);
    }
    h.finalize()
}

/// Whether two plans are the same for the autopilot (targets aside).
pub fn same_plan(a: &[MISSION_ITEM_INT_DATA], b: &[MISSION_ITEM_INT_DATA]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(x, y)| {
            MISSION_ITEM_INT_DATA {
                target_system: 0,
                target_component: 0,
                ..x.clone()
            } == MISSION_ITEM_INT_DATA {
                target_system: 0,
                target_component: 0,
                ..y.clone()
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn item(seq: u16, x: i32) -> MISSION_ITEM_INT_DATA {
        MISSION_ITEM_INT_DATA {
            seq,
            x,
            ..Default::default()
        }
    }

    #[test]
    fn hash_sees_every_item_and_the_type_but_not_the_targets() {
        let a = vec![item(0, 1), item(1, 2)];
        let mut b = a.clone();
        b[1].x = 3;
        let t = MavMissionType::MAV_MISSION_TYPE_MISSION;
        assert_ne!(plan_hash(t, &a), plan_hash(t, &b));
        assert_ne!(
            plan_hash(t, &a),
            plan_hash(MavMissionType::MAV_MISSION_TYPE_FENCE, &a)
        );
        let mut c = a.clone();
        c[0].target_component = 190;
        assert_eq!(plan_hash(t, &a), plan_hash(t, &c));
        assert!(same_plan(&a, &c) && !same_plan(&a, &b));
    }

    #[test]
    fn transfer_id_is_never_the_invalid_zero() {
        assert_eq!(transfer_id(0, 0), 1);
        assert_eq!(plan_part(transfer_id(7, 0xAB_CDEF)), 0xAB_CDEF);
        assert_eq!(transfer_id(7, 0x12AB_CDEF) >> 24, 7);
    }
}
