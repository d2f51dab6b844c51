//! What the property tests of the parser crates share (each crate's
//! `tests/properties.rs` includes this file as its `support` module): the
//! cases' configuration, and an allocator that counts what a read holds.

// Each test binary uses its own share of these.
#![allow(dead_code)]

use proptest::test_runner::{Config, RngSeed};

/// 64 cases from the fixed `seed`, the same every run so that a failure
/// repeats, unless `PROPTEST_CASES` or `PROPTEST_RNG_SEED` ask for others
/// (a longer search); no files of failures written into the source tree.
pub fn config(seed: u64) -> Config {
    let default = Config::default();
    let set = |name: &str| std::env::var_os(name).is_some();
    Config {
        cases: if set("PROPTEST_CASES") {
            default.cases
        } else {
            64
        },
        rng_seed: if set("PROPTEST_RNG_SEED") {
            default.rng_seed
        } else {
            RngSeed::Fixed(seed)
        },
        failure_persistence: None,
        ..default
    }
}

/// Counts the bytes each thread holds, to bound what a read allocates.
pub mod allocations {
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    /// The system allocator, counting what each thread holds.
    pub struct Counting;

    thread_local! {
        static HELD: Cell<isize> = const { Cell::new(0) };
        static PEAK: Cell<isize> = const { Cell::new(0) };
    }

    fn add(bytes: isize) {
        let _ = HELD.try_with(|held| {
            let now = held.get().saturating_add(bytes);
            held.set(now);
            let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
        });
    }

    fn size(bytes: usize) -> isize {
        isize::try_from(bytes).unwrap_or(isize::MAX)
    }

    // SAFETY: every call is passed on to the system allocator unchanged.
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            add(size(layout.size()));
            unsafe { System.alloc(layout) }
        }

        unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
            add(size(layout.size()));
            unsafe { System.alloc_zeroed(layout) }
        }

        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            add(-size(layout.size()));
            unsafe { System.dealloc(ptr, layout) }
        }

        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            add(size(new_size) - size(layout.size()));
            unsafe { System.realloc(ptr, layout, new_size) }
        }
    }

    /// What `f` returns, and the most bytes this thread held at once while
    /// it ran beyond what it held before.
    pub fn peak<T>(f: impl FnOnce() -> T) -> (T, usize) {
        let start = HELD.with(Cell::get);
        PEAK.with(|p| p.set(start));
        let out = f();
        let peak = PEAK.with(Cell::get);
        (out, (peak - start).max(0) as usize)
    }
}
