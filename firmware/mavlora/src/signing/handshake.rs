//! The freshness handshake between the two ends of the radio link: an end whose state knows
//! nothing of its peer (a first start, or a lost state file) cannot tell a frame recorded a
//! minute ago from a live one by its clock, which may itself be behind. So it takes nothing
//! from the peer ([`Rejection::Unproven`](super::Rejection::Unproven)) until the peer has
//! answered a challenge only a live peer can answer:
//!
//! - the challenge is a signed `TIMESYNC` request (`tc1` = 0) whose `ts1` is a random nonce,
//!   sent every [`CHALLENGE_EVERY`] (with the commands' priority) until answered;
//! - the answer is a signed `TIMESYNC` with `tc1` = the responder's time, `ts1` the nonce
//!   echoed and the challenger's ids as target, as the common dialect prescribes;
//! - the answer's signing timestamp becomes the floor of the peer's link id: its frames must
//!   be stamped above, and everything it signed before the answer (every recording) is not.
//!
//! The nonce is negative (its top bit set): no clock gives `TIMESYNC` a negative time, so an
//! autopilot's or ground station's own `TIMESYNC` is never taken for one of these, and these
//! are consumed by the end that receives them, never passed on. An answer echoing any other
//! nonce (an earlier run's, recorded) proves nothing. Answering is always allowed: a replayed
//! challenge only gets an answer echoing an old nonce.

use crate::dialect::{MavMessage, TIMESYNC_DATA};
use crate::time::{Duration, Instant};
use crate::wire::{OwnedFrame, ids};

/// How often an unanswered challenge goes again.
pub const CHALLENGE_EVERY: Duration = Duration::from_secs(1);
/// The least time between two answers: a flood of replayed challenges gets a few answers a
/// second, not one each (the peer repeats its own once a second).
pub const ANSWER_GAP: Duration = Duration::from_millis(250);

/// A handshake frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HandshakeFrame {
    /// A challenge carrying its nonce.
    Challenge {
        /// The challenger's nonce.
        nonce: i64,
    },
    /// An answer echoing a nonce.
    Answer {
        /// The nonce echoed.
        nonce: i64,
    },
}

impl HandshakeFrame {
    /// `frame` as a handshake frame (signed or not); `None` for anything else, other
    /// `TIMESYNC`s included.
    pub fn parse(frame: &OwnedFrame) -> Option<Self> {
        if frame.message_id() != ids::TIMESYNC {
            return None;
        }
        let Ok(MavMessage::TIMESYNC(t)) = frame.decode::<MavMessage>() else {
            return None;
        };
        match (t.ts1 < 0, t.tc1) {
            (false, _) => None,
            (true, 0) => Some(Self::Challenge { nonce: t.ts1 }),
            (true, _) => Some(Self::Answer { nonce: t.ts1 }),
        }
    }
}

/// What a live peer sends back for `frame` if it is a challenge: the answer echoing its
/// nonce, addressed to the challenger, `time_ns` the responder's time (a peer simulated in
/// tests, or a tool speaking for one end).
pub fn answer_to(frame: &OwnedFrame, time_ns: i64) -> Option<MavMessage> {
    let Some(HandshakeFrame::Challenge { nonce }) = HandshakeFrame::parse(frame) else {
        return None;
    };
    Some(MavMessage::TIMESYNC(TIMESYNC_DATA {
        tc1: time_ns.max(1),
        ts1: nonce,
        target_system: frame.system_id(),
        target_component: frame.component_id(),
    }))
}

/// A nonce for this run: random (std's hash keys, drawn from the operating system), its top
/// bit set. Only a run's own challenges carry it, so a recorded answer never matches.
pub fn random_nonce() -> i64 {
    use std::hash::BuildHasher;
    let clock = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let h = std::collections::hash_map::RandomState::new().hash_one(clock);
    (h | 1 << 63) as i64
}

/// One end's side of the handshake: its challenges, and its answers to the peer's.
#[derive(Debug)]
pub struct Handshake {
    nonce: i64,
    /// When the next challenge goes; `None`: not challenging.
    next_challenge: Option<Instant>,
    /// The answer waiting to go: (challenger's system, component, its nonce).
    answer: Option<(u8, u8, i64)>,
    /// When the next answer may go.
    next_answer: Instant,
}

impl Handshake {
    /// A handshake with our `nonce` (negative: [`random_nonce`]), challenging at once if
    /// `challenging`.
    pub fn new(nonce: i64, challenging: bool) -> Self {
        Self {
            nonce: nonce | i64::MIN,
            next_challenge: challenging.then_some(Instant::ZERO),
            answer: None,
            next_answer: Instant::ZERO,
        }
    }

    /// Whether we are waiting for an answer.
    pub fn challenging(&self) -> bool {
        self.next_challenge.is_some()
    }

