//! One bound on the decoded assets a process holds. Every cache of decoded
//! files (the photo and texture libraries of the 2D generator, the 3D
//! renderer's asset cache) counts its bytes against the same budget, so a
//! process that draws 2D scenes, renders 3D ones and trains holds at most
//! about `limit` bytes of decoded assets in all, not a budget per cache.

use std::collections::HashMap;
use std::hash::Hash;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// A byte budget shared by the caches of a process.
#[derive(Debug)]
pub struct MemoryBudget {
    limit: usize,
    held: AtomicUsize,
}

impl MemoryBudget {
    /// A budget of `limit` bytes, none held yet.
    pub fn new(limit: usize) -> Arc<Self> {
        Arc::new(Self {
            limit,
            held: AtomicUsize::new(0),
        })
    }

    /// The bound, in bytes.
    pub fn limit(&self) -> usize {
        self.limit
    }

    /// Bytes the caches hold now.
    pub fn held(&self) -> usize {
        self.held.load(Ordering::Relaxed)
    }

    /// Whether `bytes` more would stay within the bound.
    pub fn fits(&self, bytes: usize) -> bool {
        self.held().saturating_add(bytes) <= self.limit
    }

    /// Whether the caches hold more than the bound.
    pub fn exceeded(&self) -> bool {
        self.held() > self.limit
    }

    /// A cache now holds `bytes` more.
    pub fn add(&self, bytes: usize) {
        self.held.fetch_add(bytes, Ordering::Relaxed);
    }

    /// A cache let go of `bytes`.
    pub fn release(&self, bytes: usize) {
        self.held.fetch_sub(bytes, Ordering::Relaxed);
    }
}

/// Values decoded once, kept least recently used first out while a
/// [`MemoryBudget`] is passed (the last one stays, however large), each
/// counted with the bytes the caller gives for it.
#[derive(Debug)]
pub struct ByteLru<K, V> {
    budget: Arc<MemoryBudget>,
    state: Mutex<LruState<K, V>>,
}

#[derive(Debug)]
struct LruState<K, V> {
    /// Value, its bytes, when it was last used.
    entries: HashMap<K, (Arc<V>, usize, u64)>,
    bytes: usize,
    clock: u64,
}

impl<K: Hash + Eq + Clone, V> ByteLru<K, V> {
    /// An empty cache counting against `budget`.
    pub fn new(budget: Arc<MemoryBudget>) -> Self {
        Self {
            budget,
            state: Mutex::new(LruState {
                entries: HashMap::new(),
                bytes: 0,
                clock: 0,
            }),
        }
    }

    fn state(&self) -> std::sync::MutexGuard<'_, LruState<K, V>> {
        crate::sync::lock(&self.state)
    }

    /// The value under `key`, if held.
    pub fn get(&self, key: &K) -> Option<Arc<V>> {
        let mut state = self.state();
        state.clock += 1;
        let now = state.clock;
        state.entries.get_mut(key).map(|(value, _, used)| {
            *used = now;
            value.clone()
        })
    }

    /// Keeps `value` (`bytes` of it) under `key`, letting the least
    /// recently used values go while the budget is passed.
    pub fn insert(&self, key: K, value: Arc<V>, bytes: usize) {
        let mut state = self.state();
        state.clock += 1;
        let now = state.clock;
        if let Some((_, old, _)) = state.entries.insert(key, (value, bytes, now)) {
            state.bytes -= old;
            self.budget.release(old);
        }
        state.bytes += bytes;
        self.budget.add(bytes);
        while self.budget.exceeded() && state.entries.len() > 1 {
            let oldest = state
                .entries
                .iter()
                .min_by_key(|(_, (_, _, used))| *used)
                .map(|(k, _)| k.clone())
                .expect("non-empty");
            if let Some((_, old, _)) = state.entries.remove(&oldest) {
                state.bytes -= old;
                self.budget.release(old);
            }
        }
    }

    /// Bytes this cache holds.
    pub fn bytes(&self) -> usize {
        self.state().bytes
    }

    /// Counts what this cache holds against `budget` from now on.
    pub fn share(&mut self, budget: Arc<MemoryBudget>) {
        let held = self.bytes();
        self.budget.release(held);
        budget.add(held);
        self.budget = budget;
    }
}

impl<K, V> Drop for ByteLru<K, V> {
    fn drop(&mut self) {
        let held = self.state.get_mut().map_or(0, |s| s.bytes);
        self.budget.release(held);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holdings_add_up_and_are_released() {
        let budget = MemoryBudget::new(100);
        assert!(budget.fits(100) && !budget.fits(101));
        budget.add(60);
        budget.add(50);
        assert!(budget.exceeded());
        budget.release(50);
        assert_eq!(budget.held(), 60);
        assert!(!budget.exceeded() && !budget.fits(41));
    }

    #[test]
    fn the_cache_keeps_within_its_budget_least_recently_used_first_out() {
        let one = 100;
        let cache = ByteLru::new(MemoryBudget::new(2 * one));
        cache.insert("a", Arc::new(1), one);
        cache.insert("b", Arc::new(2), one);
        assert!(cache.get(&"a").is_some());
        cache.insert("c", Arc::new(3), one);
        assert_eq!(cache.bytes(), 2 * one);
        assert!(cache.get(&"b").is_none(), "b was the least recently used");
        assert!(cache.get(&"a").is_some() && cache.get(&"c").is_some());
        // One value larger than the budget still stays.
        cache.insert("big", Arc::new(4), 16 * one);
        assert!(cache.get(&"big").is_some());
        assert_eq!(cache.bytes(), 16 * one);
    }
}
