//! Two compact frames that have not left yet, made one: when the radio falls behind (a
//! half-duplex LoRa channel carrying an upload, a burst of acks and texts at arming), the
//! bridge folds each new frame into the one still queued instead of queueing behind it, so
//! what leaves next carries the newest status and positions, not a status the vehicle left
//! seconds ago (issue 21: a mode change reached the ground 1.5 s late behind three older
//! frames on LoRa SF7 with real PX4).

use super::codec::{CompactFrame, MAX_SAMPLES, Positions, Status};

/// Altitude offsets (MSL minus above home, dm) closer than this share one frame's offset: the
/// compactor's own rule for starting a new frame (1 m).
const ALT_OFFSET_TOLERANCE_DM: i32 = 10;

/// What a merge gave up (counted by the bridge).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MergeLoss {
    /// Older samples dropped: past [`MAX_SAMPLES`], or under an altitude offset that moved.
    pub samples: usize,
}

/// `older` and `newer` as one frame: every status part and the link report from `newer`
/// where it has them, else from `older`; the samples of both in time order (the oldest
/// dropped past [`MAX_SAMPLES`], and all of `older`'s if the altitude offset moved more than
/// 1 m, which one frame cannot carry), with `newer`'s velocity, heading and air data.
pub fn merge(older: &CompactFrame, newer: &CompactFrame) -> (CompactFrame, MergeLoss) {
    let mut loss = MergeLoss::default();
    let positions = match (&older.positions, &newer.positions) {
        (Some(o), Some(n)) => Some(merge_positions(o, n, &mut loss)),
        (o, n) => n.clone().or_else(|| o.clone()),
    };
    let status = match (older.status, newer.status) {
        (Some(o), Some(n)) => Some(Status {
            heartbeat: n.heartbeat.or(o.heartbeat),
            sys: n.sys.or(o.sys),
            gps: n.gps.or(o.gps),
            mission: n.mission.or(o.mission),
        }),
        (o, n) => n.or(o),
    };
    let frame = CompactFrame {
        positions,
        status,
        link: newer.link.clone().or_else(|| older.link.clone()),
    };
    (frame, loss)
}

