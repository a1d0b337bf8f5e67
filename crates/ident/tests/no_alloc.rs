//! The on-line update never touches the heap: a counting global allocator sees no allocation
//! across 10 000 updates with forgetting and with a sliding window (including downdates).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_ident::workload::rows;
use physid_ident::{Memory, OnlineIdent};
use physid_testkit::{allocations as allocs, Counting};

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
