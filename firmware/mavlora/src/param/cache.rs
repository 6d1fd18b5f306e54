//! The router's parameter cache: a ground station that asks for the list again (a reconnect,
//! a second station) gets it from the ground side in a moment instead of across the radio,
//! but only when the vehicle itself says its parameters are what the cache holds.
//!
//! The check is the vehicle's own: PX4 answers a `PARAM_REQUEST_READ` of `_HASH_CHECK` (by
//! name, index -1) with a `PARAM_VALUE` of that name (type `UINT32`, index 65535, its
//! `param_count`) whose four value bytes are a CRC-32 (the reflected 0xEDB88320 polynomial, no
//! initial or final inversion) over every parameter's name (without its zero bytes) and four
//! value bytes, in list order, leaving out the parameters PX4 marks volatile (calibration, flight
//! time, the flight's UUID...); it sends the same value first whenever it streams its list.
//! ArduPilot (4.6) answers no `_HASH_CHECK`: its components are never served from here (the
//! cache only serves a component it has heard a hash from), so its lists cross the radio as
//! before and no ArduPilot list waits for a check.
//!
//! The cache cannot compute PX4's hash itself (which parameters are volatile is PX4's
//! metadata, not on the wire), so it *binds* its content to a hash the vehicle reported:
//! - a list is filled from the `PARAM_VALUE`s the router delivers (packed or raw), every index
//!   `0..count` of one (system, component), after the hash the vehicle sent at the list's
//!   start; once complete the router asks the hash again (one small frame each way). The
//!   same hash at both ends (or a difference one seen change explains, below) binds the
//!   content to it; anything else (a change whose `PARAM_VALUE` was lost during the
//!   download) leaves it unbound, and the next list crosses the radio and fills afresh;
//! - every later `PARAM_VALUE` (a change the autopilot broadcasts, the echo of a
//!   `PARAM_SET`) updates the cache and is remembered as a change since the bound hash, and
//!   the router asks the hash again. The CRC is linear: a change of one value's four bytes by
//!   `delta` moves the hash by `crc(delta ‖ L zero bytes)` where `L` is what the hash covers
//!   after that value, at most the list's bytes after it. A new hash that one seen change
//!   explains (some `L` in range, or no move at all: a volatile parameter) binds again; a
//!   chance match is ~`L`/2³², 5·10⁻⁶ for a 20 kB list. Two changes or more are not
//!   explained (a chance match of two would be ~10 %): unbound;
//! - a ground station's `PARAM_REQUEST_LIST` to a bound component is held while the router
//!   asks the hash (one frame up, one down: what decides "unchanged" is the vehicle's answer
//!   now, never what the cache remembers). A hash the bound one (and the changes seen)
//!   explains: the whole list goes to the ground from here, byte for byte as it came (name,
//!   value bits, type, count, index) and as the component that sent it. Any other hash (a
//!   lost change, a vehicle rebooted with other parameters, another vehicle with the same
//!   system id, another count), or no answer within [`CHECK_TIMEOUT`]: the held request goes
//!   to the radio, the cache drops its content and fills again from that list.
//!
//! What the check cannot see: PX4's volatile parameters are outside its hash, so their
//! cached values are as fresh as the last `PARAM_VALUE` of them the router saw (as they are
//! in QGroundControl's own `_HASH_CHECK` cache).

use std::collections::VecDeque;

use super::ParamValue;
use crate::time::{Duration, Instant};

/// The name PX4 answers with its parameter set's hash.
pub const HASH_CHECK_NAME: [u8; 16] = *b"_HASH_CHECK\0\0\0\0\0";

/// How long a ground's list request waits at the router for the vehicle's hash before it goes
/// to the radio anyway (the check frame or its answer was lost): a LoRa SF7 round trip of two
/// small frames behind a queue is ~1 s; QGroundControl waits longer for a list's first value.
pub const CHECK_TIMEOUT: Duration = Duration::from_secs(3);