fn merge_positions(older: &Positions, newer: &Positions, loss: &mut MergeLoss) -> Positions {
    let newest_time = newer.samples.first().map(|s| s.time_boot_ms);
    let keep_older = (older.alt_offset_dm - newer.alt_offset_dm).abs() <= ALT_OFFSET_TOLERANCE_DM;
    let mut samples: Vec<_> = if keep_older {
        older
            .samples
            .iter()
            // times only go forward within a frame (an autopilot that rebooted between the two
            // starts again from its own zero: its new samples win)
            .filter(|s| newest_time.is_none_or(|t| s.time_boot_ms < t))
            .copied()
            .collect()
    } else {
        Vec::new()
    };
    loss.samples += older.samples.len() - samples.len();
    samples.extend_from_slice(&newer.samples);
    if samples.len() > MAX_SAMPLES {
        let extra = samples.len() - MAX_SAMPLES;
        samples.drain(..extra);
        loss.samples += extra;
    }
    Positions {
        samples,
        air: newer.air.or(older.air),
        ..newer.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compact::{GpsPart, HeartbeatPart, MissionPart, Sample};

    fn positions(times: &[u32], alt_offset_dm: i32) -> Positions {
        Positions {
            samples: times
                .iter()
                .map(|&t| Sample {
                    time_boot_ms: t,
                    lat: -353_632_610 + t as i32,
                    lon: 1_491_652_300,
                    rel_dm: 100,
                })
                .collect(),
            alt_offset_dm,
            vx: times.last().copied().unwrap_or(0) as i16,
            ..Default::default()
        }
    }

    fn heartbeat(custom_mode: u32) -> HeartbeatPart {
        HeartbeatPart {
            mavtype: 2,
            autopilot: 12,
            base_mode: 157,
            custom_mode,
            system_status: 4,
        }
    }

    #[test]
    fn the_newer_status_wins_part_by_part_and_the_older_fills_what_it_lacks() {
        let older = CompactFrame {
            status: Some(Status {
                heartbeat: Some(heartbeat(1)),
                mission: Some(MissionPart {
                    seq: 3,
                    ..Default::default()
                }),
                ..Default::default()
            }),
            ..Default::default()
        };
        let newer = CompactFrame {
            status: Some(Status {
                heartbeat: Some(heartbeat(2)),
                gps: Some(GpsPart::default()),
                ..Default::default()
            }),
            ..Default::default()
        };
        let (m, loss) = merge(&older, &newer);
        let s = m.status.unwrap();
        assert_eq!(s.heartbeat.unwrap().custom_mode, 2);
        assert_eq!(
            s.mission.unwrap().seq,
            3,
            "a mission change only the older carried"
        );
        assert!(s.gps.is_some());
        assert_eq!(loss, MergeLoss::default());
        // a newer frame without a status keeps the older's
        let (m, _) = merge(&older, &CompactFrame::default());
        assert_eq!(m.status, older.status);
    }

    #[test]
    fn samples_of_both_go_in_time_order_with_the_newest_velocity() {
        let older = CompactFrame {
            positions: Some(positions(&[1000, 1333, 1666], 4890)),
            ..Default::default()
        };
        let newer = CompactFrame {
            positions: Some(positions(&[2000, 2333], 4893)),
            ..Default::default()
        };
        let (m, loss) = merge(&older, &newer);
        let p = m.positions.unwrap();
        let times: Vec<u32> = p.samples.iter().map(|s| s.time_boot_ms).collect();
        assert_eq!(times, [1000, 1333, 1666, 2000, 2333]);
        assert_eq!((p.vx, p.alt_offset_dm), (2333, 4893));
        assert_eq!(loss.samples, 0);
        // and the result encodes and decodes as it is
        let again = CompactFrame::decode(&m_encoded(&p)).unwrap();
        assert_eq!(again.positions.unwrap().samples.len(), 5);
    }

    fn m_encoded(p: &Positions) -> crate::dialect::MAVLORA_COMPACT_DATA {
        CompactFrame {
            positions: Some(p.clone()),
            ..Default::default()
        }
        .encode()
        .unwrap()
    }

    #[test]
    fn past_the_sample_limit_the_oldest_go_and_are_counted() {
        let older = CompactFrame {
            positions: Some(positions(&[0, 100, 200, 300, 400, 500, 600, 700], 0)),
            ..Default::default()
        };
        let newer = CompactFrame {
            positions: Some(positions(&[800, 900, 1000, 1100], 0)),
            ..Default::default()
        };
        let (m, loss) = merge(&older, &newer);
        let p = m.positions.unwrap();
        assert_eq!(p.samples.len(), MAX_SAMPLES);
        assert_eq!(p.samples[0].time_boot_ms, 200);
        assert_eq!(loss.samples, 2);
    }

    #[test]
    fn an_altitude_offset_that_moved_drops_the_older_samples_rather_than_shift_them() {
        let older = CompactFrame {
            positions: Some(positions(&[0, 100], 0)),
            ..Default::default()
        };
        let newer = CompactFrame {
            positions: Some(positions(&[200], 50)),
            ..Default::default()
        };
        let (m, loss) = merge(&older, &newer);
        assert_eq!(m.positions.unwrap().samples.len(), 1);
        assert_eq!(loss.samples, 2);
    }

    #[test]
    fn samples_from_before_an_autopilot_reboot_are_not_put_after_its_new_ones() {
        let older = CompactFrame {
            positions: Some(positions(&[90_000, 90_333], 0)),
            ..Default::default()
        };
        let newer = CompactFrame {
            positions: Some(positions(&[500], 0)),
            ..Default::default()
        };
        let (m, loss) = merge(&older, &newer);
        let p = m.positions.unwrap();
        assert_eq!(p.samples.len(), 1);
        assert_eq!(loss.samples, 2);
        assert!(
            CompactFrame {
                positions: Some(p),
                ..Default::default()
            }
            .encode()
            .is_ok()
        );
    }

    #[test]
    fn positions_or_a_link_report_only_one_side_has_are_kept() {
        let older = CompactFrame {
            positions: Some(positions(&[0], 0)),
            ..Default::default()
        };
        let newer = CompactFrame {
            link: Some(Default::default()),
            ..Default::default()
        };
        let (m, _) = merge(&older, &newer);
        assert!(m.positions.is_some() && m.link.is_some());
    }
}
