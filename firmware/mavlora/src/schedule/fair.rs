//! Fairness between the origins of one class of traffic: each origin's frames leave in the
//! order they came, and origins take turns by bytes (start-time fair queueing), so an origin
//! that floods a class delays only its own frames: a second ground station's hundred
//! parameter reads a second wait behind each other, not in front of the pilot's.

use std::collections::VecDeque;
use std::hash::{DefaultHasher, Hash, Hasher};

use crate::wire::OwnedFrame;

/// Who queued a frame: a sender's (system, component) by default; the router adds the ground
/// station's address, since MAVProxy, QGroundControl and Mission Planner all call themselves
/// system 255.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Origin(u64);

impl Origin {
    /// The frame's sender.
    pub fn of(frame: &OwnedFrame) -> Self {
        Self::tagged(frame, ())
    }

    /// The frame's sender, told apart by `tag` (an address) from senders with the same ids.
    pub fn tagged(frame: &OwnedFrame, tag: impl Hash) -> Self {
        // SipHash with fixed keys: the same origin on every run, so runs replay.
        let mut h = DefaultHasher::new();
        (frame.system_id(), frame.component_id()).hash(&mut h);
        tag.hash(&mut h);
        Self(h.finish())
    }
}

#[derive(Debug)]
struct Flow {
    origin: Origin,
    frames: VecDeque<OwnedFrame>,
    bytes: usize,
    /// Start tag of the flow's next frame, in [`FairQueue::virtual_time`]'s units.
    start: u64,
}

/// Frames of one class from any number of origins, served origin-fair.
///
/// An origin joining (or coming back to) the queue starts at the virtual time of the frame
/// served last, so it waits at most one frame of each other origin; an origin that keeps the
/// queue busy advances by its own bytes only. Empty origins are forgotten: memory is bounded
/// by the frames queued, whatever the number of origins seen.
#[derive(Debug, Default)]
pub(super) struct FairQueue {
    /// Few origins at a time (a vehicle's components, a handful of ground stations): a
    /// linear scan beats an index.
    flows: Vec<Flow>,
    virtual_time: u64,
    bytes: usize,
}

impl FairQueue {
    pub fn push(&mut self, origin: Origin, frame: OwnedFrame) {
        let len = frame.as_bytes().len();
        self.bytes += len;
        match self.flows.iter_mut().find(|f| f.origin == origin) {
            Some(flow) => {
                flow.bytes += len;
                flow.frames.push_back(frame);
            }
            None => self.flows.push(Flow {
                origin,
                frames: VecDeque::from([frame]),
                bytes: len,
                start: self.virtual_time,
            }),
        }
    }

    /// The flow whose frame leaves next: the lowest start tag, the longest waiting on a tie.
    fn next(&self) -> Option<usize> {
        (0..self.flows.len()).min_by_key(|&i| self.flows[i].start)
    }

    /// The frame [`pop`](Self::pop) returns next.
    pub fn front(&self) -> Option<&OwnedFrame> {
        self.next().and_then(|i| self.flows[i].frames.front())
    }

    /// Takes the next frame, charging its origin `cost` bytes (its length on the air).
    pub fn pop(&mut self, cost: usize) -> Option<OwnedFrame> {
        let i = self.next()?;
        let flow = &mut self.flows[i];
        let frame = flow.frames.pop_front()?;
        let len = frame.as_bytes().len();
        flow.bytes -= len;
        self.bytes -= len;
        self.virtual_time = flow.start;
        flow.start += cost as u64;
        if flow.frames.is_empty() {
            // `remove`, not `swap_remove`: ties go to the flow that joined first
            self.flows.remove(i);
        }
        Some(frame)
    }

    /// Drops one frame of the origin with the most bytes waiting (the one flooding): the one
    /// `choose` picks among its frames, in arrival order.
    pub fn drop_from_largest(
        &mut self,
        choose: impl Fn(&VecDeque<OwnedFrame>) -> usize,
    ) -> Option<OwnedFrame> {
        let i = (0..self.flows.len()).max_by_key(|&i| self.flows[i].bytes)?;
        let flow = &mut self.flows[i];
        let frame = flow.frames.remove(choose(&flow.frames))?;
        let len = frame.as_bytes().len();
        flow.bytes -= len;
        self.bytes -= len;
        if flow.frames.is_empty() {
            self.flows.remove(i);
        }
        Some(frame)
    }