/// Lists (one per component of a vehicle) cached at once.
const MAX_ENTRIES: usize = 4;
/// The longest list cached (the bridge holds 4,096 values at most).
pub const MAX_COUNT: u16 = 4096;

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ParamCacheStats {
    /// Ground list requests answered from the cache.
    pub lists_served: u64,
    /// `PARAM_VALUE`s given from the cache.
    pub values_served: u64,
    /// Ground list requests that went to the radio after a check (a hash that did not
    /// match, or none in time).
    pub misses: u64,
    /// Checks sent to the radio (`PARAM_REQUEST_READ` of `_HASH_CHECK`).
    pub checks_sent: u64,
    /// Checks that got no answer within [`CHECK_TIMEOUT`].
    pub check_timeouts: u64,
    /// Times the content was bound to a hash of the vehicle's.
    pub binds: u64,
    /// Times the content was dropped: the vehicle's hash said it differs, or a change could
    /// not be followed.
    pub dropped: u64,
}

/// Something for the radio.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CacheRadio<T> {
    /// Ask (`system`, `component`) for its `_HASH_CHECK`.
    HashCheck {
        /// Target system.
        system: u8,
        /// Target component.
        component: u8,
    },
    /// A held list request that goes to the radio after all.
    Forward(T),
}

/// A change since the bound hash: the value's index and its bits' XOR with the bound ones.
#[derive(Debug, Clone, Copy)]
struct Change {
    index: u16,
    delta: [u8; 4],
}

#[derive(Debug)]
struct Check<T> {
    deadline: Instant,
    /// Ground list requests waiting for the answer.
    held: Vec<T>,
}

#[derive(Debug)]
struct Entry<T> {
    system: u8,
    component: u8,
    count: u16,
    values: Vec<Option<ParamValue>>,
    filled: usize,
    /// The hash the content is bound to (`bound`) or is being filled after (not `bound`).
    reference: Option<u32>,
    bound: bool,
    /// Value changes seen since `reference`.
    changes: Vec<Change>,
    /// More changes than one since `reference`: it can no longer be checked.
    untraceable: bool,
    check: Option<Check<T>>,
    /// A check to send (none was in flight when it was wanted).
    check_wanted: bool,
}

impl<T> Entry<T> {
    fn new(system: u8, component: u8, count: u16) -> Self {
        Self {
            system,
            component,
            count,
            values: vec![None; usize::from(count)],
            filled: 0,
            reference: None,
            bound: false,
            changes: Vec::new(),
            untraceable: false,
            check: None,
            check_wanted: false,
        }
    }

    fn complete(&self) -> bool {
        self.filled == usize::from(self.count)
    }

    /// Forgets the content (keeps the check in flight and the requests it holds).
    fn clear(&mut self, count: u16) {
        self.count = count;
        self.values = vec![None; usize::from(count)];
        self.filled = 0;
        self.reference = None;
        self.bound = false;
        self.changes.clear();
        self.untraceable = false;
    }

    /// Bytes PX4's hash covers after `index`, at most: every later name and value.
    fn bytes_after(&self, index: u16) -> usize {
        self.values[usize::from(index) + 1..]
            .iter()
            .flatten()
            .map(|v| v.name_len() + 4)
            .sum()
    }

    /// Whether the vehicle's `hash` now is what `reference` and the changes seen since make it.
    fn explains(&self, hash: u32) -> bool {
        let Some(reference) = self.reference else {
            return false;
        };
        if self.untraceable {
            return false;
        }
        match self.changes.as_slice() {
            [] => hash == reference,
            // no move: a volatile parameter (outside the hash)
            [c] => {
                hash == reference || shifts_by(c.delta, self.bytes_after(c.index), hash ^ reference)
            }
            _ => false,
        }
    }

    /// A value's change from `old` to `new` bits at `index`.
    fn changed(&mut self, index: u16, old: [u8; 4], new: [u8; 4]) {
        let delta = xor(old, new);
        match self.changes.iter().position(|c| c.index == index) {
            Some(at) => {
                let d = xor(self.changes[at].delta, delta);
                if d == [0; 4] {
                    self.changes.remove(at);
                } else {
                    self.changes[at].delta = d;
                }
            }
            None if delta != [0; 4] => self.changes.push(Change { index, delta }),
            None => {}
        }
        if self.changes.len() > 1 {
            self.untraceable = true;
        }
    }
}

