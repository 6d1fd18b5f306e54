//! A bounded queue between IO threads: bytes may enter faster than they leave (a UDP flood,
//! a radio that is not read), so every queue past the point where bytes enter holds at most a
//! fixed number of bytes. A full queue never blocks the producer: it drops the oldest
//! [`Lane::Bulk`] item first (periodic telemetry: a newer sample is coming), then the oldest
//! [`Lane::Priority`] item (commands, mission, acks: last to go), and counts what it dropped.
//! [`Lane::Keep`] items (port opened/closed, stop) are never dropped; they are rare.
//!
//! A producer that can be slowed down (a serial port: the kernel and the device hold what is
//! not read) waits with [`Queue::wait_room`] before pushing, so it never reads far ahead of
//! the consumer and never has its own bytes dropped; one that cannot (UDP) pushes and lets
//! the queue drop.
//!
//! In a [`Order::PriorityFirst`] queue priority items leave first (a ground command does not
//! wait behind megabytes of radio bytes when the main loop falls behind); bulk and keep items
//! leave in the order they entered, so a port's bytes and its open/idle/closed events stay in
//! order. In an [`Order::Arrival`] queue every item leaves in the order it entered (lanes
//! then only say what is dropped first): for a port whose frames were already ordered,
//! numbered and signed for the wire.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Which items go first when the queue is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lane {
    /// Dropped first: periodic telemetry, raw stream bytes.
    Bulk,
    /// Dropped only when no bulk item is left: commands, acks, mission traffic.
    Priority,
    /// Never dropped: control events.
    Keep,
}

/// Which item leaves next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// Priority items first, then the others in the order they entered.
    PriorityFirst,
    /// Every item in the order it entered: the radio port, whose frames the engine scheduled,
    /// numbered and signed in their order on the air; a frame overtaken there reads as a
    /// replay (rejected) and its stream as lost at the far end.
    Arrival,
}

/// What a queue has dropped so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QueueStats {
    /// Items dropped because the queue was full (or closed).
    pub dropped_items: u64,
    /// The bytes they carried.
    pub dropped_bytes: u64,
    /// Of those, priority items.
    pub dropped_priority: u64,
    /// Most bytes held at once, as counted against the capacity (what holding the items
    /// takes, for producers that use [`Queue::push_sized`]).
    pub peak_bytes: usize,
}

/// Why [`Queue::pop_until`] returned nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PopError {
    /// The deadline passed.
    Timeout,
    /// The queue was closed and is empty.
    Closed,
}

#[derive(Debug)]
struct Entry<T> {
    seq: u64,
    /// What it counts against the capacity.
    bytes: usize,
    /// What it counts in `dropped_bytes` if dropped.
    len: usize,
    item: T,
}

#[derive(Debug)]
struct State<T> {
    lanes: [VecDeque<Entry<T>>; 3],
    next_seq: u64,
    /// Bytes held, per lane (as counted against the capacity).
    lane_bytes: [usize; 3],
    closed: bool,
    /// A producer waits in [`Queue::wait_room`]: pops must wake it.
    room_wanted: bool,
    stats: QueueStats,
}

/// A bounded multi-producer, single-consumer queue; see the module doc.
#[derive(Debug)]
pub struct Queue<T> {
    capacity: usize,
    order: Order,
    state: Mutex<State<T>>,
    ready: Condvar,
    room: Condvar,
}

impl<T> Queue<T> {
    /// What holding one item costs the queue itself, beyond whatever the item owns: its slot,
    /// twice, because a lane's `VecDeque` doubles its capacity as it grows and keeps it. A
    /// producer that counts this per item bounds the queue's real memory by `capacity`.
    pub const SLOT_BYTES: usize = 2 * std::mem::size_of::<Entry<T>>();

    /// A queue holding at most `capacity` bytes (as the producers count them), priority items
    /// leaving first.
    pub fn new(capacity: usize) -> Self {
        Self::with_order(capacity, Order::PriorityFirst)
    }

