//! Which `PARAM_VALUE`s answer a ground station's own question: the echo of a `PARAM_SET`, the
//! answer to a `PARAM_REQUEST_READ`. Those go with the commands (priority), not behind a
//! parameter list of ~1000 frames in flight: a pilot who changes a value while a ground
//! station loads the list must see the echo within a second, not after the list (8.3 s on
//! LoRa with ArduPilot, three sends). The list's own values keep their paced queue.
//!
//! ArduPilot echoes a set with `param_index` 65535, PX4 with the parameter's index, so the
//! answer is matched by name (a set, a read by name) or by index (a read by index).

use std::collections::VecDeque;

use crate::dialect::MavMessage;
use crate::time::{Duration, Instant};

/// How long a question waits for its answer: an autopilot answers in milliseconds; a
/// ground station resends after ~1 s and is asked again then.
const HOLD: Duration = Duration::from_secs(5);
/// Questions remembered at once: a ground station re-reading a list keeps ~10 in flight.
/// More are not given priority (the list's queue still carries their answers).
const MAX_PENDING: usize = 32;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Key {
    Name([u8; 16]),
    Index(u16),
}

/// What a `PARAM_VALUE` answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Asked {
    /// A `PARAM_SET`: its echo.
    Set,
    /// A `PARAM_REQUEST_READ`.
    Read,
}

/// Questions forwarded to the flight controller, waiting for their `PARAM_VALUE`.
#[derive(Debug, Default)]
pub struct ParamAnswers {
    pending: VecDeque<(Key, Asked, Instant)>,
}

impl ParamAnswers {
    /// Notes a question from the radio that is about to reach the flight controller.
    pub fn asked(&mut self, now: Instant, msg: &MavMessage) {
        let (key, asked) = match msg {
            MavMessage::PARAM_SET(s) => (Key::Name(*s.param_id), Asked::Set),
            MavMessage::PARAM_REQUEST_READ(r) => match u16::try_from(r.param_index) {
                Ok(index) => (Key::Index(index), Asked::Read),
                // -1: by name.
                Err(_) => (Key::Name(*r.param_id), Asked::Read),
            },
            _ => return,
        };
        self.expire(now);
        self.pending.retain(|(k, a, _)| (*k, *a) != (key, asked));
        if self.pending.len() < MAX_PENDING {
            self.pending.push_back((key, asked, now + HOLD));
        }
    }

    /// Whether any question waits (else no `PARAM_VALUE` needs decoding).
    pub fn waiting(&self) -> bool {
        !self.pending.is_empty()
    }

    /// What `msg`, a `PARAM_VALUE` from the flight controller, answers, if it answers a
    /// question (a set before a read, when it answers both); the question is then answered.
    pub fn answers(&mut self, now: Instant, msg: &MavMessage) -> Option<Asked> {
        let MavMessage::PARAM_VALUE(v) = msg else {
            return None;
        };
        self.expire(now);
        let name = Key::Name(*v.param_id);
        let index = Key::Index(v.param_index);
        let matches = |k: &Key| *k == name || *k == index;
        let at = self
            .pending
            .iter()
            .position(|(k, a, _)| *a == Asked::Set && matches(k))
            .or_else(|| self.pending.iter().position(|(k, _, _)| matches(k)))?;
        self.pending.remove(at).map(|(_, asked, _)| asked)
    }

    fn expire(&mut self, now: Instant) {
        self.pending.retain(|(_, _, until)| *until > now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{PARAM_REQUEST_READ_DATA, PARAM_SET_DATA, PARAM_VALUE_DATA};

    fn value(name: &str, index: u16) -> MavMessage {
        MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_id: name.into(),
            param_index: index,
            param_count: 1396,
            ..Default::default()
        })
    }

    fn ms(n: u64) -> Instant {
        Instant::ZERO + Duration::from_millis(n)
    }

    #[test]
    fn a_set_is_answered_by_its_echo_once_whatever_its_index() {
        let mut a = ParamAnswers::default();
        a.asked(
            ms(0),
            &MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_id: "RTL_ALT".into(),
                param_value: 2500.0,
                ..Default::default()
            }),
        );
        assert_eq!(a.answers(ms(10), &value("RTL_ALT_FINAL", 11)), None);
        assert_eq!(
            a.answers(ms(10), &value("RTL_ALT", 65535)),
            Some(Asked::Set)
        );
        assert_eq!(
            a.answers(ms(20), &value("RTL_ALT", 8)),
            None,
            "answered once"
        );
    }

    #[test]
    fn a_read_by_index_is_answered_by_that_index_and_questions_expire() {
        let mut a = ParamAnswers::default();
        a.asked(
            ms(0),
            &MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: 812,
                ..Default::default()
            }),
        );
        assert_eq!(a.answers(ms(1), &value("X", 811)), None);
        assert_eq!(a.answers(ms(1), &value("X", 812)), Some(Asked::Read));
        a.asked(
            ms(0),
            &MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: 5,
                ..Default::default()
            }),
        );
        assert_eq!(a.answers(ms(6_000), &value("Y", 5)), None, "expired");
    }
}