fn xor(a: [u8; 4], b: [u8; 4]) -> [u8; 4] {
    [a[0] ^ b[0], a[1] ^ b[1], a[2] ^ b[2], a[3] ^ b[3]]
}

const fn crc_table() -> [u32; 256] {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
}

static CRC_TABLE: [u32; 256] = crc_table();

/// PX4's `crc32part`: CRC-32 (reflected 0xEDB88320) of `bytes` from `crc`, with no inversion.
pub fn crc32_part(bytes: &[u8], mut crc: u32) -> u32 {
    for &b in bytes {
        crc = CRC_TABLE[((crc ^ u32::from(b)) & 0xFF) as usize] ^ (crc >> 8);
    }
    crc
}

/// Whether `crc(delta ‖ L zero bytes)` is `shift` for some `L` in `0..=max_after`: what a
/// change of one value by `delta` does to the hash when the hash covers `L` bytes after it.
fn shifts_by(delta: [u8; 4], max_after: usize, shift: u32) -> bool {
    let mut crc = crc32_part(&delta, 0);
    for _ in 0..=max_after {
        if crc == shift {
            return true;
        }
        crc = crc32_part(&[0], crc);
    }
    false
}

/// Sans-IO: tell it every `PARAM_VALUE` the router delivers and every list request of the
/// ground; it says what to send to the radio and which lists to give the ground.
#[derive(Debug)]
pub struct ParamCache<T> {
    entries: VecDeque<Entry<T>>,
    radio: VecDeque<CacheRadio<T>>,
    served: VecDeque<(u8, u8, Vec<ParamValue>)>,
    stats: ParamCacheStats,
}

impl<T> Default for ParamCache<T> {
    fn default() -> Self {
        Self {
            entries: VecDeque::new(),
            radio: VecDeque::new(),
            served: VecDeque::new(),
            stats: ParamCacheStats::default(),
        }
    }
}

impl<T> ParamCache<T> {
    /// Counters so far.
    pub fn stats(&self) -> ParamCacheStats {
        self.stats
    }

    /// Whether (`system`, `component`)'s list is cached and bound to a hash of the vehicle's.
    pub fn bound(&self, system: u8, component: u8) -> bool {
        self.entries
            .iter()
            .any(|e| (e.system, e.component) == (system, component) && e.bound && e.complete())
    }

    /// The entry of (`system`, `component`), made if new and started again if its list's
    /// `count` changed; `None` for a count no list has.
    fn entry(&mut self, system: u8, component: u8, count: u16) -> Option<usize> {
        if count == 0 || count > MAX_COUNT {
            return None;
        }
        let at = match self
            .entries
            .iter()
            .position(|e| (e.system, e.component) == (system, component))
        {
            Some(at) => at,
            None => {
                if self.entries.len() == MAX_ENTRIES {
                    // the oldest goes, with what it holds back
                    if let Some(old) = self.entries.pop_front()
                        && let Some(check) = old.check
                    {
                        self.radio
                            .extend(check.held.into_iter().map(CacheRadio::Forward));
                    }
                }
                self.entries.push_back(Entry::new(system, component, count));
                self.entries.len() - 1
            }
        };
        let e = &mut self.entries[at];
        if count != e.count {
            // another parameter set (a reboot, another vehicle): start again
            if e.filled > 0 {
                self.stats.dropped += 1;
            }
            e.clear(count);
        }
        Some(at)
    }