    /// A queue holding at most `capacity` bytes whose items leave in `order`.
    pub fn with_order(capacity: usize, order: Order) -> Self {
        Self {
            capacity,
            order,
            state: Mutex::new(State {
                lanes: [VecDeque::new(), VecDeque::new(), VecDeque::new()],
                next_seq: 0,
                lane_bytes: [0; 3],
                closed: false,
                room_wanted: false,
                stats: QueueStats::default(),
            }),
            ready: Condvar::new(),
            room: Condvar::new(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, State<T>> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Queues `item` of `bytes` bytes; never blocks. Returns `false` if `item` itself was
    /// dropped (closed queue, or no room even after dropping every older droppable item).
    pub fn push(&self, item: T, bytes: usize, lane: Lane) -> bool {
        self.push_sized(item, bytes, bytes, lane)
    }

    /// Queues `item` as [`push`](Self::push) does, counting `cost` against the capacity (what
    /// holding it takes: its slot and allocation, see [`SLOT_BYTES`](Self::SLOT_BYTES)) and
    /// `len` in [`QueueStats::dropped_bytes`] if it is dropped (the bytes it carries).
    pub fn push_sized(&self, item: T, len: usize, cost: usize, lane: Lane) -> bool {
        let bytes = cost;
        let mut s = self.lock();
        if s.closed {
            s.drop_counted(len, lane);
            return false;
        }
        if lane != Lane::Keep {
            while s.bytes() + bytes > self.capacity {
                let victim = if !s.lanes[0].is_empty() {
                    Lane::Bulk
                } else if lane == Lane::Priority && !s.lanes[1].is_empty() {
                    Lane::Priority
                } else {
                    s.drop_counted(len, lane);
                    return false;
                };
                let old = s.lanes[victim as usize]
                    .pop_front()
                    .expect("non-empty lane");
                s.lane_bytes[victim as usize] -= old.bytes;
                s.drop_counted(old.len, victim);
            }
        }
        let seq = s.next_seq;
        s.next_seq += 1;
        s.lane_bytes[lane as usize] += bytes;
        s.stats.peak_bytes = s.stats.peak_bytes.max(s.bytes());
        s.lanes[lane as usize].push_back(Entry {
            seq,
            bytes,
            len,
            item,
        });
        drop(s);
        self.ready.notify_one();
        true
    }

    /// Waits until the queue holds at most `bytes` bytes, or is closed, or `deadline`
    /// passes; returns whether it does now.
    pub fn wait_room(&self, bytes: usize, deadline: Instant) -> bool {
        self.wait_until(deadline, |s| s.bytes() <= bytes)
    }

    /// As [`wait_room`](Self::wait_room), counting only what `lane` holds: a producer whose
    /// items go in a lane of their own is bounded by its own backlog, not held back by what
    /// others pushed (a UDP flood filling the bulk lane must not stop a serial port's reads).
    pub fn wait_room_in(&self, lane: Lane, bytes: usize, deadline: Instant) -> bool {
        self.wait_until(deadline, |s| s.lane_bytes[lane as usize] <= bytes)
    }

    /// Waits until `room` holds or the queue is closed, at most until `deadline`; returns
    /// whether it does now.
    fn wait_until(&self, deadline: Instant, room: impl Fn(&State<T>) -> bool) -> bool {
        let mut s = self.lock();
        while !room(&s) && !s.closed {
            let left = deadline.saturating_duration_since(Instant::now());
            if left == Duration::ZERO {
                return false;
            }
            s.room_wanted = true;
            s = self
                .room
                .wait_timeout(s, left)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        true
    }

    /// The oldest item, waiting until `deadline` (`None`: forever) for one.
    pub fn pop_until(&self, deadline: Option<Instant>) -> Result<T, PopError> {
        let mut s = self.lock();
        loop {
            if let Some(item) = s.pop(self.order) {
                // Only a waiting producer costs the pop a wake-up.
                if std::mem::take(&mut s.room_wanted) {
                    self.room.notify_all();
                }
                return Ok(item);
            }
            if s.closed {
                return Err(PopError::Closed);
            }
            s = match deadline {
                None => self.ready.wait(s).unwrap_or_else(|e| e.into_inner()),
                Some(d) => {
                    let left = d.saturating_duration_since(Instant::now());
                    if left == Duration::ZERO {
                        return Err(PopError::Timeout);
                    }
                    self.ready
                        .wait_timeout(s, left)
                        .unwrap_or_else(|e| e.into_inner())
                        .0
                }
            };
        }
    }

    /// Closes the queue: later pushes are dropped and counted; what is queued is counted as
    /// dropped too when `discard` is set, else it can still be popped.
    pub fn close(&self, discard: bool) {
        let mut s = self.lock();
        s.closed = true;
        if discard {
            for lane in [Lane::Bulk, Lane::Priority, Lane::Keep] {
                while let Some(old) = s.lanes[lane as usize].pop_front() {
                    s.lane_bytes[lane as usize] -= old.bytes;
                    s.drop_counted(old.len, lane);
                }
            }
        }
        drop(s);
        self.ready.notify_all();
        self.room.notify_all();
    }

    /// Drops everything queued now (counted), leaving the queue open.
    pub fn discard(&self) -> usize {
        let mut s = self.lock();
        let before = s.bytes();
        for lane in [Lane::Bulk, Lane::Priority, Lane::Keep] {
            while let Some(old) = s.lanes[lane as usize].pop_front() {
                s.lane_bytes[lane as usize] -= old.bytes;
                s.drop_counted(old.len, lane);
            }
        }
        before
    }

    /// Bytes queued now.
    pub fn bytes(&self) -> usize {
        self.lock().bytes()
    }

    /// Counters so far.
    pub fn stats(&self) -> QueueStats {
        self.lock().stats
    }
}

impl<T> State<T> {
    /// Bytes held, all lanes.
    fn bytes(&self) -> usize {
        self.lane_bytes.iter().sum()
    }

    fn pop(&mut self, order: Order) -> Option<T> {
        let lane = if order == Order::Arrival {
            (0..self.lanes.len())
                .filter_map(|i| self.lanes[i].front().map(|e| (e.seq, i)))
                .min()?
                .1
        } else if self.lanes[Lane::Priority as usize].is_empty() {
            [Lane::Bulk as usize, Lane::Keep as usize]
                .into_iter()
                .filter_map(|i| self.lanes[i].front().map(|e| (e.seq, i)))
                .min()?
                .1
        } else {
            Lane::Priority as usize
        };
        let e = self.lanes[lane].pop_front()?;
        self.lane_bytes[lane] -= e.bytes;
        Some(e.item)
    }

    fn drop_counted(&mut self, bytes: usize, lane: Lane) {
        self.stats.dropped_items += 1;
        self.stats.dropped_bytes += bytes as u64;
        if lane == Lane::Priority {
            self.stats.dropped_priority += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drain(q: &Queue<u32>) -> Vec<u32> {
        std::iter::from_fn(|| q.pop_until(Some(Instant::now())).ok()).collect()
    }

    /// Fills a 50-byte queue with bulk, priority and keep items, one bulk item too many.
    fn push_mixed(q: &Queue<u32>) {
        q.push(1, 10, Lane::Priority);
        q.push(2, 10, Lane::Bulk);
        q.push(3, 10, Lane::Bulk);
        q.push(6, 0, Lane::Keep);
        q.push(4, 10, Lane::Priority);
        q.push(7, 10, Lane::Bulk);
        assert!(q.push(5, 10, Lane::Bulk));
    }

    #[test]
    fn full_queue_drops_oldest_bulk_first_and_priority_leaves_first() {
        let q = Queue::new(50);
        push_mixed(&q);
        // Priority first; bulk and keep in the order they came.
        assert_eq!(drain(&q), [1, 4, 3, 6, 7, 5]);
        let s = q.stats();
        assert_eq!(
            (s.dropped_items, s.dropped_bytes, s.dropped_priority),
            (1, 10, 0)
        );
        assert_eq!(s.peak_bytes, 50);
    }

    #[test]
    fn an_arrival_queue_keeps_the_order_and_still_drops_bulk_first() {
        let q = Queue::with_order(50, Order::Arrival);
        push_mixed(&q);
        // The oldest bulk item (2) made room; the rest leave as they came.
        assert_eq!(drain(&q), [1, 3, 6, 4, 7, 5]);
        assert_eq!(q.stats().dropped_items, 1);
    }

    #[test]
    fn priority_goes_last_and_bulk_never_evicts_priority() {
        let q = Queue::new(20);
        q.push(1, 10, Lane::Priority);
        q.push(2, 10, Lane::Priority);
        // A bulk item finds only priority items: it is the one dropped.
        assert!(!q.push(3, 10, Lane::Bulk));
        // A priority item evicts the oldest priority item.
        assert!(q.push(4, 10, Lane::Priority));
        assert_eq!(drain(&q), [2, 4]);
        assert_eq!(q.stats().dropped_priority, 1);
    }

    #[test]
    fn keep_items_are_never_dropped_and_bytes_stay_bounded_under_a_flood() {
        let q = Queue::new(1000);
        q.push(0, 0, Lane::Keep);
        for i in 1..=100_000 {
            q.push(i, 100, Lane::Bulk);
            assert!(q.bytes() <= 1000);
        }
        let out = drain(&q);
        assert_eq!(out[0], 0);
        assert_eq!(out.len(), 11);
        assert_eq!(*out.last().unwrap(), 100_000);
        let s = q.stats();
        // Offered = delivered + dropped.
        assert_eq!(s.dropped_items + 10, 100_000);
    }

    #[test]
    fn a_paced_producer_waits_for_room_instead_of_losing_bytes() {
        let q = std::sync::Arc::new(Queue::new(1000));
        let producer = {
            let q = q.clone();
            std::thread::spawn(move || {
                for i in 0..1000 {
                    assert!(q.wait_room(300, Instant::now() + Duration::from_secs(10)));
                    assert!(q.push(i, 100, Lane::Bulk));
                }
            })
        };
        let mut got = Vec::new();
        while got.len() < 1000 {
            assert!(q.bytes() <= 400, "{} bytes queued", q.bytes());
            got.push(q.pop_until(None).unwrap());
        }
        producer.join().unwrap();
        assert_eq!(got, (0..1000).collect::<Vec<_>>());
        assert_eq!(q.stats().dropped_items, 0);
        assert!(q.stats().peak_bytes <= 400);
    }

    #[test]
    fn wait_room_gives_up_at_its_deadline() {
        let q = Queue::new(1000);
        q.push(1, 500, Lane::Bulk);
        assert!(!q.wait_room(100, Instant::now() + Duration::from_millis(20)));
        assert!(q.wait_room(500, Instant::now()));
    }

    #[test]
    fn a_sized_push_counts_its_cost_against_the_capacity_and_its_length_when_dropped() {
        let q = Queue::new(1000);
        for i in 0..10 {
            q.push_sized(i, 40, 200, Lane::Bulk);
            assert!(q.bytes() <= 1000);
        }
        // Five fit: what they take, not the 400 bytes ten of them carry.
        assert_eq!(drain(&q), [5, 6, 7, 8, 9]);
        let s = q.stats();
        assert_eq!(
            (s.dropped_items, s.dropped_bytes, s.peak_bytes),
            (5, 200, 1000)
        );
    }

    #[test]
    fn closed_queue_counts_what_it_discards() {
        let q = Queue::new(100);
        q.push(1, 30, Lane::Bulk);
        q.close(true);
        assert!(!q.push(2, 20, Lane::Bulk));
        assert_eq!(q.pop_until(None), Err(PopError::Closed));
        assert_eq!(q.stats().dropped_bytes, 50);
    }
}