    /// Starts challenging at `now` (a peer we do not know spoke), unless already.
    pub fn start(&mut self, now: Instant) {
        self.next_challenge.get_or_insert(now);
    }

    /// A verified challenge from (`system`, `component`): answered when the gap allows (a
    /// newer challenge replaces one not yet answered).
    pub fn challenged(&mut self, system: u8, component: u8, nonce: i64) {
        self.answer = Some((system, component, nonce));
    }

    /// A verified answer: whether it answers our challenge (our nonce, while we wait for
    /// one); then challenging stops. Later copies (the peer answered a repeated challenge
    /// too) prove nothing more.
    pub fn answered(&mut self, nonce: i64) -> bool {
        let ours = nonce == self.nonce && self.challenging();
        if ours {
            self.next_challenge = None;
        }
        ours
    }

    /// The next handshake message to send at `now`, an answer first; `time_ns` is our time
    /// for an answer's `tc1` (never 0: that would make it a request).
    pub fn poll(&mut self, now: Instant, time_ns: i64) -> Option<MavMessage> {
        if now >= self.next_answer
            && let Some((target_system, target_component, nonce)) = self.answer.take()
        {
            self.next_answer = now + ANSWER_GAP;
            return Some(MavMessage::TIMESYNC(TIMESYNC_DATA {
                tc1: time_ns.max(1),
                ts1: nonce,
                target_system,
                target_component,
            }));
        }
        match self.next_challenge {
            Some(due) if now >= due => {
                self.next_challenge = Some(now + CHALLENGE_EVERY);
                // To whoever holds the key at the other end: we may not know its ids yet.
                Some(MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: 0,
                    ts1: self.nonce,
                    target_system: 0,
                    target_component: 0,
                }))
            }
            _ => None,
        }
    }

    /// When [`poll`](Self::poll) next has something.
    pub fn poll_timeout(&self) -> Option<Instant> {
        let answer = self.answer.map(|_| self.next_answer);
        [answer, self.next_challenge].into_iter().flatten().min()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Sender;
    use mavlink::MavlinkVersion;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    fn frame_of(msg: &MavMessage) -> OwnedFrame {
        Sender::new(1, 191, MavlinkVersion::V2).frame(msg)
    }

    #[test]
    fn challenges_repeat_until_the_answer_with_our_nonce() {
        let mut h = Handshake::new(-5, true);
        let first = h.poll(ms(0), 7).expect("at once");
        assert_eq!(
            HandshakeFrame::parse(&frame_of(&first)),
            Some(HandshakeFrame::Challenge { nonce: -5 })
        );
        assert_eq!(h.poll(ms(500), 7), None);
        assert_eq!(h.poll_timeout(), Some(ms(1000)));
        assert!(h.poll(ms(1000), 7).is_some(), "again a second later");
        assert!(!h.answered(-6), "another nonce proves nothing");
        assert!(h.challenging());
        assert!(h.answered(-5));
        assert!(!h.challenging());
        assert!(!h.answered(-5), "a second copy");
        assert_eq!(h.poll(ms(5000), 7), None);
        assert_eq!(h.poll_timeout(), None);
    }

    #[test]
    fn an_answer_echoes_the_nonce_to_the_challenger_and_answers_are_paced() {
        let mut h = Handshake::new(-5, false);
        assert_eq!(h.poll(ms(0), 7), None);
        h.challenged(255, 191, -9);
        let MavMessage::TIMESYNC(a) = h.poll(ms(0), 7).unwrap() else {
            panic!()
        };
        assert_eq!(
            (a.tc1, a.ts1, a.target_system, a.target_component),
            (7, -9, 255, 191)
        );
        assert_eq!(
            HandshakeFrame::parse(&frame_of(&MavMessage::TIMESYNC(a))),
            Some(HandshakeFrame::Answer { nonce: -9 })
        );
        h.challenged(255, 191, -10);
        assert_eq!(h.poll(ms(100), 7), None, "within the gap");
        assert_eq!(h.poll_timeout(), Some(ms(250)));
        assert!(
            h.poll(ms(250), 0)
                .is_some_and(|m| matches!(m, MavMessage::TIMESYNC(t) if t.tc1 == 1))
        );
    }

    #[test]
    fn an_autopilots_timesync_is_not_a_handshake_frame() {
        for (tc1, ts1) in [(0, 123_456_789), (42, 123_456_789), (0, 0)] {
            let t = MavMessage::TIMESYNC(TIMESYNC_DATA {
                tc1,
                ts1,
                ..Default::default()
            });
            assert_eq!(HandshakeFrame::parse(&frame_of(&t)), None);
        }
        assert!(random_nonce() < 0);
        assert_ne!(random_nonce(), random_nonce());
    }
}