    /// A `PARAM_VALUE` from (`system`, `component`) the router gives the ground at `now`.
    pub fn value(&mut self, now: Instant, system: u8, component: u8, v: &ParamValue) {
        if v.name == HASH_CHECK_NAME {
            self.hash(now, system, component, v);
            return;
        }
        let Some(at) = self.entry(system, component, v.count) else {
            return;
        };
        let e = &mut self.entries[at];
        let index = if v.index < v.count {
            Some(v.index)
        } else {
            // told by name (ArduPilot's echo, index 65535)
            e.values
                .iter()
                .position(|x| x.is_some_and(|x| x.name == v.name))
                .map(|i| i as u16)
        };
        let Some(index) = index else {
            if e.complete() {
                // a parameter the cached list does not hold: not that list any more
                e.clear(e.count);
                self.stats.dropped += 1;
            }
            return;
        };
        let slot = usize::from(index);
        match e.values[slot] {
            None => {
                e.values[slot] = Some(ParamValue { index, ..*v });
                e.filled += 1;
                if e.complete() && e.reference.is_some() {
                    e.check_wanted = true;
                }
            }
            Some(old) if old.name != v.name => {
                // another list under the same count
                let dropped = e.bound;
                e.clear(e.count);
                e.values[slot] = Some(ParamValue { index, ..*v });
                e.filled = 1;
                self.stats.dropped += u64::from(dropped);
            }
            Some(old) => {
                e.values[slot] = Some(ParamValue { index, ..*v });
                if old.value != v.value {
                    e.changed(index, old.value, v.value);
                    if e.complete() && e.reference.is_some() && !e.untraceable {
                        // re-bind now, while one change explains the hash's move
                        e.check_wanted = true;
                    }
                }
            }
        }
        self.send_checks(now);
    }

    /// The vehicle's `_HASH_CHECK` value.
    fn hash(&mut self, now: Instant, system: u8, component: u8, v: &ParamValue) {
        let hash = u32::from_le_bytes(v.value);
        let Some(at) = self.entry(system, component, v.count) else {
            return;
        };
        let e = &mut self.entries[at];
        let mut forward = Vec::new();
        let mut serve = false;
        if e.complete() {
            if e.explains(hash) {
                if !e.bound {
                    self.stats.binds += 1;
                    tracing::info!(%now, system, component, count = e.count, hash = format_args!("{hash:#010x}"), "parameter cache bound to the vehicle's hash");
                }
                e.bound = true;
                e.reference = Some(hash);
                e.changes.clear();
                serve = true;
            } else {
                // the vehicle's set is not what the cache holds: fill afresh from the next
                // list, which starts from this hash
                self.stats.dropped += 1;
                tracing::info!(%now, system, component, hash = format_args!("{hash:#010x}"), reference = ?e.reference, changes = e.changes.len(), "parameter cache dropped: the vehicle's hash is not the cached set's");
                e.clear(e.count);
                e.reference = Some(hash);
            }
        } else if e.reference != Some(hash) {
            // A list starts (PX4 sends its hash first), or the set moved while one was filling:
            // values from here on are the set this hash stands for; those before it may be
            // older (PX4 broadcasts values it changes at boot, before any list) and go.
            if e.filled > 0 {
                e.clear(e.count);
            }
            e.reference = Some(hash);
            e.changes.clear();
            e.untraceable = false;
        }
        if let Some(check) = e.check.take() {
            if serve {
                let values: Vec<ParamValue> = e.values.iter().flatten().copied().collect();
                for _ in &check.held {
                    self.stats.lists_served += 1;
                    self.stats.values_served += values.len() as u64;
                }
                if !check.held.is_empty() {
                    self.served.push_back((e.system, e.component, values));
                }
            } else {
                self.stats.misses += check.held.len() as u64;
                forward = check.held;
            }
        }
        self.radio
            .extend(forward.into_iter().map(CacheRadio::Forward));
        self.send_checks(now);
    }

    fn send_checks(&mut self, now: Instant) {
        for e in &mut self.entries {
            if e.check_wanted && e.check.is_none() {
                e.check_wanted = false;
                e.check = Some(Check {
                    deadline: now + CHECK_TIMEOUT,
                    held: Vec::new(),
                });
                self.stats.checks_sent += 1;
                self.radio.push_back(CacheRadio::HashCheck {
                    system: e.system,
                    component: e.component,
                });
            }
        }
    }

