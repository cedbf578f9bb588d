// A global allocator that counts the allocations of the threads that asked to be
// watched. Shared by the kernel's and the runtime's no-allocation tests (included by
// path, so no crate depends on another for it).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// Counts allocations (and reallocations) of watching threads, and their frees apart.
pub struct Counting;

thread_local! {
    static WATCHING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
    static FREES: Cell<u64> = const { Cell::new(0) };
}

/// Starts or stops watching this thread.
pub fn watch(on: bool) {
    WATCHING.with(|w| w.set(on));
}

/// Allocations this thread made while watched; resets the count.
pub fn take_count() -> u64 {
    COUNT.with(|c| c.replace(0))
}

/// Frees this thread made while watched (memory it freed, whoever allocated it); resets
/// the count.
#[allow(dead_code)] // not every test binary asks
pub fn take_frees() -> u64 {
    FREES.with(|c| c.replace(0))
}

fn counted() {
    if WATCHING.with(Cell::get) {
        COUNT.with(|c| c.set(c.get() + 1));
    }
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        counted();
        // SAFETY: same contract as our caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if WATCHING.with(Cell::get) {
            FREES.with(|c| c.set(c.get() + 1));
        }
        // SAFETY: same contract as our caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        counted();
        // SAFETY: same contract as our caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