    /// The newest waiting frame that matches: the one [`replace_newest`](Self::replace_newest)
    /// replaces.
    pub fn newest(&self, matches: impl Fn(&OwnedFrame) -> bool) -> Option<&OwnedFrame> {
        self.flows
            .iter()
            .rev()
            .find_map(|flow| flow.frames.iter().rev().find(|f| matches(f)))
    }

    /// Puts `frame` in the place of the newest waiting frame that matches (its origin's turn
    /// and order kept); gives `frame` back if none does.
    pub fn replace_newest(
        &mut self,
        matches: impl Fn(&OwnedFrame) -> bool,
        frame: OwnedFrame,
    ) -> Result<(), OwnedFrame> {
        let found = self.flows.iter_mut().rev().find_map(|flow| {
            let i = flow.frames.iter().rposition(&matches)?;
            Some((flow, i))
        });
        let Some((flow, i)) = found else {
            return Err(frame);
        };
        let (old, new) = (flow.frames[i].as_bytes().len(), frame.as_bytes().len());
        flow.bytes = flow.bytes - old + new;
        self.bytes = self.bytes - old + new;
        flow.frames[i] = frame;
        Ok(())
    }

    pub fn bytes(&self) -> usize {
        self.bytes
    }

    pub fn len(&self) -> usize {
        self.flows.iter().map(|f| f.frames.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.flows.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use mavlink::MavlinkVersion;

    use super::*;
    use crate::testutil::raw_frame;
    use crate::wire::ids::PARAM_REQUEST_READ;

    fn read(sys: u8, seq: u8) -> OwnedFrame {
        raw_frame(
            MavlinkVersion::V2,
            sys,
            190,
            seq,
            PARAM_REQUEST_READ,
            &[seq | 1; 20],
        )
    }

    #[test]
    fn a_flooding_origin_waits_behind_its_own_frames_only() {
        let mut q = FairQueue::default();
        let (flooder, pilot) = (read(200, 0), read(255, 0));
        let (flooder, pilot) = (Origin::of(&flooder), Origin::of(&pilot));
        for seq in 0..100 {
            q.push(flooder, read(200, seq));
        }
        q.push(pilot, read(255, 0));
        q.push(pilot, read(255, 1));
        let out: Vec<(u8, u8)> = std::iter::from_fn(|| q.pop(30))
            .take(4)
            .map(|f| (f.system_id(), f.sequence()))
            .collect();
        // turn about, each origin in its own order
        assert_eq!(out, [(200, 0), (255, 0), (200, 1), (255, 1)]);
        assert_eq!(q.len(), 98);
    }

    #[test]
    fn the_same_ids_from_two_addresses_are_two_origins() {
        let f = read(255, 0);
        assert_ne!(
            Origin::tagged(&f, "127.0.0.1:14550"),
            Origin::tagged(&f, "127.0.0.1:14551")
        );
        assert_eq!(Origin::of(&f), Origin::of(&read(255, 7)));
    }

    #[test]
    fn a_full_queue_drops_from_the_origin_with_most_waiting() {
        let mut q = FairQueue::default();
        let (a, b) = (Origin::of(&read(1, 0)), Origin::of(&read(2, 0)));
        q.push(b, read(2, 0));
        for seq in 0..3 {
            q.push(a, read(1, seq));
        }
        let dropped = q.drop_from_largest(|_| 0).unwrap();
        assert_eq!((dropped.system_id(), dropped.sequence()), (1, 0));
        assert_eq!(q.len(), 3);
        let left: usize = std::iter::from_fn(|| q.pop(30))
            .map(|f| f.as_bytes().len())
            .sum();
        assert_eq!((left, q.bytes(), q.is_empty()), (3 * 32, 0, true));
    }
}
