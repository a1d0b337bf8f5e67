//! The on-line update never touches the heap: a counting global allocator sees no allocation
//! across 10 000 updates with forgetting and with a sliding window (including downdates).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]
// A global allocator can only be written with `unsafe impl GlobalAlloc`; it forwards to `System`.
#![allow(unsafe_code)]

use physid_ident::workload::rows;
use physid_ident::{Memory, OnlineIdent};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;
thread_local! {
    /// Allocations made by *this* thread (the harness's threads allocate concurrently).
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
}

fn bump() {
    let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
}

fn allocs() -> usize {
    ALLOCS.with(Cell::get)
}

// SAFETY: forwards every call unchanged to `System`, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        bump();
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        bump();
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn online_updates_do_not_allocate() {
    let p = 8;
    let data = rows(10_000, p);
    for memory in [Memory::Forgetting(0.99), Memory::Window(300)] {
        let mut on = OnlineIdent::new(p, memory).unwrap();
        let before = allocs();
        for r in data.chunks_exact(p) {
            on.update(r).unwrap();
        }
        assert_eq!(allocs() - before, 0, "{memory:?}");
        // The counter is live: the ranking allocates.
        let before = allocs();
        let _ = on.ranking();
        assert!(allocs() > before);
    }
}
