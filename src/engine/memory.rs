//! The memory a job's run holds, watched while it runs. The server's global allocator is the
//! system's, counting: on a worker thread whose run's numerics are computing, every byte
//! allocated is added to the run's count and every byte freed taken off, so the count is what
//! the run holds at that instant. The engine's observer compares it with the server's
//! `max_memory_mb` at every step and ends a run past it `failed`, naming the limit. (A
//! `lagrangian` model is also estimated from its sizes before it is compiled: `check_memory`.)
//!
//! What is counted is the run's own thread while the numerics compute: counting pauses inside
//! the observer's calls ([`Paused`]), whose buffers are bounded on their own (one stored
//! chunk, the event queue) and whose step batches are freed on the publisher's thread. Helper
//! threads a modal scan spawns are not counted, nor is the model compiled before the run
//! (estimated instead).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    /// Whether this thread's allocations count: a run's numerics are computing on it.
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    /// Bytes allocated minus bytes freed on this thread while counting.
    static HELD: Cell<i64> = const { Cell::new(0) };
}

/// Adds `delta` bytes to this thread's count when it is counting.
fn count(delta: i64) {
    // `try_with`: never fails for these constant, drop-free cells, but an allocator must not
    // panic.
    let on = COUNTING.try_with(Cell::get).unwrap_or(false);
    if on {
        let _ = HELD.try_with(|held| held.set(held.get().saturating_add(delta)));
    }
}

/// The system's allocator, counting what a run holds on its thread.
pub struct CountingAllocator;

// SAFETY: every call is forwarded unchanged to `System`, which upholds `GlobalAlloc`'s
// contract; the counting only reads the layout and never allocates.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's layout, as `GlobalAlloc::alloc` requires.
        let ptr = unsafe { System.alloc(layout) };
        if !ptr.is_null() {
            count(layout.size() as i64);
        }
        ptr
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as in `alloc`.
        let ptr = unsafe { System.alloc_zeroed(layout) };
        if !ptr.is_null() {
            count(layout.size() as i64);
        }
        ptr
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` (through this allocator) with `layout`.
        unsafe { System.dealloc(ptr, layout) };
        count(-(layout.size() as i64));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as in `dealloc`; `new_size` as the caller was required to give it.
        let moved = unsafe { System.realloc(ptr, layout, new_size) };
        if !moved.is_null() {
            count(new_size as i64 - layout.size() as i64);
        }
        moved
    }
}

/// A run's count on the current thread: from zero, while this lives.
pub(super) struct RunMemory(());

impl RunMemory {
    /// Starts counting this thread's allocations from zero.
    pub(super) fn start() -> RunMemory {
        HELD.with(|held| held.set(0));
        COUNTING.with(|on| on.set(true));
        RunMemory(())
    }

    /// The bytes the run holds now.
    pub(super) fn held() -> u64 {
        HELD.with(Cell::get).max(0) as u64
    }
}

impl Drop for RunMemory {
    fn drop(&mut self) {
        COUNTING.with(|on| on.set(false));
    }
}

/// Counting paused on the current thread while this lives (the observer's calls), resumed as
/// it was.
pub(super) struct Paused(bool);

impl Paused {
    pub(super) fn new() -> Paused {
        Paused(COUNTING.with(|on| on.replace(false)))
    }
}

impl Drop for Paused {
    fn drop(&mut self) {
        COUNTING.with(|on| on.set(self.0));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run holding a 40 MiB vector is counted 40 MiB (to the few bytes of the test's own
    /// bookkeeping), nothing once it is freed; what is allocated while paused is not counted, a
    /// vector grown by reallocation is, and nothing is counted once the run's count is dropped.
    #[test]
    fn a_run_is_counted_what_it_holds_and_nothing_while_paused() {
        const BYTES: usize = 40 << 20;
        let run = RunMemory::start();
        let big = vec![1u8; BYTES];
        let held = RunMemory::held();
        assert!(
            (BYTES as u64..BYTES as u64 + 4096).contains(&held),
            "{held}"
        );
        let paused = Paused::new();
        let aside = vec![2u8; BYTES];
        drop(paused);
        assert_eq!(RunMemory::held(), held);
        drop(big);
        assert!(RunMemory::held() < 4096, "{}", RunMemory::held());
        let mut grown = Vec::<u64>::with_capacity(1);
        grown.resize(BYTES / 8, 3);
        assert!(RunMemory::held() >= BYTES as u64, "{}", RunMemory::held());
        drop(run);
        let after = RunMemory::held();
        drop(grown);
        drop(aside);
        assert_eq!(RunMemory::held(), after);
    }
}
