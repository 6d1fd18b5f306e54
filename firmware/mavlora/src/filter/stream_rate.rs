//! Stream-rate requests for the flight controller, from the same profile as the radio filter:
//! configuring the flight controller saved the most bandwidth in the paper (11,440 → 1,536
//! B/s), filtering on the companion computer catches what it cannot be told to stop.

// MAV_DATA_STREAM / REQUEST_DATA_STREAM are deprecated upstream in favour of
// SET_MESSAGE_INTERVAL; they are used here on purpose, for MAVLink 1 autopilots.
#![allow(deprecated)]

use crate::dialect::{
    COMMAND_LONG_DATA, MavAutopilot, MavCmd, MavMessage, REQUEST_DATA_STREAM_DATA,
};

use super::profile::Profile;

/// `MAV_CMD_SET_MESSAGE_INTERVAL` for the autopilot's mode and arming at `hz`: `HEARTBEAT` of
/// ArduPilot (it takes it), `CURRENT_MODE` of PX4 (it refuses a HEARTBEAT interval and keeps
/// 1 Hz), both of any other. Not CURRENT_MODE of ArduPilot 4.6: it refuses it with a
/// STATUSTEXT ("No ap_message for mavlink id (436)") that would cost the radio ~50 bytes per
/// try. None for 0 Hz (the autopilot's own rates: a HEARTBEAT is never stopped).
pub fn state_interval_requests(
    hz: f64,
    autopilot: Option<MavAutopilot>,
    target_system: u8,
    target_component: u8,
) -> Vec<MavMessage> {
    use crate::wire::ids;
    if hz <= 0.0 {
        return Vec::new();
    }
    let wanted: &[u32] = match autopilot {
        Some(MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA) => &[ids::HEARTBEAT],
        Some(MavAutopilot::MAV_AUTOPILOT_PX4) => &[ids::CURRENT_MODE],
        _ => &[ids::HEARTBEAT, ids::CURRENT_MODE],
    };
    wanted
        .iter()
        .map(|&id| interval_request(id, hz, target_system, target_component))
        .collect()
}

fn interval_request(id: u32, hz: f64, target_system: u8, target_component: u8) -> MavMessage {
    let interval_us = if hz == 0.0 {
        -1.0
    } else {
        (1e6 / hz).round() as f32
    };
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system,
        target_component,
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        confirmation: 0,
        param1: id as f32,
        param2: interval_us,
        // param3..6 unused; param7 = 0: send to the address that asked (the bridge)
        ..COMMAND_LONG_DATA::default()
    })
}

/// One `COMMAND_LONG` / `MAV_CMD_SET_MESSAGE_INTERVAL` per message with a `stream_hz`, in
/// message id order: interval 1e6/hz µs, or -1 (stop the stream) for 0 Hz.
///
/// The caller frames and sends them (and resends after a flight controller reboot); the
/// flight controller answers each with a `COMMAND_ACK`.
pub fn set_message_interval_requests(
    profile: &Profile,
    target_system: u8,
    target_component: u8,
) -> Vec<MavMessage> {
    profile
        .rules()
        .filter_map(|(id, rule)| rule.stream_hz.map(|hz| (id, hz)))
        .map(|(id, hz)| interval_request(id, hz, target_system, target_component))
        .collect()
}

/// One `REQUEST_DATA_STREAM` per `[data_streams]` entry of the profile, `MAV_DATA_STREAM_ALL`
/// first: the MAVLink 1 way (ArduPilot before 4.0, APM). These are not acknowledged.
pub fn request_data_stream_requests(
    profile: &Profile,
    target_system: u8,
    target_component: u8,
) -> Vec<MavMessage> {
    profile
        .data_streams()
        .iter()
        .map(|&(stream, hz)| {
            MavMessage::REQUEST_DATA_STREAM(REQUEST_DATA_STREAM_DATA {
                target_system,
                target_component,
                req_stream_id: stream,
                req_message_rate: hz,
                start_stop: u8::from(hz > 0),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::ids::{ATTITUDE, GLOBAL_POSITION_INT};

    #[test]
    fn requests_follow_the_profile() {
        let p = Profile::parse(
            "[messages.GLOBAL_POSITION_INT]\nstream_hz = 3\n[messages.ATTITUDE]\nstream_hz = 0\n\
             [messages.HEARTBEAT]\nradio = \"pass\"\n",
            "p",
        )
        .unwrap();
        let reqs = set_message_interval_requests(&p, 1, 1);
        let params: Vec<_> = reqs
            .iter()
            .map(|m| match m {
                MavMessage::COMMAND_LONG(c) => {
                    assert_eq!(c.command, MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL);
                    assert_eq!((c.target_system, c.target_component), (1, 1));
                    (c.param1, c.param2)
                }
                other => panic!("unexpected {other:?}"),
            })
            .collect();
        // ATTITUDE stopped, GLOBAL_POSITION_INT every 333,333 µs; HEARTBEAT untouched
        let id = |id: u32| id as f32;
        assert_eq!(
            params,
            vec![(id(ATTITUDE), -1.0), (id(GLOBAL_POSITION_INT), 333_333.0)]
        );
    }

    #[test]
    fn data_stream_requests_start_and_stop() {
        let p = Profile::parse("[data_streams]\nall = 0\nposition = 3\n", "p").unwrap();
        let reqs: Vec<_> = request_data_stream_requests(&p, 1, 1)
            .into_iter()
            .map(|m| match m {
                MavMessage::REQUEST_DATA_STREAM(r) => {
                    (r.req_stream_id as u32, r.req_message_rate, r.start_stop)
                }
                other => panic!("unexpected {other:?}"),
            })
            .collect();
        assert_eq!(reqs, vec![(0, 0, 0), (6, 3, 1)]);
    }
}
