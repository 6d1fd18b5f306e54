//! The process's heap, counted: a global allocator that wraps the system's and keeps the
//! bytes live now and their high-water mark, so a soak can show its memory stays flat.
//!
//! Written here rather than taken from a crate: it is two atomic counters around
//! `System`, and the soak needs a high-water mark it can restart at a moment of its
//! choosing ([`HeapMeter::mark`]), which the small allocator-statistics crates do not give.
//! The `rig` binary installs it (`#[global_allocator]`); elsewhere [`installed`] says no.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static USED: AtomicBool = AtomicBool::new(false);

/// The counting allocator: `#[global_allocator] static A: HeapMeter = HeapMeter;`.
pub struct HeapMeter;

impl HeapMeter {
    fn add(bytes: usize) {
        let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
        PEAK.fetch_max(live, Ordering::Relaxed);
    }

    fn sub(bytes: usize) {
        LIVE.fetch_sub(bytes, Ordering::Relaxed);
    }

    /// Restarts the high-water mark at what is live now; returns that.
    pub fn mark() -> usize {
        let live = LIVE.load(Ordering::Relaxed);
        PEAK.store(live, Ordering::Relaxed);
        live
    }

    /// Heap bytes live now.
    pub fn live() -> usize {
        LIVE.load(Ordering::Relaxed)
    }

    /// The most heap bytes live at once since the last [`HeapMeter::mark`].
    pub fn peak() -> usize {
        PEAK.load(Ordering::Relaxed)
    }
}

/// Whether this process allocates through [`HeapMeter`] (else its counters stay at 0).
pub fn installed() -> bool {
    USED.load(Ordering::Relaxed)
}

// SAFETY: every call goes to `System` unchanged; the counters only observe sizes.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for HeapMeter {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        USED.store(true, Ordering::Relaxed);
        // SAFETY: the caller's contract for `alloc`, passed on.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            Self::add(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract for `dealloc`, passed on.
        unsafe { System.dealloc(ptr, layout) };
        Self::sub(layout.size());
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        USED.store(true, Ordering::Relaxed);
        // SAFETY: the caller's contract for `alloc_zeroed`, passed on.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            Self::add(layout.size());
        }
        p
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract for `realloc`, passed on.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            Self::sub(layout.size());
            Self::add(new_size);
        }
        p
    }
}
