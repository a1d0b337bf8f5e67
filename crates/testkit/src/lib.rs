//! Test support shared by the crates' tests — a dev-dependency only.
//!
//! [`Counting`] is a global allocator that forwards to the system allocator and counts, per
//! thread, the allocations made: a test installs it with
//!
//! ```ignore
//! #[global_allocator]
//! static GLOBAL: physid_testkit::Counting = physid_testkit::Counting;
//! ```
//!
//! and checks that [`allocations`] does not move across the code under test (the estimators'
//! "no allocation per sample" promise).

// A global allocator can only be written with `unsafe impl GlobalAlloc`; it forwards to `System`.
#![allow(unsafe_code)]

pub mod fuzz;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// The counting allocator.
#[derive(Debug, Clone, Copy, Default)]
pub struct Counting;

thread_local! {
    /// Allocations made by *this* thread: the test harness's own threads (output capture,
    /// progress) allocate concurrently and must not count.
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
    /// The largest block this thread has asked for since [`reset_largest`] [bytes].
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

fn bump(size: usize) {
    // `try_with`: no panic while thread-locals are being torn down.
    let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
    let _ = LARGEST.try_with(|c| c.set(c.get().max(size)));
}

/// The largest block (allocation or reallocation) this thread has asked for since the last
/// [`reset_largest`] [bytes]: what a bound on the memory a call holds is checked against.
pub fn largest_allocation() -> usize {
    LARGEST.with(Cell::get)
}

/// Start [`largest_allocation`] again.
pub fn reset_largest() {
    LARGEST.with(|c| c.set(0));
}

/// Allocations (and reallocations) this thread has made so far.
pub fn allocations() -> usize {
    ALLOCS.with(Cell::get)
}

// SAFETY: forwards every call unchanged to `System`, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        bump(l.size());
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        bump(n);
        unsafe { System.realloc(p, l, n) }
    }
}

/// A scratch directory for one test, removed when it goes out of scope (so tests leave nothing
/// in the temporary folder): `let s = Scratch::new("physid-io"); let p = s.file("a.csv");`.
#[derive(Debug)]
pub struct Scratch(tempfile::TempDir);

impl Scratch {
    /// A new empty directory named `PREFIX-…` in the temporary folder.
    #[allow(clippy::expect_used)] // test support: no temporary folder is a broken machine
    pub fn new(prefix: &str) -> Self {
        Self(
            tempfile::Builder::new()
                .prefix(&format!("{prefix}-"))
                .tempdir()
                .expect("a scratch directory in the temporary folder"),
        )
    }

    /// The path of `name` inside it.
    pub fn file(&self, name: &str) -> std::path::PathBuf {
        self.0.path().join(name)
    }
}

impl std::ops::Deref for Scratch {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        self.0.path()
    }
}