    /// A ground station's `PARAM_REQUEST_LIST` to (`system`, `component`) at `now`; `request`
    /// is what to send to the radio should the cache not answer it. `Some(request)`: not for
    /// the cache, to the radio now; `None`: held until the vehicle's hash decides
    /// ([`poll_radio`](Self::poll_radio) then gives it back, or
    /// [`poll_served`](Self::poll_served) the list).
    pub fn request_list(
        &mut self,
        now: Instant,
        system: u8,
        component: u8,
        request: T,
    ) -> Option<T> {
        let Some(e) = self.entries.iter_mut().find(|e| {
            e.system == system
                && (e.component == component || component == 0)
                && e.bound
                && e.complete()
        }) else {
            return Some(request);
        };
        match &mut e.check {
            Some(check) => {
                // a check in flight decides for this request too; a repeat of a request
                // already held is not held twice
                if check.held.is_empty() {
                    check.held.push(request);
                }
            }
            None => {
                e.check = Some(Check {
                    deadline: now + CHECK_TIMEOUT,
                    held: vec![request],
                });
                self.stats.checks_sent += 1;
                self.radio.push_back(CacheRadio::HashCheck {
                    system: e.system,
                    component: e.component,
                });
            }
        }
        None
    }

    /// Checks unanswered at `now`: their held requests go to the radio.
    pub fn handle_timeout(&mut self, now: Instant) {
        for e in &mut self.entries {
            if e.check.as_ref().is_some_and(|c| now >= c.deadline) {
                let check = e.check.take().expect("checked");
                self.stats.check_timeouts += 1;
                self.stats.misses += check.held.len() as u64;
                self.radio
                    .extend(check.held.into_iter().map(CacheRadio::Forward));
            }
        }
        self.send_checks(now);
    }

