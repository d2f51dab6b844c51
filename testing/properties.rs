//! What the property tests of the parser crates share (each crate's
//! `tests/properties.rs` includes this file as its `support` module): the
//! cases' configuration, and an allocator that counts what a read holds.

// Each test binary uses its own share of these.
#![allow(dead_code)]

use proptest::prelude::*;
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

/// A change to a valid file's bytes: what the properties do to valid
/// files to see that the readers refuse the damage cleanly.
#[derive(Clone, Debug)]
pub enum Mutation {
    /// Keep this share (in 1/65536) of the bytes.
    Truncate(u16),
    /// Flip bits: (position share, bit) pairs.
    Flip(Vec<(u16, u8)>),
    /// Overwrite bytes at a position share with these.
    Overwrite(u16, Vec<u8>),
    /// Insert bytes at a position share.
    Insert(u16, Vec<u8>),
    /// Remove up to this many bytes at a position share.
    Remove(u16, u8),
}

pub fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        any::<u16>().prop_map(Mutation::Truncate),
        prop::collection::vec((any::<u16>(), 0u8..8), 1..8).prop_map(Mutation::Flip),
        (any::<u16>(), prop::collection::vec(any::<u8>(), 1..9))
            .prop_map(|(at, b)| Mutation::Overwrite(at, b)),
        (any::<u16>(), prop::collection::vec(any::<u8>(), 1..9))
            .prop_map(|(at, b)| Mutation::Insert(at, b)),
        (any::<u16>(), any::<u8>()).prop_map(|(at, n)| Mutation::Remove(at, n)),
    ]
}

pub fn position(share: u16, len: usize) -> usize {
    (len * share as usize) >> 16
}

pub fn mutate(bytes: &[u8], m: &Mutation) -> Vec<u8> {
    let mut out = bytes.to_vec();
    match m {
        Mutation::Truncate(share) => out.truncate(position(*share, bytes.len())),
        Mutation::Flip(flips) => {
            if !out.is_empty() {
                for &(share, bit) in flips {
                    let at = position(share, out.len());
                    out[at] ^= 1 << bit;
                }
            }
        }
        Mutation::Overwrite(share, new) => {
            let at = position(*share, out.len());
            for (k, b) in new.iter().enumerate() {
                if let Some(old) = out.get_mut(at + k) {
                    *old = *b;
                }
            }
        }
        Mutation::Insert(share, new) => {
            let at = position(*share, out.len());
            out.splice(at..at, new.iter().copied());
        }
        Mutation::Remove(share, n) => {
            let at = position(*share, out.len());
            let end = (at + *n as usize).min(out.len());
            out.drain(at..end);
        }
    }
    out
}

/// Any JSON value, up to `depth` levels deep with `branches` items a
/// level, its numbers from `numbers` (each crate's edges).
pub fn json_value(
    numbers: impl Strategy<Value = serde_json::Value> + 'static,
    depth: u32,
    branches: usize,
) -> impl Strategy<Value = serde_json::Value> {
    use serde_json::Value;
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::from),
        numbers,
        any::<String>().prop_map(Value::from),
    ];
    leaf.prop_recursive(depth, 4 * branches as u32, branches as u32, move |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..branches).prop_map(Value::Array),
            prop::collection::btree_map(any::<String>(), inner, 0..branches)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}