    /// When a check times out.
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.entries
            .iter()
            .filter_map(|e| e.check.as_ref().map(|c| c.deadline))
            .min()
    }

    /// The next thing for the radio.
    pub fn poll_radio(&mut self) -> Option<CacheRadio<T>> {
        self.radio.pop_front()
    }

    /// The next list to give the ground from the cache: (system, component, values in index
    /// order).
    pub fn poll_served(&mut self) -> Option<(u8, u8, Vec<ParamValue>)> {
        self.served.pop_front()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    fn param(i: u16, count: u16, v: f32) -> ParamValue {
        let mut name = [0u8; 16];
        let text = format!("P_{i}");
        name[..text.len()].copy_from_slice(text.as_bytes());
        ParamValue {
            value: v.to_le_bytes(),
            count,
            index: i,
            name,
            param_type: 9,
        }
    }

    /// PX4's hash over `values`, leaving out the indices in `volatile`.
    fn px4_hash(values: &[ParamValue], volatile: &[u16]) -> u32 {
        values
            .iter()
            .filter(|v| !volatile.contains(&v.index))
            .fold(0, |h, v| {
                let h = crc32_part(&v.name[..v.name_len()], h);
                crc32_part(&v.value, h)
            })
    }

    fn hash_value(h: u32, count: u16) -> ParamValue {
        ParamValue {
            value: h.to_le_bytes(),
            count,
            index: u16::MAX,
            name: HASH_CHECK_NAME,
            param_type: 5,
        }
    }

    /// A cache bound to `list`: its list's hash first, the values, the end check answered.
    fn bound_cache(list: &[ParamValue], volatile: &[u16]) -> ParamCache<u32> {
        let mut c = ParamCache::default();
        let n = list.len() as u16;
        let h = px4_hash(list, volatile);
        c.value(ms(0), 1, 1, &hash_value(h, n));
        for v in list {
            c.value(ms(10), 1, 1, v);
        }
        assert_eq!(
            c.poll_radio(),
            Some(CacheRadio::HashCheck {
                system: 1,
                component: 1
            })
        );
        c.value(ms(100), 1, 1, &hash_value(h, n));
        assert!(c.bound(1, 1));
        c
    }

    #[test]
    fn crc_is_px4s_crc32part() {
        // PX4's CRC-32 is zlib's without the inversions: zlib's "123456789" check value
        // 0xCBF43926 is !crc32_part(.., !0).
        assert_eq!(!crc32_part(b"123456789", !0), 0xCBF4_3926);
    }

    #[test]
    fn one_change_explains_the_hash_move_wherever_the_volatile_ones_are() {
        let list: Vec<_> = (0..50).map(|i| param(i, 50, i as f32)).collect();
        let volatile = [3, 40, 41];
        let mut c = bound_cache(&list, &volatile);
        // a broadcast change of 20: the router asks at once
        let mut now_list = list.clone();
        now_list[20] = param(20, 50, 99.5);
        c.value(ms(200), 1, 1, &now_list[20]);
        assert!(matches!(c.poll_radio(), Some(CacheRadio::HashCheck { .. })));
        c.value(
            ms(300),
            1,
            1,
            &hash_value(px4_hash(&now_list, &volatile), 50),
        );
        assert!(c.bound(1, 1), "one change, the hash moved by its delta");
        // a volatile one changes: the hash does not move
        now_list[40] = param(40, 50, 7.0);
        c.value(ms(400), 1, 1, &now_list[40]);
        c.poll_radio();
        c.value(
            ms(500),
            1,
            1,
            &hash_value(px4_hash(&now_list, &volatile), 50),
        );
        assert!(c.bound(1, 1));
        // and a list request is served
        assert_eq!(c.request_list(ms(600), 1, 1, 7), None);
        c.poll_radio();
        c.value(
            ms(700),
            1,
            1,
            &hash_value(px4_hash(&now_list, &volatile), 50),
        );
        let (_, _, served) = c.poll_served().expect("served");
        assert_eq!(served, now_list);
    }

    #[test]
    fn a_change_seen_with_one_lost_is_not_explained() {
        let list: Vec<_> = (0..50).map(|i| param(i, 50, i as f32)).collect();
        let mut c = bound_cache(&list, &[]);
        let mut now_list = list.clone();
        now_list[20] = param(20, 50, 99.5);
        now_list[30] = param(30, 50, -1.0); // its broadcast lost
        c.value(ms(200), 1, 1, &now_list[20]);
        c.poll_radio();
        c.value(ms(300), 1, 1, &hash_value(px4_hash(&now_list, &[]), 50));
        assert!(!c.bound(1, 1));
        assert_eq!(c.request_list(ms(400), 1, 1, 7), Some(7));
    }

    /// PX4 broadcasts values it changes at boot, before any list: a list's hash that comes
    /// after them starts the fill afresh, so the list binds (before, those values, with no
    /// hash before them, left the fill without a reference and the cache never served).
    #[test]
    fn values_before_a_lists_hash_do_not_keep_the_list_from_binding() {
        let list: Vec<_> = (0..20).map(|i| param(i, 20, i as f32)).collect();
        let mut c = ParamCache::<u32>::default();
        c.value(ms(0), 1, 1, &param(4, 20, -3.0)); // at boot, older than the list
        let h = px4_hash(&list, &[]);
        c.value(ms(100), 1, 1, &hash_value(h, 20));
        for v in &list {
            c.value(ms(200), 1, 1, v);
        }
        assert!(matches!(c.poll_radio(), Some(CacheRadio::HashCheck { .. })));
        c.value(ms(300), 1, 1, &hash_value(h, 20));
        assert!(c.bound(1, 1));
    }

    #[test]
    fn a_held_request_goes_to_the_radio_on_a_mismatch_or_without_an_answer() {
        let list: Vec<_> = (0..10).map(|i| param(i, 10, i as f32)).collect();
        let mut c = bound_cache(&list, &[]);
        assert_eq!(c.request_list(ms(1000), 1, 0, 7), None);
        assert_eq!(c.request_list(ms(1500), 1, 0, 8), None);
        c.poll_radio();
        c.value(ms(1600), 1, 1, &hash_value(12345, 10));
        assert_eq!(c.poll_radio(), Some(CacheRadio::Forward(7)));
        assert_eq!(c.poll_radio(), None, "a repeat is not sent twice");
        assert!(c.poll_served().is_none());
        // no answer
        let mut c = bound_cache(&list, &[]);
        c.request_list(ms(1000), 1, 1, 7);
        c.poll_radio();
        assert_eq!(c.poll_timeout(), Some(ms(1000) + CHECK_TIMEOUT));
        c.handle_timeout(ms(1000) + CHECK_TIMEOUT);
        assert_eq!(c.poll_radio(), Some(CacheRadio::Forward(7)));
        assert_eq!(c.stats().check_timeouts, 1);
    }
}
